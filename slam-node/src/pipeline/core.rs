//! The pipeline proper: one azimuth at a time, at its own timestamp, from a measured
//! spectrum to filter updates, with per-rotation diagnostics. No IO, no threads: the thread
//! loop in [`super::run`] feeds it and ships its [`OutputEvent`]s to the writer.

use std::time::Instant;

use nalgebra::Matrix3;
use radar_driver::Azimuth;
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::spectrum::{SpectrumGeometry, SpectrumModel};
use tracing::{info, warn};

use super::beams::BeamAssembler;
use super::odometry::OdometryQueue;
use super::settings::PipelineSettings;
use super::spectrum::{compare_beam, SpectrumScratch, SpectrumTally};
use super::summary::PipelineSummary;
use super::truth::{nearest_feature, PoseErrorStats, TruthOracle};
use crate::detect::{
    BeamDetection, BeamDetector, Detection, FloorProfile, Grouper, Observation, RangeAxis,
};
use crate::output::{OutputEvent, PoseSample, RotationDiagnostics, SpectrumComparison};
use slam_filter::{BeamObservation, BeamReport, Ekf, FilterError, OdometrySample, RadarBeamModel};

/// The filter the daemon runs.
pub type DaemonEkf = Ekf<MotionModel, RadarBeamModel>;

/// Why the pipeline could not start.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The filter rejected its settings or initial state.
    #[error("the filter could not start")]
    Filter(#[from] FilterError),
    /// The radar's geometry does not make a spectrum model.
    #[error("radar geometry: {0}")]
    Geometry(String),
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

/// Buffers reused across azimuths.
#[derive(Debug, Default)]
struct Scratch {
    measured: Vec<f64>,
    detections: Vec<Detection>,
    beam_detections: Vec<BeamDetection>,
    released: Vec<Observation>,
    beams: Vec<BeamObservation>,
    spectrum: SpectrumScratch,
}

/// The daemon's processing state.
#[derive(Debug)]
pub struct Pipeline {
    settings: PipelineSettings,
    ekf: DaemonEkf,
    radar: Option<RadarState>,
    grouper: Option<Grouper>,
    assembler: BeamAssembler,
    odometry: OdometryQueue,
    held: Option<OdometrySample>,
    truth: Option<Box<dyn TruthOracle>>,
    scratch: Scratch,
    rot: RotationDiagnostics,
    rot_spectrum: SpectrumTally,
    rot_nis: (f64, u64),
    rot_sample: Option<(usize, SpectrumComparison)>,
    rot_chosen: Vec<SpectrumComparison>,
    last_encoder: Option<u16>,
    last_time_s: Option<f64>,
    summary: PipelineSummary,
    pose_errors: PoseErrorStats,
    in_range: Vec<bool>,
    last_no_odometry_warning_s: f64,
    filter_started: bool,
}

impl Pipeline {
    /// A pipeline whose filter starts at the configured pose at `start_time_s` (or at the
    /// first odometry sample when `None`), scoring itself against `truth` when given.
    pub fn new(
        settings: PipelineSettings,
        start_time_s: Option<f64>,
        truth: Option<Box<dyn TruthOracle>>,
    ) -> Result<Self, PipelineError> {
        let [x, y, theta] = settings.initial_pose;
        let [sx, sy, st] = settings.initial_pose_std;
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(sx * sx, sy * sy, st * st));
        let ekf = Ekf::new(
            settings.filter.clone(),
            Pose2::new(x, y, wrap_angle(theta)),
            cov,
            start_time_s.unwrap_or(0.0),
            settings.motion,
            RadarBeamModel {
                power: settings.power,
            },
        )?;
        let in_range = vec![false; truth.as_ref().map_or(0, |t| t.features().len())];
        Ok(Self {
            assembler: BeamAssembler::new(0.5 * settings.beam_width_rad, 0.02),
            ekf,
            radar: None,
            grouper: None,
            odometry: OdometryQueue::new(1 << 16),
            held: None,
            truth,
            scratch: Scratch::default(),
            rot: RotationDiagnostics::default(),
            rot_spectrum: SpectrumTally::default(),
            rot_nis: (0.0, 0),
            rot_sample: None,
            rot_chosen: Vec::new(),
            last_encoder: None,
            last_time_s: None,
            summary: PipelineSummary::default(),
            pose_errors: PoseErrorStats::default(),
            in_range,
            last_no_odometry_warning_s: f64::NEG_INFINITY,
            filter_started: false,
            settings,
        })
    }

    /// The filter.
    pub fn ekf(&self) -> &DaemonEkf {
        &self.ekf
    }

    /// The settings in force.
    pub fn settings(&self) -> &PipelineSettings {
        &self.settings
    }

    /// Newest odometry time received (not necessarily applied).
    pub fn odometry_latest_s(&self) -> Option<f64> {
        self.odometry.latest_s()
    }

    /// Stream time of the last azimuth processed.
    pub fn last_time_s(&self) -> Option<f64> {
        self.last_time_s
    }

    /// Running totals.
    pub fn summary(&self) -> &PipelineSummary {
        &self.summary
    }

    /// With ground truth, the map frame is defined as the true pose at the first odometry
    /// sample: the filter is (re)started there, before any feature exists. Without truth the
    /// configured initial pose at the first sample defines it.
    fn start_at_first_odometry(&mut self, sample: &OdometrySample) {
        if self.filter_started || self.held.is_some() || self.ekf.feature_count() > 0 {
            return;
        }
        self.filter_started = true;
        let Some(pose) = self
            .truth
            .as_ref()
            .and_then(|t| t.pose_at(sample.timestamp_s))
        else {
            return;
        };
        let [sx, sy, st] = self.settings.initial_pose_std;
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(sx * sx, sy * sy, st * st));
        match Ekf::new(
            self.settings.filter.clone(),
            pose,
            cov,
            sample.timestamp_s,
            self.settings.motion,
            RadarBeamModel {
                power: self.settings.power,
            },
        ) {
            Ok(ekf) => {
                info!(
                    time_s = sample.timestamp_s,
                    x_m = pose.x,
                    y_m = pose.y,
                    theta_rad = pose.theta,
                    "map frame: the true pose at the first odometry sample"
                );
                self.ekf = ekf;
            }
            Err(e) => {
                warn!(error = %e, "could not restart the filter at the first odometry sample")
            }
        }
    }

    /// Takes one odometry sample (queued until the radar reaches its time).
    pub fn push_odometry(&mut self, sample: OdometrySample) {
        self.start_at_first_odometry(&sample);
        self.summary.odometry_samples += 1;
        if let Some(forced) = self.odometry.push(sample) {
            self.apply_odometry(forced);
        }
    }

    fn apply_odometry(&mut self, s: OdometrySample) {
        match self.ekf.apply_odometry(s) {
            Ok(()) => self.held = Some(s),
            Err(e) => {
                self.summary.filter_errors += 1;
                warn!(error = %e, "odometry sample rejected by the filter");
            }
        }
    }

    fn radar_for(&mut self, geometry: &protocol::Geometry) -> Result<(), PipelineError> {
        if self.radar.as_ref().is_some_and(|r| &r.geometry == geometry) {
            return Ok(());
        }
        let bin_m = geometry.range_gain * geometry.bin_size_m;
        let sg = SpectrumGeometry {
            bins: usize::from(geometry.range_in_bins),
            bin_size_m: bin_m,
            range_offset_m: geometry.range_offset_m,
        };
        let spectrum = SpectrumModel::new(sg, &self.settings.compensation, self.settings.noise)
            .map_err(|e| PipelineError::Geometry(e.to_string()))?;
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

    /// Processes one azimuth; events for the writer go to `events`.
    pub fn process_azimuth(
        &mut self,
        az: &Azimuth,
        events: &mut Vec<OutputEvent>,
    ) -> Result<(), PipelineError> {
        if !az.timestamp_s.is_finite() {
            self.summary.bad_azimuths += 1;
            return Ok(());
        }
        if self.last_time_s.is_some_and(|t| az.timestamp_s < t) {
            // Time went backwards on the wire: nothing sensible can be done with it.
            self.summary.bad_azimuths += 1;
            return Ok(());
        }
        if az.encoder >= az.geometry.encoder_size {
            // An encoder value past the revolution: malformed, and it would index nothing.
            self.summary.bad_azimuths += 1;
            return Ok(());
        }
        self.radar_for(&az.geometry)?;
        if self.last_encoder.is_some_and(|e| az.encoder < e) {
            self.end_rotation(events);
        }
        self.last_encoder = Some(az.encoder);
        self.last_time_s = Some(az.timestamp_s);
        self.summary.first_time_s.get_or_insert(az.timestamp_s);
        self.summary.last_time_s = Some(az.timestamp_s);
        let started = Instant::now();
        let bearing = wrap_angle(az.angle_rad);
        let Some(radar) = self.radar.as_mut() else {
            return Ok(());
        };
        // Slot = azimuth index: encoder x azimuths / encoder size, in u32 (no overflow).
        let slot = u32::from(az.encoder) * u32::from(radar.geometry.azimuth_samples)
            / u32::from(radar.geometry.encoder_size.max(1));
        let slot = usize::try_from(slot).unwrap_or(0);
        let s = &mut self.scratch;
        s.measured.clear();
        s.measured.extend(az.bins_db());
        let gain = radar.spectrum.gain_db();
        let n = s.measured.len().min(gain.len());
        s.measured.truncate(n);
        s.detections.clear();
        if n > 0 {
            radar.detector.detect(
                slot,
                &s.measured,
                gain.get(..n).unwrap_or_default(),
                radar.floor.floor(n),
                &radar.axis,
                &mut s.detections,
            );
        }
        s.beam_detections.clear();
        s.beam_detections
            .extend(s.detections.iter().map(|d| BeamDetection {
                range_m: d.range_m,
                power_db: d.power_db,
            }));
        s.released.clear();
        if let Some(g) = self.grouper.as_mut() {
            g.push(bearing, az.timestamp_s, &s.beam_detections, &mut s.released);
        }
        self.rot.azimuths += 1;
        self.rot.detections += u32::try_from(s.detections.len()).unwrap_or(u32::MAX);
        self.rot.observations += u32::try_from(s.released.len()).unwrap_or(u32::MAX);
        let detected = Instant::now();
        self.rot.detect_ms += ms(started, detected);
        let released = std::mem::take(&mut self.scratch.released);
        for o in &released {
            self.assembler.push(*o, &mut self.scratch.beams);
        }
        self.scratch.released = released;
        self.run_beams();
        let filtered = Instant::now();
        self.rot.filter_ms += ms(detected, filtered);
        self.check_spectrum(az, bearing);
        let done = Instant::now();
        self.rot.spectrum_ms += ms(filtered, done);
        self.rot.total_ms += ms(started, done);
        Ok(())
    }

    fn run_beams(&mut self) {
        let beams = std::mem::take(&mut self.scratch.beams);
        for beam in &beams {
            self.run_beam(beam);
        }
        self.scratch.beams = beams;
        self.scratch.beams.clear();
    }

    fn run_beam(&mut self, beam: &BeamObservation) {
        while let Some(s) = self.odometry.pop_until(beam.timestamp_s) {
            self.apply_odometry(s);
        }
        let Some(held) = self.held else {
            self.summary.refused.no_odometry += 1;
            if beam.timestamp_s - self.last_no_odometry_warning_s > 5.0 {
                self.last_no_odometry_warning_s = beam.timestamp_s;
                warn!(
                    time_s = beam.timestamp_s,
                    "no odometry yet: refusing to update the map (no dead reckoning is fabricated)"
                );
            }
            return;
        };
        if beam.timestamp_s - held.timestamp_s > self.settings.odometry_stale_s {
            self.summary.refused.stale_odometry += 1;
            if beam.timestamp_s - self.last_no_odometry_warning_s > 5.0 {
                self.last_no_odometry_warning_s = beam.timestamp_s;
                warn!(
                    time_s = beam.timestamp_s,
                    odometry_age_s = beam.timestamp_s - held.timestamp_s,
                    "odometry is stale: refusing to update the map until it returns"
                );
            }
            return;
        }
        match self.ekf.process_beam(beam) {
            Ok(report) => self.account(beam, &report),
            Err(FilterError::TimeWentBackwards { .. }) => self.summary.refused.late_beams += 1,
            Err(e) => {
                self.summary.filter_errors += 1;
                warn!(error = %e, time_s = beam.timestamp_s, "beam update failed");
            }
        }
    }

    fn account(&mut self, beam: &BeamObservation, report: &BeamReport) {
        self.summary.beams += 1;
        let associated = u32::try_from(report.associated.len()).unwrap_or(u32::MAX);
        self.rot.associated += associated;
        self.rot.new_features += u32::try_from(report.initialised.len()).unwrap_or(u32::MAX);
        self.rot.retired += u32::try_from(report.retired.len()).unwrap_or(u32::MAX);
        self.rot.tentative += u32::try_from(report.new_tentatives).unwrap_or(u32::MAX);
        let unclaimed = beam.targets.len().saturating_sub(report.associated.len());
        let placed = report.initialised.len() + report.new_tentatives;
        self.rot.rejected += u32::try_from(unclaimed.saturating_sub(placed)).unwrap_or(0);
        if let Some(u) = &report.update {
            if u.dof > 0 && u.nis.is_finite() {
                self.rot_nis.0 += u.nis / u.dof as f64;
                self.rot_nis.1 += 1;
            }
        }
        self.summary.associations += u64::from(associated);
        let Some(truth) = self.truth.as_ref() else {
            return;
        };
        let Some(true_pose) = truth.pose_at(beam.timestamp_s) else {
            return;
        };
        for &(j, id) in &report.associated {
            let (Some(t), Some(f)) = (beam.targets.get(j), self.ekf.feature(id)) else {
                continue;
            };
            let xy = true_pose.point_at(t.range_m, t.bearing_rad);
            let seen = nearest_feature(truth.features(), xy, 1.5).map(|(i, _)| i);
            let mapped = nearest_feature(truth.features(), [f.x_m, f.y_m], 2.0).map(|(i, _)| i);
            if let Some(tf) = seen.and_then(|a| truth.features().get(a)) {
                let rb = range_bearing(&true_pose, [tf.x_m, tf.y_m]);
                self.summary
                    .observation_errors
                    .get_or_insert_with(Default::default)
                    .add(
                        t.range_m - rb.range_m,
                        wrap_angle(t.bearing_rad - rb.bearing_rad),
                    );
            }
            match (seen, mapped) {
                (Some(a), Some(b)) if a != b => {
                    self.summary.association_errors += 1;
                    *self.rot.association_errors.get_or_insert(0) += 1;
                }
                (None, _) => self.summary.clutter_associations += 1,
                _ => {}
            }
        }
    }

    /// The pose predicted to `time_s` from the filter's current estimate with the held
    /// odometry (the filter itself is not moved).
    pub fn predicted_pose(&self, time_s: f64) -> Option<Pose2> {
        let held = self.held?;
        let pose = self.ekf.pose();
        let dt = time_s - self.ekf.state().time_s();
        if dt <= 0.0 {
            return Some(pose);
        }
        self.settings
            .motion
            .predict(
                &pose,
                &ControlInput::new(held.speed_mps, held.steer_rad),
                dt,
            )
            .ok()
    }

    fn check_spectrum(&mut self, az: &Azimuth, bearing: f64) {
        let every = self.settings.spectrum_every_azimuths;
        if every == 0 || self.ekf.feature_count() == 0 {
            return;
        }
        let slot = usize::from(az.encoder);
        if slot % every != 0 && every > 1 {
            return;
        }
        let Some(pose) = self.predicted_pose(az.timestamp_s) else {
            return;
        };
        let Some(radar) = self.radar.as_ref() else {
            return;
        };
        let found = compare_beam(
            self.ekf.state(),
            &pose,
            bearing,
            0.5 * self.settings.beam_width_rad,
            &self.settings.power,
            &radar.spectrum,
            &self.scratch.measured,
            self.settings.spectrum_bound_db,
            &mut self.scratch.spectrum,
        );
        let Some((features, tally)) = found else {
            return;
        };
        self.rot_spectrum.merge(&tally);
        let every_rot = self.settings.spectrum_sample_every_rotations;
        if every_rot == 0 || self.summary.rotations % every_rot != every_rot - 1 {
            return;
        }
        let chosen = &self.settings.spectrum_bearings_rad;
        let half_step = std::f64::consts::PI / f64::from(radar.geometry.azimuth_samples.max(1));
        let is_chosen = chosen
            .iter()
            .any(|b| wrap_angle(bearing - b).abs() <= half_step);
        let better = self
            .rot_sample
            .as_ref()
            .map_or(true, |(k, _)| features > *k);
        if !(is_chosen || (chosen.is_empty() && better)) {
            return;
        }
        let n = self.scratch.measured.len();
        let sample = SpectrumComparison {
            rotation: self.summary.rotations,
            bearing_rad: bearing,
            first_bin_m: radar.axis.first_bin_m,
            bin_m: radar.axis.bin_m,
            measured_db: self.scratch.measured.clone(),
            predicted_db: self
                .scratch
                .spectrum
                .predicted
                .get(..n)
                .unwrap_or_default()
                .to_vec(),
            bound_db: self.settings.spectrum_bound_db,
        };
        if is_chosen {
            self.rot_chosen.push(sample);
        } else {
            self.rot_sample = Some((features, sample));
        }
    }

    /// Closes the current rotation: diagnostics, pose, truth comparison, map snapshot.
    pub fn end_rotation(&mut self, events: &mut Vec<OutputEvent>) {
        if self.rot.azimuths == 0 {
            return;
        }
        let mut d = std::mem::take(&mut self.rot);
        d.rotation = self.summary.rotations;
        d.timestamp_s = self.last_time_s.unwrap_or(0.0);
        d.map_size = u32::try_from(self.ekf.feature_count()).unwrap_or(u32::MAX);
        d.mean_nis = (self.rot_nis.1 > 0).then(|| self.rot_nis.0 / self.rot_nis.1 as f64);
        d.spectrum_in_bound_fraction = self.rot_spectrum.in_bound_fraction();
        d.spectrum_bias_db = self.rot_spectrum.bias_db();
        self.summary.spectrum.merge(&self.rot_spectrum);
        self.summary.add_rotation(&d);
        self.rot_nis = (0.0, 0);
        self.rot_spectrum = SpectrumTally::default();
        if let Some((_, sample)) = self.rot_sample.take() {
            events.push(OutputEvent::Spectrum(sample));
        }
        events.extend(self.rot_chosen.drain(..).map(OutputEvent::Spectrum));
        let pose = self.ekf.pose();
        let cov = self.ekf.pose_covariance();
        let t = self.ekf.state().time_s();
        events.push(OutputEvent::Pose(PoseSample {
            timestamp_s: t,
            x_m: pose.x,
            y_m: pose.y,
            theta_rad: pose.theta,
            covariance: [
                [cov[(0, 0)], cov[(0, 1)], cov[(0, 2)]],
                [cov[(1, 0)], cov[(1, 1)], cov[(1, 2)]],
                [cov[(2, 0)], cov[(2, 1)], cov[(2, 2)]],
            ],
        }));
        if let Some(truth_pose) = self.truth.as_ref().and_then(|tr| tr.pose_at(t)) {
            if self.held.is_some() {
                let nees = self.ekf.pose_nees(&truth_pose).ok();
                d.pose_error_x_m = Some(pose.x - truth_pose.x);
                d.pose_error_y_m = Some(pose.y - truth_pose.y);
                d.pose_error_theta_rad = Some(wrap_angle(pose.theta - truth_pose.theta));
                d.pose_sigma_x_m = Some(cov[(0, 0)].max(0.0).sqrt());
                d.pose_sigma_y_m = Some(cov[(1, 1)].max(0.0).sqrt());
                d.pose_sigma_theta_rad = Some(cov[(2, 2)].max(0.0).sqrt());
                d.pose_nees = nees;
                self.pose_errors.add(
                    &pose,
                    [cov[(0, 0)], cov[(1, 1)], cov[(2, 2)]],
                    &truth_pose,
                    nees,
                );
            }
            let max_range = self.settings.filter.max_range_m;
            if let Some(tr) = self.truth.as_ref() {
                for (flag, f) in self.in_range.iter_mut().zip(tr.features()) {
                    if (f.x_m - truth_pose.x).hypot(f.y_m - truth_pose.y) <= max_range {
                        *flag = true;
                    }
                }
            }
        }
        let every = self.settings.map_every_rotations;
        if every > 0 && self.summary.rotations % every == 0 {
            events.push(OutputEvent::Map(super::summary::snapshot(&self.ekf)));
        }
        events.push(OutputEvent::Rotation(Box::new(d)));
    }

    /// Flushes everything still pending (end of stream), closes the last rotation, and
    /// returns the summary with the truth comparison.
    pub fn finish(&mut self, events: &mut Vec<OutputEvent>) -> PipelineSummary {
        let mut released = Vec::new();
        if let Some(g) = self.grouper.as_mut() {
            g.flush(&mut released);
        }
        for o in released {
            self.assembler.push(o, &mut self.scratch.beams);
        }
        self.assembler.flush(&mut self.scratch.beams);
        self.run_beams();
        self.end_rotation(events);
        events.push(OutputEvent::Map(super::summary::snapshot(&self.ekf)));
        let mut s = self.summary.clone();
        s.map_size = self.ekf.feature_count();
        s.odometry_out_of_order = self.odometry.out_of_order();
        if let Some(tr) = self.truth.as_ref() {
            s.pose = Some(self.pose_errors.clone());
            let in_range = self.in_range.iter().filter(|&&b| b).count();
            let mut score = super::truth::score_map(
                &self.ekf.features(),
                tr.features(),
                in_range,
                2.0,
                self.settings.filter.initial_rho,
                self.settings.filter.initial_alpha,
            );
            score.loss_db = self.ekf.state().loss_db();
            if let Some(true_loss) = tr.loss_db() {
                score.true_loss_db = Some(true_loss);
                score.mean_rho_error_gauge_fixed = Some(super::truth::gauge_fixed_rho_error(
                    &self.ekf.features(),
                    tr.features(),
                    2.0,
                    score.loss_db - true_loss,
                ));
            }
            s.map = Some(score);
        }
        s
    }
}

fn ms(a: Instant, b: Instant) -> f64 {
    b.duration_since(a).as_secs_f64() * 1e3
}
