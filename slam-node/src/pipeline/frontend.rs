//! The front end: from one azimuth's bins to the filter's beams. Bins to dB (`protocol`'s
//! conversion), the receiver's range compensation removed, every target down the beam
//! detected, detections of neighbouring azimuths grouped into one observation per target,
//! observations gathered into beams. No IO, no clock; it owns the per-radar state (spectrum
//! tables, floor profile, detector state), rebuilt when the radar's geometry changes.
//!
//! The daemon's pipeline and the evaluation both run this stage, with settings derived by
//! [`super::PipelineSettings::front_end`].

use radar_driver::Azimuth;
use radar_model::compensation::Compensation;
use radar_model::noise::NoiseModel;
use radar_model::spectrum::{SpectrumGeometry, SpectrumModel};
use slam_filter::BeamObservation;
use tracing::info;

use super::beams::BeamAssembler;
use crate::detect::{
    BeamDetection, BeamDetector, Detection, DetectorSettings, FloorProfile, Grouper,
    GroupingSettings, Observation, RangeAxis,
};

/// Everything that shapes the front end besides the radar's own geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct FrontEndSettings {
    /// Detection.
    pub detector: DetectorSettings,
    /// Grouping range gate (m).
    pub grouping_range_gate_m: f64,
    /// Widest group, in beam widths.
    pub grouping_max_width_beams: f64,
    /// Beam width (rad).
    pub beam_width_rad: f64,
    /// Receiver compensation to remove from measured spectra.
    pub compensation: Compensation,
    /// Noise model (the target-absent floor the detector is told about).
    pub noise: NoiseModel,
    /// Bytes the detector may keep across rotations; a geometry needing more is refused.
    pub max_detector_state_bytes: usize,
}

impl FrontEndSettings {
    /// Grouping settings for a radar with `azimuths` spectra per rotation.
    pub fn grouping(&self, azimuths: u16) -> GroupingSettings {
        let step = std::f64::consts::TAU / f64::from(azimuths.max(1));
        GroupingSettings {
            range_gate_m: self.grouping_range_gate_m,
            max_step_rad: 1.5 * step,
            max_width_rad: (self.grouping_max_width_beams * self.beam_width_rad).max(step),
        }
    }
}

/// The radar's announced geometry cannot be processed.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// The geometry does not make a spectrum model.
    #[error(
        "radar geometry ({azimuths} azimuths, {bins} bins of {bin_m} m) makes no spectrum model"
    )]
    NoSpectrumModel {
        /// Azimuths per rotation.
        azimuths: u16,
        /// Bins per azimuth.
        bins: u16,
        /// Bin size after the range gain (m).
        bin_m: f64,
        /// Why.
        #[source]
        source: radar_model::ModelError,
    },
    /// The detector's state for this geometry would exceed its memory budget.
    #[error("radar geometry ({azimuths} azimuths x {bins} bins) needs {needed_bytes} bytes of detector state, over the budget of {budget_bytes} ([detector] max_state_mib): refused")]
    DetectorStateTooLarge {
        /// Azimuths per rotation.
        azimuths: u16,
        /// Bins per azimuth.
        bins: u16,
        /// What the state would take.
        needed_bytes: usize,
        /// What it may take.
        budget_bytes: usize,
    },
}

/// Per-radar state, rebuilt when the radar's configuration changes.
#[derive(Debug)]
struct RadarState {
    geometry: protocol::Geometry,
    axis: RangeAxis,
    spectrum: SpectrumModel,
    floor: FloorProfile,
    detector: BeamDetector,
}

/// What the front end did with one azimuth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrontEndCounts {
    /// Targets detected down this azimuth.
    pub detections: usize,
    /// Observations (grouped across azimuths) released by this azimuth.
    pub observations: usize,
}

/// The front end's state.
#[derive(Debug)]
pub struct FrontEnd {
    settings: FrontEndSettings,
    radar: Option<RadarState>,
    grouper: Option<Grouper>,
    assembler: BeamAssembler,
    measured: Vec<f64>,
    detections: Vec<Detection>,
    beam_detections: Vec<BeamDetection>,
    released: Vec<Observation>,
    /// Per azimuth index, the range the last azimuth there covered when it was shorter than
    /// the radar's full range (a contour, a blanked sector); `None`: full range.
    short: Vec<Option<f64>>,
}

impl FrontEnd {
    /// A front end waiting for its first azimuth (which brings the radar's geometry).
    pub fn new(settings: FrontEndSettings) -> Self {
        Self {
            assembler: BeamAssembler::new(0.5 * settings.beam_width_rad, 0.02),
            settings,
            radar: None,
            grouper: None,
            measured: Vec::new(),
            detections: Vec::new(),
            beam_detections: Vec::new(),
            released: Vec::new(),
            short: Vec::new(),
        }
    }

    /// The settings in force.
    pub fn settings(&self) -> &FrontEndSettings {
        &self.settings
    }

    /// Builds the per-radar state for `geometry` unless it is already in force.
    pub fn configure(&mut self, geometry: &protocol::Geometry) -> Result<(), GeometryError> {
        if self.radar.as_ref().is_some_and(|r| &r.geometry == geometry) {
            return Ok(());
        }
        let bin_m = geometry.range_gain * geometry.bin_size_m;
        let needed_bytes = self.detector_state_bytes(geometry);
        if needed_bytes > self.settings.max_detector_state_bytes {
            return Err(GeometryError::DetectorStateTooLarge {
                azimuths: geometry.azimuth_samples,
                bins: geometry.range_in_bins,
                needed_bytes,
                budget_bytes: self.settings.max_detector_state_bytes,
            });
        }
        let sg = SpectrumGeometry {
            bins: usize::from(geometry.range_in_bins),
            bin_size_m: bin_m,
            range_offset_m: geometry.range_offset_m,
        };
        let spectrum = SpectrumModel::new(sg, &self.settings.compensation, self.settings.noise)
            .map_err(|source| GeometryError::NoSpectrumModel {
                azimuths: geometry.azimuth_samples,
                bins: geometry.range_in_bins,
                bin_m,
                source,
            })?;
        info!(
            azimuths = geometry.azimuth_samples,
            bins = geometry.range_in_bins,
            bin_m,
            rotation_hz = geometry.rotation_hz,
            "radar geometry"
        );
        self.grouper = Some(Grouper::new(
            self.settings.grouping(geometry.azimuth_samples),
        ));
        let floor = FloorProfile::new(
            &spectrum,
            &self.settings.noise.absent,
            self.settings.detector.floor_tail_pfa,
        );
        self.radar = Some(RadarState {
            floor,
            geometry: geometry.clone(),
            axis: RangeAxis {
                first_bin_m: geometry.range_offset_m,
                bin_m,
            },
            spectrum,
            detector: BeamDetector::new(
                self.settings.detector,
                usize::from(geometry.azimuth_samples),
            ),
        });
        Ok(())
    }

    /// Bytes the detector keeps across rotations for `geometry` (TPP: every bin of every
    /// azimuth; the CFAR detectors keep none).
    pub fn detector_state_bytes(&self, geometry: &protocol::Geometry) -> usize {
        if self.settings.detector.kind != crate::detect::DetectorKind::Tpp {
            return 0;
        }
        usize::from(geometry.azimuth_samples)
            .saturating_mul(usize::from(geometry.range_in_bins))
            .saturating_mul(crate::detect::tpp::STATE_BYTES_PER_BIN)
    }

    /// Detects and groups one azimuth (its geometry must have been [`Self::configure`]d):
    /// beams the grouping completes go to `beams`. `index` is the azimuth's index in the
    /// rotation ([`protocol::Geometry::azimuth_index`]), `bearing_rad` its bearing.
    pub fn process(
        &mut self,
        az: &Azimuth,
        index: u16,
        bearing_rad: f64,
        beams: &mut Vec<BeamObservation>,
    ) -> FrontEndCounts {
        let Some(radar) = self.radar.as_mut() else {
            return FrontEndCounts::default();
        };
        self.measured.clear();
        self.measured.extend(az.bins_db());
        // A contoured or blanked azimuth is shorter: remember how far it reached, so that
        // missing range is not taken for empty range.
        let full = usize::from(radar.geometry.range_in_bins);
        let covered = (self.measured.len() < full).then(|| {
            radar
                .axis
                .range_m(self.measured.len() as f64 - 0.5)
                .max(0.0)
        });
        let slots = usize::from(radar.geometry.azimuth_samples);
        if self.short.len() != slots {
            self.short = vec![None; slots];
        }
        if let Some(slot) = self.short.get_mut(usize::from(index)) {
            *slot = covered;
        }
        let gain = radar.spectrum.gain_db();
        let n = self.measured.len().min(gain.len());
        self.measured.truncate(n);
        self.detections.clear();
        if n > 0 {
            radar.detector.detect(
                usize::from(index),
                &self.measured,
                gain.get(..n).unwrap_or_default(),
                radar.floor.floor(n),
                &radar.axis,
                &mut self.detections,
            );
        }
        self.beam_detections.clear();
        self.beam_detections
            .extend(self.detections.iter().map(|d| BeamDetection {
                range_m: d.range_m,
                power_db: d.power_db,
            }));
        self.released.clear();
        if let Some(g) = self.grouper.as_mut() {
            g.push(
                bearing_rad,
                az.timestamp_s,
                &self.beam_detections,
                &mut self.released,
            );
        }
        for o in &self.released {
            self.assembler.push(*o, beams);
        }
        FrontEndCounts {
            detections: self.detections.len(),
            observations: self.released.len(),
        }
    }

    /// How far the radar's last look along `bearing_rad` reached, when it was cut short (a
    /// contour or a blanked sector); `None` when it covered the full range.
    pub fn covered_range_m(&self, bearing_rad: f64) -> Option<f64> {
        let n = self.short.len();
        if n == 0 {
            return None;
        }
        let step = std::f64::consts::TAU / n as f64;
        let index = (bearing_rad.rem_euclid(std::f64::consts::TAU) / step).round() as usize % n;
        self.short.get(index).copied().flatten()
    }

    /// Whether the radar's last look along `bearing_rad` reached `range_m`.
    pub fn covers(&self, bearing_rad: f64, range_m: f64) -> bool {
        self.covered_range_m(bearing_rad)
            .map_or(true, |covered| range_m <= covered)
    }

    /// Releases everything still held (end of stream) into `beams`.
    pub fn flush(&mut self, beams: &mut Vec<BeamObservation>) {
        let mut released = Vec::new();
        if let Some(g) = self.grouper.as_mut() {
            g.flush(&mut released);
        }
        for o in released {
            self.assembler.push(o, beams);
        }
        self.assembler.flush(beams);
    }

    /// The last azimuth's spectrum in dB as measured (compensation not removed), cut to the
    /// spectrum model's bins.
    pub fn measured_db(&self) -> &[f64] {
        &self.measured
    }

    /// The last azimuth's detections.
    pub fn detections(&self) -> &[Detection] {
        &self.detections
    }

    /// The spectrum model of the radar in force.
    pub fn spectrum(&self) -> Option<&SpectrumModel> {
        self.radar.as_ref().map(|r| &r.spectrum)
    }

    /// The range axis of the radar in force.
    pub fn axis(&self) -> Option<RangeAxis> {
        self.radar.as_ref().map(|r| r.axis)
    }

    /// The geometry in force.
    pub fn geometry(&self) -> Option<&protocol::Geometry> {
        self.radar.as_ref().map(|r| &r.geometry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry(azimuths: u16, bins: u16) -> protocol::Geometry {
        protocol::Geometry {
            azimuth_samples: azimuths,
            range_in_bins: bins,
            ..protocol::Geometry::cts350x()
        }
    }

    #[test]
    fn the_largest_legal_geometry_is_refused_before_any_detector_state_is_allocated() {
        let settings = super::super::PipelineSettings::from_config(&config::Config::default())
            .unwrap()
            .front_end();
        let mut fe = FrontEnd::new(settings);
        // 65,535 x 65,535 bins would need 68 GB of TPP state.
        let err = fe.configure(&geometry(u16::MAX, u16::MAX)).unwrap_err();
        assert!(
            matches!(err, GeometryError::DetectorStateTooLarge { needed_bytes, budget_bytes, .. }
                if needed_bytes > 60_000_000_000 && budget_bytes == 256 << 20),
            "{err}"
        );
        assert!(fe.geometry().is_none());
        // A CTS350-X fits (23 MiB).
        fe.configure(&geometry(400, 3768)).unwrap();
        assert_eq!(
            fe.detector_state_bytes(&geometry(400, 3768)),
            400 * 3768 * 16
        );
    }
}
