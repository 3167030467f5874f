//! From grouped observations (one per target, in time order) to the filter's beams: targets
//! whose bearings lie within half a beam width of each other, seen within a few azimuths,
//! go to the filter together, so that eq. 13's attenuation by the targets in front applies.
//!
//! A beam's timestamp is its earliest target's, so beams leave in non-decreasing time (the
//! filter refuses to predict backwards); each target keeps its own bearing.

use crate::detect::Observation;
use radar_model::geometry::wrap_angle;
use slam_filter::{BeamObservation, Target};

/// One beam's targets for the filter, with which of them may start a new feature.
#[derive(Debug, Clone, PartialEq)]
pub struct OfferedBeam {
    /// The targets.
    pub beam: BeamObservation,
    /// Per target, whether it may start a feature (or only re-observe one).
    pub may_start: Vec<bool>,
}

/// Most observations pending in one beam. Far more than a beam can hold (the filter refuses
/// beams over `max_targets_per_beam`), so it never splits a real beam; it bounds what a
/// stuck encoder with a stuck clock (every azimuth at one bearing and one time) can pile
/// up: one rotation of the largest legal radar is 131,070 azimuths.
pub const MAX_PENDING_OBSERVATIONS: usize = 4096;

/// Gathers observations into beams.
#[derive(Debug)]
pub struct BeamAssembler {
    half_width_rad: f64,
    max_dt_s: f64,
    pending: Vec<Observation>,
}

impl BeamAssembler {
    /// Targets within `half_width_rad` of the beam's first target and `max_dt_s` of its time
    /// share a beam.
    pub fn new(half_width_rad: f64, max_dt_s: f64) -> Self {
        Self {
            half_width_rad,
            max_dt_s,
            pending: Vec::new(),
        }
    }

    /// Adds one observation; completed beams go to `out`.
    pub fn push(&mut self, obs: Observation, out: &mut Vec<OfferedBeam>) {
        if let Some(first) = self.pending.first() {
            let same_beam = wrap_angle(obs.bearing_rad - first.bearing_rad).abs()
                <= self.half_width_rad
                && obs.timestamp_s - first.timestamp_s <= self.max_dt_s;
            if !same_beam || self.pending.len() >= MAX_PENDING_OBSERVATIONS {
                self.flush(out);
            }
        }
        self.pending.push(obs);
    }

    /// Emits the pending beam, if any.
    pub fn flush(&mut self, out: &mut Vec<OfferedBeam>) {
        let Some(first) = self.pending.first().copied() else {
            return;
        };
        let strongest = self
            .pending
            .iter()
            .max_by(|a, b| a.power_db.total_cmp(&b.power_db))
            .copied()
            .unwrap_or(first);
        let may_start = self.pending.iter().map(|o| o.may_start).collect();
        out.push(OfferedBeam {
            beam: BeamObservation {
                timestamp_s: first.timestamp_s,
                bearing_rad: strongest.bearing_rad,
                targets: self
                    .pending
                    .drain(..)
                    .map(|o| Target {
                        range_m: o.range_m,
                        bearing_rad: o.bearing_rad,
                        power_db: o.power_db,
                    })
                    .collect(),
            },
            may_start,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(range_m: f64, bearing_deg: f64, t: f64) -> Observation {
        Observation {
            range_m,
            bearing_rad: bearing_deg.to_radians(),
            power_db: 0.0,
            timestamp_s: t,
            azimuths: 1,
            peak_range_m: range_m,
            extent_m: 0.1,
            snr_db: 30.0,
            width_rad: 0.0,
            cut: false,
            may_start: true,
        }
    }

    #[test]
    fn targets_down_one_beam_are_delivered_together_and_others_apart() {
        let mut a = BeamAssembler::new(0.9f64.to_radians(), 0.05);
        let mut out = Vec::new();
        a.push(obs(8.5, 0.0, 1.000), &mut out);
        a.push(obs(14.0, 0.3, 1.002), &mut out);
        a.push(obs(20.0, 10.0, 1.010), &mut out);
        a.flush(&mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].beam.targets.len(), 2);
        assert_eq!(out[1].beam.targets.len(), 1);
        assert_eq!(out[0].may_start, vec![true, true]);
        assert!(out[0].beam.timestamp_s <= out[1].beam.timestamp_s);
    }

    #[test]
    fn a_stuck_bearing_at_a_stuck_time_never_holds_more_than_the_pending_cap() {
        let mut a = BeamAssembler::new(0.9f64.to_radians(), 0.05);
        let mut out = Vec::new();
        for _ in 0..3 * MAX_PENDING_OBSERVATIONS {
            a.push(obs(8.5, 0.0, 1.0), &mut out);
            assert!(a.pending.len() <= MAX_PENDING_OBSERVATIONS);
        }
        assert_eq!(out.len(), 2);
    }
}
