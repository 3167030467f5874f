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
use tracing::info;

use super::beams::{BeamAssembler, OfferedBeam};
use crate::detect::{
    BeamDetection, BeamDetector, Detection, DetectorKind, DetectorSettings, FloorProfile,
    GainLearner, Grouper, GroupingSettings, LearnedFloor, LineDetector, LinePeak, LineSettings,
    Observation, RangeAxis,
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
    /// FMCW range-Doppler coupling (s): see [`doppler_range_shift_m`].
    pub doppler_range_coupling_s: f64,
    /// Receiver compensation to remove from measured spectra.
    pub compensation: Compensation,
    /// Noise model (the target-absent floor the detector is told about).
    pub noise: NoiseModel,
    /// Bytes the detector may keep across rotations; a geometry needing more is refused.
    pub max_detector_state_bytes: usize,
    /// The learned detector converts the measured spectrum to dB only for every this-many-th
    /// azimuth (the spectrum comparison's); 0: never.
    pub keep_spectrum_every: usize,
    /// The spectrum comparison's constant bound (dB), where none is learned.
    pub spectrum_bound_db: f64,
}

/// What to add to a detection's range to undo an FMCW radar's range-Doppler coupling: a
/// sawtooth chirp reads a return closing at `v` m/s `coupling_s * v` metres short, so
/// returns ahead of a moving vehicle come in short and those behind long, by 0.4 m at 8 m/s
/// for a CTS350-X (`coupling_s` about 0.049 s, Burnett et al., "Do we need to compensate for
/// motion distortion and Doppler effects in spinning radar navigation?", RA-L 2021).
/// Uncorrected, a landmark seems to move with the vehicle's speed changes, and the radar
/// reads every deceleration as less distance driven. The closing speed of a static return
/// along a beam at `bearing_rad` (clockwise from forward) is `speed * cos(bearing)`; the
/// vehicle's sideways speed (yaw rate times the radar's lever arm) is neglected.
pub fn doppler_range_shift_m(coupling_s: f64, speed_mps: f64, bearing_rad: f64) -> f64 {
    let shift = coupling_s * speed_mps * bearing_rad.cos();
    if shift.is_finite() {
        shift
    } else {
        0.0
    }
}

/// Whether an observation of `class` goes to the filter: a strong point-like return always
/// (it may start a feature), a weaker point-like one when it lies near a mapped feature
/// (`near_map`, asked only then), an extended one only with `extended_reobserve` and near
/// the map.
pub(crate) fn offered(
    class: LandmarkClass,
    extended_reobserve: bool,
    near_map: impl FnOnce() -> bool,
) -> bool {
    match class {
        LandmarkClass::New => true,
        LandmarkClass::Reobserve => near_map(),
        LandmarkClass::Extended => extended_reobserve && near_map(),
    }
}

impl FrontEndSettings {
    /// What an observation may do (see [`crate::detect::LandmarkSettings`]): a strong
    /// point-like return may become a feature; a weaker point-like one may only re-observe
    /// a mapped feature (the landmark test is strict for entering the map and lenient for
    /// staying in it, so a landmark whose return hovers near the SNR limit is not lost);
    /// an extended return never becomes a feature, and re-observes one only with
    /// [`crate::detect::LandmarkSettings::extended_reobserve`].
    pub fn landmark_class(&self, o: &Observation) -> LandmarkClass {
        let l = &self.detector.landmarks;
        if !l.points_only {
            return LandmarkClass::New;
        }
        if o.cut
            || o.extent_m > l.max_extent_m
            || o.width_rad > l.max_width_beams * self.beam_width_rad
        {
            return LandmarkClass::Extended;
        }
        if o.snr_db >= l.min_snr_db {
            LandmarkClass::New
        } else {
            LandmarkClass::Reobserve
        }
    }

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

/// What an observation may do in the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LandmarkClass {
    /// A point-like return strong enough to become a feature.
    New,
    /// Point-like but weaker: it may only re-observe a mapped feature.
    Reobserve,
    /// Extended structure: kept out of the map.
    Extended,
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
    learned: Option<Box<Learned>>,
}

/// The learned front end's state ([`DetectorKind::Learned`]).
#[derive(Debug)]
struct Learned {
    floor: LearnedFloor,
    gain: GainLearner,
    line: LineDetector,
    peaks: Vec<LinePeak>,
    /// The configured compensation per bin (where no gain is learned yet).
    configured_gain_db: Vec<f64>,
    /// The gain in force per bin.
    gain_db: Vec<f64>,
    /// 16-bit bins brought to the 8-bit scale.
    eight: Vec<u8>,
    /// Three standard deviations of the learned background per bin: the spectrum
    /// comparison's bound.
    bound_db: Vec<f64>,
    /// Floor refreshes seen (the spectrum model follows them).
    refreshes: u64,
}

/// What the front end did with one azimuth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrontEndCounts {
    /// Targets detected down this azimuth.
    pub detections: usize,
    /// Observations (grouped across azimuths) released by this azimuth.
    pub observations: usize,
    /// Of those, extended returns kept out of the map.
    pub extended: usize,
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
    /// Geometries taken (each logged only at powers of two).
    geometry_changes: u64,
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
            geometry_changes: 0,
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
        // A radar that keeps changing its geometry must not log at the rate it sends it:
        // the 1st, 2nd, 4th, 8th... change.
        self.geometry_changes += 1;
        if self.geometry_changes.is_power_of_two() {
            info!(
                azimuths = geometry.azimuth_samples,
                bins = geometry.range_in_bins,
                bin_m,
                rotation_hz = geometry.rotation_hz,
                changes = self.geometry_changes,
                "radar geometry"
            );
        }
        self.grouper = Some(Grouper::new(
            self.settings.grouping(geometry.azimuth_samples),
        ));
        let floor = FloorProfile::new(
            &spectrum,
            &self.settings.noise.absent,
            self.settings.detector.floor_tail_pfa,
        );
        let learned = (self.settings.detector.kind == DetectorKind::Learned).then(|| {
            let bins = usize::from(geometry.range_in_bins);
            Box::new(Learned {
                floor: LearnedFloor::new(self.settings.detector.floor, bins),
                gain: GainLearner::new(self.settings.detector.gain),
                line: LineDetector::new(),
                peaks: Vec::with_capacity(self.settings.detector.peaks.max_peaks + 1),
                configured_gain_db: spectrum.gain_db().to_vec(),
                gain_db: spectrum.gain_db().to_vec(),
                eight: Vec::new(),
                bound_db: vec![self.settings.spectrum_bound_db; bins],
                refreshes: 0,
            })
        });
        self.radar = Some(RadarState {
            learned,
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
        if self.settings.detector.kind == DetectorKind::Learned {
            // Histograms per block of bins and per-bin tables: no per-azimuth state.
            return LearnedFloor::state_bytes(
                usize::from(geometry.range_in_bins),
                self.settings.detector.floor.block_bins,
            );
        }
        if self.settings.detector.kind != DetectorKind::Tpp {
            return 0;
        }
        usize::from(geometry.azimuth_samples)
            .saturating_mul(usize::from(geometry.range_in_bins))
            .saturating_mul(crate::detect::tpp::STATE_BYTES_PER_BIN)
    }

    /// Detects and groups one azimuth (its geometry must have been [`Self::configure`]d):
    /// beams the grouping completes go to `beams`. `index` is the azimuth's index in the
    /// rotation ([`protocol::Geometry::azimuth_index`]), `bearing_rad` its bearing.
    ///
    /// `near_map` tells whether an observation lies near a mapped feature: a point-like
    /// return too weak to start a feature is offered to the filter only then.
    /// `sensor_speed_mps` is the vehicle's forward speed, for the range-Doppler correction
    /// ([`doppler_range_shift_m`]; nothing is corrected when the coupling is 0).
    pub fn process(
        &mut self,
        az: &Azimuth,
        index: u16,
        bearing_rad: f64,
        sensor_speed_mps: f64,
        beams: &mut Vec<OfferedBeam>,
        near_map: impl Fn(&Observation) -> bool,
    ) -> FrontEndCounts {
        let Some(radar) = self.radar.as_mut() else {
            return FrontEndCounts::default();
        };
        // A contoured or blanked azimuth is shorter: remember how far it reached, so that
        // missing range is not taken for empty range.
        let full = usize::from(radar.geometry.range_in_bins);
        let bins = az.bin_count();
        let covered = (bins < full).then(|| radar.axis.range_m(bins as f64 - 0.5).max(0.0));
        let slots = usize::from(radar.geometry.azimuth_samples);
        if self.short.len() != slots {
            self.short = vec![None; slots];
        }
        if let Some(slot) = self.short.get_mut(usize::from(index)) {
            *slot = covered;
        }
        self.detections.clear();
        self.measured.clear();
        match radar.learned.as_deref_mut() {
            Some(learned) => {
                // The measured spectrum in dB is wanted only for the spectrum comparison.
                let every = self.settings.keep_spectrum_every;
                if every > 0 && usize::from(index) % every == 0 {
                    self.measured.extend(az.bins_db().take(full));
                }
                detect_learned(
                    learned,
                    az,
                    &radar.axis,
                    &mut radar.spectrum,
                    &self.settings.detector,
                    &mut self.detections,
                );
            }
            None => {
                self.measured.extend(az.bins_db());
                let gain = radar.spectrum.gain_db();
                let n = self.measured.len().min(gain.len());
                self.measured.truncate(n);
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
            }
        }
        let shift = doppler_range_shift_m(
            self.settings.doppler_range_coupling_s,
            sensor_speed_mps,
            bearing_rad,
        );
        if shift != 0.0 {
            for d in &mut self.detections {
                d.range_m = (d.range_m + shift).max(0.0);
            }
        }
        self.beam_detections.clear();
        self.beam_detections
            .extend(self.detections.iter().map(|d| BeamDetection {
                range_m: d.range_m,
                power_db: d.power_db,
                extent_m: d.extent_m,
                snr_db: d.snr_db,
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
        let mut extended = 0;
        for o in &self.released {
            let class = self.settings.landmark_class(o);
            if class == LandmarkClass::Extended {
                extended += 1;
            }
            // Anything but a strong point-like return only re-observes, and only near the
            // map; an extended one not even that unless configured.
            let offer = offered(
                class,
                self.settings.detector.landmarks.extended_reobserve,
                || near_map(o),
            );
            if offer {
                let mut o = *o;
                o.may_start = class == LandmarkClass::New;
                self.assembler.push(o, beams);
            }
        }
        FrontEndCounts {
            detections: self.detections.len(),
            observations: self.released.len(),
            extended,
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
            .is_none_or(|covered| range_m <= covered)
    }

    /// Releases everything still held (end of stream) into `beams`.
    pub fn flush(&mut self, beams: &mut Vec<OfferedBeam>) {
        let mut released = Vec::new();
        if let Some(g) = self.grouper.as_mut() {
            g.flush(&mut released);
        }
        for o in released {
            if self.settings.landmark_class(&o) == LandmarkClass::New {
                self.assembler.push(o, beams);
            }
        }
        self.assembler.flush(beams);
    }

    /// The last azimuth's spectrum in dB as measured (compensation not removed), cut to the
    /// spectrum model's bins. With the learned detector it is kept only for every
    /// `keep_spectrum_every`-th azimuth and is empty otherwise.
    pub fn measured_db(&self) -> &[f64] {
        &self.measured
    }

    /// The spectrum comparison's bound per bin, dB, when it is learned (three sigma of the
    /// learned floor); `None`: the configured constant bound.
    pub fn spectrum_bound_db(&self) -> Option<&[f64]> {
        let learned = self.radar.as_ref()?.learned.as_deref()?;
        learned
            .floor
            .is_ready()
            .then_some(learned.bound_db.as_slice())
    }

    /// The learned floor, when the learned detector runs.
    pub fn learned_floor(&self) -> Option<&LearnedFloor> {
        Some(&self.radar.as_ref()?.learned.as_deref()?.floor)
    }

    /// The learned compensation slope (dB per decade), once there is one.
    pub fn learned_gain_slope(&self) -> Option<f64> {
        self.radar
            .as_ref()?
            .learned
            .as_deref()?
            .gain
            .slope_db_per_decade()
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

/// One azimuth through the learned front end: 8-bit bins, smoothing, the learned floor,
/// the line-rate detector, the learned gain; detections with their uncompensated powers.
fn detect_learned(
    learned: &mut Learned,
    az: &Azimuth,
    axis: &RangeAxis,
    spectrum: &mut SpectrumModel,
    settings: &DetectorSettings,
    out: &mut Vec<Detection>,
) {
    let full = learned.gain_db.len();
    let bins: &[u8] = match az.width {
        protocol::BinWidth::Eight => az.bins.get(..full.min(az.bins.len())).unwrap_or_default(),
        protocol::BinWidth::Sixteen => {
            learned.eight.clear();
            learned
                .eight
                .extend(az.bins_db().take(full).map(protocol::db_to_bin8));
            &learned.eight
        }
    };
    let line = LineSettings {
        merge_gap_bins: settings.peaks.merge_gap_bins,
        max_peaks: settings.peaks.max_peaks,
        min_range_m: settings.min_range_m,
        max_range_m: settings.max_range_m,
    };
    learned
        .line
        .detect(bins, &mut learned.floor, axis, &line, &mut learned.peaks);
    let l = &settings.landmarks;
    for p in &learned.peaks {
        let range_m = axis.range_m(p.bin);
        let extent_m = p.extent_bins as f64 * axis.bin_m;
        if extent_m <= l.max_extent_m {
            learned.gain.add(range_m, p.measured_db);
        }
        let gain = crate::detect::interpolate(&learned.gain_db, p.bin);
        out.push(Detection {
            range_m,
            power_db: p.measured_db - gain,
            bin: p.bin,
            extent_m,
            snr_db: p.snr_db,
        });
    }
    // After a floor refresh: refit the gain, and hand both to the spectrum model.
    if learned.floor.refreshes() != learned.refreshes {
        learned.refreshes = learned.floor.refreshes();
        learned.gain.refit();
        let axis = *axis;
        learned.gain.gain_into(
            &learned.configured_gain_db,
            |b| axis.range_m(b as f64),
            &mut learned.gain_db,
        );
        for (b, s) in learned
            .bound_db
            .iter_mut()
            .zip(learned.floor.background_sigma_db())
        {
            *b = 3.0 * s;
        }
        if let Err(e) = spectrum.set_tables(&learned.gain_db, learned.floor.background_db()) {
            tracing::warn!(error = %e, "the learned floor and gain were refused by the spectrum model");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A return ahead of a vehicle driving at 8 m/s reads 0.39 m short on a CTS350-X and
    /// one behind 0.39 m long: the correction adds and subtracts that; abeam nothing; no
    /// coupling or a non-finite speed corrects nothing.
    #[test]
    fn the_doppler_correction_lengthens_returns_ahead_and_shortens_those_behind() {
        let (beta, v) = (0.0488, 8.0);
        assert!((doppler_range_shift_m(beta, v, 0.0) - 0.3904).abs() < 1e-12);
        assert!((doppler_range_shift_m(beta, v, std::f64::consts::PI) + 0.3904).abs() < 1e-12);
        assert!(doppler_range_shift_m(beta, v, std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(doppler_range_shift_m(beta, v, -std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(doppler_range_shift_m(0.0, v, 0.0), 0.0);
        assert_eq!(doppler_range_shift_m(beta, f64::NAN, 0.0), 0.0);
        assert_eq!(doppler_range_shift_m(beta, f64::INFINITY, 0.0), 0.0);
    }

    /// Strong point-like returns always reach the filter, weaker ones only near the map,
    /// extended ones never unless configured (and then only near the map).
    #[test]
    fn extended_returns_reach_the_filter_only_when_configured_and_near_the_map() {
        use LandmarkClass::{Extended, New, Reobserve};
        for near in [false, true] {
            assert!(offered(New, false, || near));
            assert_eq!(offered(Reobserve, false, || near), near);
            assert!(!offered(Extended, false, || near));
            assert_eq!(offered(Extended, true, || near), near);
        }
        let settings =
            super::super::PipelineSettings::from_config(&config::Config::default()).unwrap();
        assert!(
            !settings.detector.landmarks.extended_reobserve,
            "off by default"
        );
    }

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
