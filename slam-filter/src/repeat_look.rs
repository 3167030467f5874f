//! Repeat-look decorrelation.
//!
//! A parked or slow radar sees a feature from the same geometry rotation after rotation, so
//! the errors tied to that geometry (azimuth and bin quantisation, partial occlusion, on
//! hardware speckle) repeat instead of averaging out. While a feature's predicted range and
//! bearing stay within one cell ([`crate::FilterSettings::repeat_look_range_m`],
//! [`crate::FilterSettings::repeat_look_bearing_rad`]) of where a run of looks began, its
//! k-th look is used with k times its noise variance. Looks of one sweep (closer together in
//! time than [`crate::FilterSettings::confirm_min_separation_s`]: neighbouring azimuths,
//! each quantised differently) are independent and count as 1 without ending the run.
//! A cell of zero switches it off.

use radar_model::geometry::wrap_angle;

use super::settings::FilterSettings;
use super::state::FeatureTrack;

/// The cell inside which looks repeat, and the time that separates sweeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LookCell {
    /// Range extent (m).
    pub range_m: f64,
    /// Bearing extent (rad).
    pub bearing_rad: f64,
    /// Looks closer together than this belong to one sweep (s).
    pub same_sweep_s: f64,
}

impl LookCell {
    /// The cell the settings describe.
    pub fn from_settings(settings: &FilterSettings) -> Self {
        Self {
            range_m: settings.repeat_look_range_m,
            bearing_rad: settings.repeat_look_bearing_rad,
            same_sweep_s: settings.confirm_min_separation_s,
        }
    }

    /// Counts a look at `track`, predicted at `[range, bearing]` in the radar's frame at
    /// `now_s`, and returns the factor its noise variance is multiplied by.
    pub fn inflation(&self, track: &mut FeatureTrack, look: [f64; 2], now_s: f64) -> f64 {
        if self.range_m <= 0.0 || self.bearing_rad <= 0.0 {
            return 1.0;
        }
        let same_cell = track.look_anchor.is_some_and(|a| {
            (look[0] - a[0]).abs() < self.range_m
                && wrap_angle(look[1] - a[1]).abs() < self.bearing_rad
        });
        if !same_cell {
            track.look_anchor = Some(look);
            track.repeat_looks = 1;
            track.last_look_s = now_s;
            return 1.0;
        }
        if now_s - track.last_look_s < self.same_sweep_s {
            return 1.0;
        }
        track.last_look_s = now_s;
        track.repeat_looks = track.repeat_looks.saturating_add(1);
        f64::from(track.repeat_looks)
    }
}
