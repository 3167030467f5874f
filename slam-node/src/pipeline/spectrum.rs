//! Whole-spectrum prediction against measurement (the paper's figures 8-10): for a beam,
//! the mapped features inside it seen from the pose predicted to the beam's own time, their
//! eq. 13 powers with the estimated materials and loss, radar-model's expected spectrum,
//! and the bin-by-bin difference with the measured spectrum against the +-16.35 dB bound
//! (the paper's unit) or, with the learned front end, three sigma of the floor learned per
//! bin.

use radar_model::geometry::{range_bearing, wrap_angle, BeamAxis, Pose2};
use radar_model::material::Material;
use radar_model::power::{PowerModel, PowerTarget};
use radar_model::spectrum::{
    beam_spectrum_targets, compare_spectra, SpectrumModel, SpectrumTarget,
};

use slam_filter::SlamState;

/// Running in-bound and bias figures over the beams compared in one rotation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SpectrumTally {
    /// Beams compared (those with at least one mapped feature inside).
    pub beams: u64,
    /// Bins compared.
    pub bins: u64,
    /// Bins with |predicted - measured| inside the bound.
    pub inside: u64,
    /// Sum of predicted - measured over the compared bins, dB.
    pub sum_db: f64,
}

impl SpectrumTally {
    /// Share of compared bins inside the bound.
    pub fn in_bound_fraction(&self) -> Option<f64> {
        (self.bins > 0).then(|| self.inside as f64 / self.bins as f64)
    }

    /// Mean predicted minus measured, dB.
    pub fn bias_db(&self) -> Option<f64> {
        (self.bins > 0).then(|| self.sum_db / self.bins as f64)
    }

    /// Adds another tally.
    pub fn merge(&mut self, o: &SpectrumTally) {
        self.beams += o.beams;
        self.bins += o.bins;
        self.inside += o.inside;
        self.sum_db += o.sum_db;
    }
}

/// Reusable buffers for spectrum prediction.
#[derive(Debug, Default)]
pub struct SpectrumScratch {
    targets: Vec<PowerTarget>,
    ranges: Vec<(f64, usize)>,
    spectrum_targets: Vec<SpectrumTarget>,
    /// The last predicted spectrum.
    pub predicted: Vec<f64>,
}

/// Predicts the spectrum of the beam at `bearing_rad` from `pose` into `scratch.predicted`
/// and compares it with `measured_db`; returns the number of mapped features in the beam and
/// the comparison's contribution (None when the beam holds no mapped feature or the model
/// rejects the input).
#[allow(clippy::too_many_arguments)]
pub fn compare_beam(
    state: &SlamState,
    pose: &Pose2,
    bearing_rad: f64,
    half_width_rad: f64,
    power: &PowerModel,
    model: &SpectrumModel,
    measured_db: &[f64],
    bound_db: f64,
    bound_table_db: Option<&[f64]>,
    scratch: &mut SpectrumScratch,
) -> Option<(usize, SpectrumTally)> {
    let g = model.geometry();
    let max_range = g.bin_range_m(g.bins);
    scratch.ranges.clear();
    let axis = BeamAxis::new(pose, bearing_rad);
    for slot in 0..state.feature_count() {
        let Some(p) = state.params(slot) else {
            continue;
        };
        if !axis.may_hold([p.x_m, p.y_m], half_width_rad) {
            continue;
        }
        let rb = range_bearing(pose, [p.x_m, p.y_m]);
        if rb.range_m > 0.5
            && rb.range_m < max_range
            && wrap_angle(rb.bearing_rad - bearing_rad).abs() <= half_width_rad
        {
            scratch.ranges.push((rb.range_m, slot));
        }
    }
    if scratch.ranges.is_empty() {
        return None;
    }
    scratch.ranges.sort_by(|a, b| a.0.total_cmp(&b.0));
    scratch.targets.clear();
    for &(range_m, slot) in &scratch.ranges {
        if let Some(p) = state.params(slot) {
            scratch.targets.push(PowerTarget {
                range_m,
                material: Material::new(p.u, p.v),
            });
        }
    }
    beam_spectrum_targets(
        power,
        &scratch.targets,
        state.loss_db(),
        &mut scratch.spectrum_targets,
    )
    .ok()?;
    scratch.predicted.resize(g.bins, 0.0);
    model
        .predict_into(&scratch.spectrum_targets, &mut scratch.predicted)
        .ok()?;
    let n = measured_db.len().min(g.bins);
    if let Some(bound) = bound_table_db {
        // A bound per bin (learned from the radar's floor).
        let mut tally = SpectrumTally {
            beams: 1,
            ..SpectrumTally::default()
        };
        for ((p, m), b) in scratch
            .predicted
            .get(..n)?
            .iter()
            .zip(measured_db.get(..n)?)
            .zip(bound.get(..n)?)
        {
            if !(p.is_finite() && m.is_finite()) {
                continue;
            }
            let d = p - m;
            tally.bins += 1;
            tally.sum_db += d;
            if d.abs() <= *b {
                tally.inside += 1;
            }
        }
        return Some((scratch.ranges.len(), tally));
    }
    let cmp = compare_spectra(scratch.predicted.get(..n)?, measured_db.get(..n)?, bound_db).ok()?;
    // fraction_inside * bins is an exact count up to rounding.
    let inside = (cmp.fraction_inside * cmp.bins as f64).round() as u64;
    Some((
        scratch.ranges.len(),
        SpectrumTally {
            beams: 1,
            bins: cmp.bins as u64,
            inside,
            sum_db: cmp.mean_bias_db * cmp.bins as f64,
        },
    ))
}
