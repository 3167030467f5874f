//! Per-rotation statistics: counts, timings, the filter's NIS, the whole-spectrum
//! comparison, and the spectra chosen for figures. Reads what the other stages did; changes
//! nothing they do.

use slam_filter::{BeamObservation, BeamReport};

use super::frontend::FrontEndCounts;
use super::spectrum::SpectrumTally;
use super::summary::PipelineSummary;
use crate::output::{
    Detection, OutputEvent, RotationDetections, RotationDiagnostics, SpectrumComparison,
};

/// Saturating count conversion for the diagnostics' 32-bit fields.
fn count(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// The statistics of the rotation in progress.
#[derive(Debug, Default)]
pub struct RotationStats {
    rot: RotationDiagnostics,
    spectrum: SpectrumTally,
    nis: (f64, u64),
    sample: Option<(usize, SpectrumComparison)>,
    chosen: Vec<SpectrumComparison>,
    detections: Vec<Detection>,
}

/// Wall time spent in each stage on one azimuth (ms).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Front end.
    pub detect_ms: f64,
    /// Odometry gate and filter.
    pub filter_ms: f64,
    /// Whole-spectrum comparison.
    pub spectrum_ms: f64,
}

impl RotationStats {
    /// Counts one azimuth.
    pub fn on_azimuth(&mut self, counts: FrontEndCounts, times: StageTimes) {
        self.rot.azimuths += 1;
        self.rot.detections += count(counts.detections);
        self.rot.observations += count(counts.observations);
        self.rot.detect_ms += times.detect_ms;
        self.rot.filter_ms += times.filter_ms;
        self.rot.spectrum_ms += times.spectrum_ms;
        self.rot.total_ms += times.detect_ms + times.filter_ms + times.spectrum_ms;
    }

    /// Counts the time of one rotation's radar-odometry registration and update (in the
    /// filter's share).
    pub fn on_registration(&mut self, ms: f64) {
        self.rot.filter_ms += ms;
        self.rot.total_ms += ms;
    }

    /// Counts one beam the filter processed; returns its associations.
    pub fn on_beam(&mut self, beam: &BeamObservation, report: &BeamReport) -> u32 {
        self.detections
            .extend(beam.targets.iter().map(|t| Detection {
                timestamp_s: beam.timestamp_s,
                range_m: t.range_m,
                bearing_rad: t.bearing_rad,
                power_db: t.power_db,
            }));
        let associated = count(report.associated.len());
        self.rot.associated += associated;
        self.rot.new_features += count(report.initialised.len());
        self.rot.retired += count(report.retired.len());
        self.rot.tentative += count(report.new_tentatives);
        let unclaimed = beam.targets.len().saturating_sub(report.associated.len());
        let placed = report.initialised.len() + report.new_tentatives;
        self.rot.rejected += count(unclaimed.saturating_sub(placed));
        if let Some(u) = &report.update {
            if u.dof > 0 && u.nis.is_finite() {
                self.nis.0 += u.nis / u.dof as f64;
                self.nis.1 += 1;
            }
        }
        associated
    }

    /// Counts features retired for going unseen in range or for being unrepeatable.
    pub fn on_retired(&mut self, n: usize) {
        self.rot.retired += count(n);
    }

    /// Counts associations to the wrong true feature (truth known only).
    pub fn on_association_errors(&mut self, wrong: u32) {
        if wrong > 0 {
            *self.rot.association_errors.get_or_insert(0) += wrong;
        }
    }

    /// Adds one beam's spectrum comparison.
    pub fn on_spectrum(&mut self, tally: &SpectrumTally) {
        self.spectrum.merge(tally);
    }

    /// Whether a comparison of a beam with `features` mapped features should replace the
    /// rotation's figure sample (the beam with the most features wins).
    pub fn better_sample(&self, features: usize) -> bool {
        self.sample.as_ref().is_none_or(|(k, _)| features > *k)
    }

    /// Keeps a comparison for the figures: a chosen bearing's, or the rotation's best.
    pub fn keep_sample(&mut self, sample: SpectrumComparison, features: usize, chosen: bool) {
        if chosen {
            self.chosen.push(sample);
        } else {
            self.sample = Some((features, sample));
        }
    }

    /// Whether any azimuth was counted in this rotation.
    pub fn is_empty(&self) -> bool {
        self.rot.azimuths == 0
    }

    /// Closes the rotation: its diagnostics (to be completed by the caller) with the
    /// totals added to `summary`; the figures' spectra go to `events`.
    pub fn close(
        &mut self,
        rotation: u64,
        timestamp_s: f64,
        map_size: usize,
        summary: &mut PipelineSummary,
        events: &mut Vec<OutputEvent>,
    ) -> RotationDiagnostics {
        let mut d = std::mem::take(&mut self.rot);
        d.rotation = rotation;
        d.timestamp_s = timestamp_s;
        d.map_size = count(map_size);
        d.mean_nis = (self.nis.1 > 0).then(|| self.nis.0 / self.nis.1 as f64);
        d.spectrum_in_bound_fraction = self.spectrum.in_bound_fraction();
        d.spectrum_bias_db = self.spectrum.bias_db();
        summary.spectrum.merge(&self.spectrum);
        summary.add_rotation(&d);
        self.nis = (0.0, 0);
        self.spectrum = SpectrumTally::default();
        if let Some((_, sample)) = self.sample.take() {
            events.push(OutputEvent::Spectrum(sample));
        }
        events.extend(self.chosen.drain(..).map(OutputEvent::Spectrum));
        events.push(OutputEvent::Detections(RotationDetections {
            rotation,
            timestamp_s,
            detections: std::mem::take(&mut self.detections),
        }));
        d
    }
}
