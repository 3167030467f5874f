//! Repeat-look decorrelation.
//!
//! A parked or slow radar sees a feature from the same geometry rotation after rotation, so
//! the errors tied to that geometry (azimuth and bin quantisation, partial occlusion, on
//! hardware speckle) repeat instead of averaging out. While a feature's predicted range and
//! bearing stay within one cell ([`crate::FilterSettings::repeat_look_range_m`],
//! [`crate::FilterSettings::repeat_look_bearing_rad`]) of where a run of looks began, its
//! k-th look is used with k times its noise variance, up to
//! [`crate::FilterSettings::repeat_look_max_factor`]. Looks of one sweep (closer together in
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
    /// The largest variance factor (at least 1).
    pub max_factor: f64,
}

impl LookCell {
    /// The cell the settings describe.
    pub fn from_settings(settings: &FilterSettings) -> Self {
        Self {
            range_m: settings.repeat_look_range_m,
            bearing_rad: settings.repeat_look_bearing_rad,
            same_sweep_s: settings.confirm_min_separation_s,
            max_factor: settings.repeat_look_max_factor.max(1.0),
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
        f64::from(track.repeat_looks).min(self.max_factor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::FeatureId;

    fn track() -> FeatureTrack {
        FeatureTrack {
            id: FeatureId(0),
            consecutive_misses: 0,
            hits: 0,
            created_s: 0.0,
            last_seen_s: 0.0,
            material_settled_s: 0.0,
            first_xy_m: [10.0, 0.0],
            look_anchor: None,
            repeat_looks: 0,
            last_look_s: 0.0,
            wander_settled_m: 0.0,
            rotations_in_view: 0,
            rotations_reobserved: 0,
        }
    }

    /// The factors of `looks` looks a rotation apart from one viewpoint, then one from a new
    /// viewpoint (two cells away in range).
    fn factors(max_factor: f64, looks: u32) -> Vec<f64> {
        let cell = LookCell {
            range_m: 0.25,
            bearing_rad: 0.03,
            same_sweep_s: 0.1,
            max_factor,
        };
        let mut t = track();
        let mut out: Vec<f64> = (0..looks)
            .map(|k| cell.inflation(&mut t, [10.0, 0.0], 0.4 * f64::from(k)))
            .collect();
        out.push(cell.inflation(&mut t, [10.5, 0.0], 0.4 * f64::from(looks)));
        out
    }

    #[test]
    fn the_kth_repeated_look_counts_k_times_up_to_the_cap_and_a_new_viewpoint_starts_over() {
        let capped = factors(4.0, 7);
        assert_eq!(capped, [1.0, 2.0, 3.0, 4.0, 4.0, 4.0, 4.0, 1.0]);
        let uncapped = factors(f64::INFINITY, 7);
        assert_eq!(uncapped, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 1.0]);
    }

    #[test]
    fn looks_within_one_sweep_count_once_and_the_default_cap_is_32() {
        let s = FilterSettings::default();
        let cell = LookCell::from_settings(&s);
        assert_eq!(cell.max_factor, 32.0);
        let mut t = track();
        assert_eq!(cell.inflation(&mut t, [10.0, 0.0], 0.0), 1.0);
        assert_eq!(cell.inflation(&mut t, [10.0, 0.0], 0.4), 2.0);
        // The next azimuth of the same sweep: independent, and the run goes on.
        assert_eq!(cell.inflation(&mut t, [10.0, 0.0], 0.402), 1.0);
        assert_eq!(cell.inflation(&mut t, [10.0, 0.0], 0.8), 3.0);
    }
}
