//! The pipeline proper: one azimuth at a time, at its own timestamp, through stages with one
//! owner each. No IO, no threads: the thread loop in [`super::run`] feeds it and ships its
//! [`OutputEvent`]s to the writer.
//!
//! | stage | owner | what it owns |
//! |---|---|---|
//! | front end | [`FrontEnd`] | bins to dB, compensation removed, detection, grouping, beams |
//! | odometry gate | [`OdometryGate`] | odometry not yet applied; refusal without (fresh) odometry |
//! | filter | [`slam_filter::RadarEkf`] | the state, the held odometry, pose extrapolation |
//! | statistics | [`RotationStats`] | per-rotation counts, timings, NIS, spectrum comparison |
//! | submaps | [`SubmapRun`] (optional) | frozen submaps, their frames in the world, the switch, the global layer's thread |
//! | truth | [`TruthObserver`] (optional) | scores against ground truth, changes nothing |
//! | localisation | [`Localiser`] (optional) | a saved map's features in the filter, the search for the fix, what is published |

use std::sync::Arc;
use std::time::Instant;

use nalgebra::Matrix3;
use radar_driver::Azimuth;
use radar_model::geometry::{wrap_angle, Pose2};
use tracing::{info, warn};

use super::beams::OfferedBeam;
use super::clock::{Verdict, WireClock};
use super::ekf::DaemonEkf;
use super::frontend::{doppler_range_shift_m, FrontEnd, GeometryError};
use super::gate::{worth_logging, OdometryGate};
use super::localise::{LocaliseError, Localiser};
use super::radar_odometry::RadarOdometryStage;
use super::saved_map;
use super::settings::PipelineSettings;
use super::spectrum::{compare_beam, SpectrumScratch};
use super::stats::{RotationStats, StageTimes};
use super::submaps::SubmapRun;
use super::summary::PipelineSummary;
use super::truth::{TruthObserver, TruthOracle};
use crate::output::{MapSnapshot, OutputEvent, PoseSample, SpectrumComparison};
use slam_filter::{Ekf, FilterError, OdometrySample, RadarBeamModel};

/// Pending odometry samples held at most (past it the oldest is applied at once).
const ODOMETRY_QUEUE: usize = 1 << 16;
/// Azimuth timestamps may step forward by at most this (s) between azimuths; a wilder one
/// costs that azimuth unless this many consecutive azimuths confirm the new clock.
const AZIMUTH_MAX_STEP_S: f64 = 2.0;
const AZIMUTH_JUMP_CONFIRM: u32 = 16;
/// A radar silence (link down and back) up to this long (s) that the odometry's clock spans
/// is taken as a silence, not a clock jump: the filter predicts through it on odometry.
const AZIMUTH_MAX_SILENCE_S: f64 = 60.0;

/// Why the pipeline could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The filter rejected its settings or initial state.
    #[error("the filter could not start")]
    Filter(#[from] FilterError),
    /// The radar's geometry does not make a spectrum model.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// The global layer's thread could not be started.
    #[error("the global layer's thread could not be started")]
    GlobalLayer(#[source] std::io::Error),
    /// The settings could not be derived for the radar that connected.
    #[error(transparent)]
    Settings(#[from] super::settings::SettingsError),
    /// The saved map to localise in does not suit this run.
    #[error(transparent)]
    Localise(#[from] LocaliseError),
}

/// Warnings about a burst of targets at most this often (stream seconds).
const BURST_WARN_EVERY_S: f64 = 5.0;

/// The daemon's processing state.
#[derive(Debug)]
pub struct Pipeline {
    settings: PipelineSettings,
    front_end: FrontEnd,
    gate: OdometryGate,
    ekf: DaemonEkf,
    stats: RotationStats,
    truth: Option<TruthObserver>,
    submaps: Option<SubmapRun>,
    beams: Vec<OfferedBeam>,
    spectrum: SpectrumScratch,
    clock: WireClock,
    last_rotation: Option<u64>,
    last_time_s: Option<f64>,
    rotation_start_s: Option<f64>,
    summary: PipelineSummary,
    filter_started: bool,
    scan_match: RadarOdometryStage,
    /// The gyro's samples waiting for the radar's clock (radar only with a gyro).
    gyro: Option<super::gyro::GyroQueue>,
    /// With truth: each rotation's published pose and the true pose then.
    online: Vec<(PoseSample, Pose2)>,
    /// With truth and submaps: the filter's pose chained through the submaps' switch poses
    /// alone (the online pose without the global layer's corrections), with the truth.
    odometry_track: Vec<(PoseSample, Pose2)>,
    /// This thread's CPU clock when the last rotation closed (see `measure_cpu`).
    cpu_mark: Option<std::time::Duration>,
    /// The run's clock at the last periodic saved map (`[map] save_every_s`).
    last_map_save_s: Option<f64>,
    /// Localisation in a saved map (`[map] mode = "localise"` or `"extend"`).
    localise: Option<Localiser>,
    /// Extending the saved map once localised (`[map] mode = "extend"`).
    extend: Option<super::extend::Extension>,
    /// Extending: the published poses (`online`) before mapping started.
    online_before_mapping: Option<usize>,
    /// Stream time of the last warning about a burst of targets.
    burst_warned_s: f64,
    /// The time of the last pose published: a rotation that did not move the filter's clock
    /// (radar alone, before the first registration starts it) publishes nothing, rather than
    /// the same pose at the same time again.
    last_published_s: Option<f64>,
}

fn filter_at(
    settings: &PipelineSettings,
    pose: Pose2,
    time_s: f64,
) -> Result<DaemonEkf, FilterError> {
    let [sx, sy, st] = settings.initial_pose_std;
    let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(sx * sx, sy * sy, st * st));
    Ekf::new(
        settings.filter.clone(),
        pose,
        cov,
        time_s,
        settings.motion,
        RadarBeamModel {
            power: settings.power,
        },
    )
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
        let mut ekf = filter_at(
            &settings,
            Pose2::new(x, y, wrap_angle(theta)),
            start_time_s.unwrap_or(0.0),
        )?;
        let extend = match settings.localise.as_ref().filter(|l| l.extend) {
            Some(l) => {
                let options = settings
                    .submaps
                    .ok_or_else(|| LocaliseError::ExtendNeedsSubmaps(l.path.clone()))?;
                Some(super::extend::Extension::new(options, Arc::clone(&l.map)))
            }
            None => None,
        };
        // Extending, the submaps start at the fix.
        let submaps = settings
            .submaps
            .filter(|_| extend.is_none())
            .map(SubmapRun::new)
            .transpose()
            .map_err(PipelineError::GlobalLayer)?;
        let localise = match settings.localise.as_ref() {
            Some(l) => {
                let mut localiser = Localiser::new(l, &settings)?;
                localiser.begin(&mut ekf)?;
                Some(localiser)
            }
            None => None,
        };
        Ok(Self {
            localise,
            extend,
            online_before_mapping: None,
            submaps,
            front_end: FrontEnd::new(settings.front_end()),
            gate: OdometryGate::new(
                ODOMETRY_QUEUE,
                settings.odometry_stale_s,
                settings.odometry_limits,
            ),
            clock: WireClock::new(AZIMUTH_MAX_STEP_S, AZIMUTH_JUMP_CONFIRM),
            ekf,
            stats: RotationStats::default(),
            truth: truth.map(TruthObserver::new),
            beams: Vec::new(),
            spectrum: SpectrumScratch::default(),
            last_rotation: None,
            last_time_s: None,
            rotation_start_s: None,
            summary: PipelineSummary::default(),
            filter_started: false,
            scan_match: RadarOdometryStage::new(
                // The front end corrects the detections for the radar's range-Doppler
                // coupling at the speed held: radar odometry reads them again at the speed
                // it registers.
                radar_odometry::ScanMatchSettings {
                    doppler_coupling_s: settings.doppler_range_coupling_s,
                    ..settings.scan_match
                },
                settings.radar_drives,
                settings.motion,
                settings.gyro.is_some(),
            )
            .composing(settings.radar_compose),
            gyro: settings.gyro.map(super::gyro::GyroQueue::new),
            online: Vec::new(),
            odometry_track: Vec::new(),
            cpu_mark: None,
            last_map_save_s: None,
            burst_warned_s: f64::NEG_INFINITY,
            last_published_s: None,
            settings,
        })
    }

    /// The filter.
    pub fn ekf(&self) -> &DaemonEkf {
        &self.ekf
    }

    /// The submap stage, when the filter runs on submaps.
    pub fn submaps(&self) -> Option<&SubmapRun> {
        self.submaps.as_ref()
    }

    /// The estimated pose in the world and its covariance (through the current submap's
    /// frame when the filter runs on submaps).
    pub fn world_pose(&self) -> (Pose2, Matrix3<f64>) {
        let (pose, cov) = (self.ekf.pose(), self.ekf.pose_covariance());
        match self.submaps.as_ref() {
            Some(s) => s.to_world(&pose, &cov),
            None => (pose, cov),
        }
    }

    /// The front end.
    pub fn front_end(&self) -> &FrontEnd {
        &self.front_end
    }

    /// The settings in force.
    pub fn settings(&self) -> &PipelineSettings {
        &self.settings
    }

    /// Newest odometry time received (not necessarily applied).
    pub fn odometry_latest_s(&self) -> Option<f64> {
        self.gate.latest_s()
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
        if self.filter_started
            || self.ekf.held_odometry().is_some()
            || self.ekf.feature_count() > 0
            || self.localise.is_some()
        {
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
        match filter_at(&self.settings, pose, sample.timestamp_s) {
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

    /// Takes one gyro sample (queued until the radar reaches its time); without a gyro in
    /// the settings (not radar only, or no `[gyro]`) it is ignored.
    pub fn push_gyro(&mut self, sample: crate::source::gyro::GyroSample) {
        if let Some(q) = self.gyro.as_mut() {
            q.push(sample);
        }
    }

    /// Newest gyro time received; `None` before the first or without a gyro.
    pub fn gyro_latest_s(&self) -> Option<f64> {
        self.gyro.as_ref().and_then(|q| q.latest_s())
    }

    /// Gyro samples received so far (refused ones included).
    pub fn gyro_received(&self) -> u64 {
        self.gyro.as_ref().map_or(0, |q| q.counts().received)
    }

    /// Whether the pipeline uses a gyro.
    pub fn uses_gyro(&self) -> bool {
        self.gyro.is_some()
    }

    /// Takes one odometry sample (queued until the radar reaches its time).
    pub fn push_odometry(&mut self, sample: OdometrySample) {
        self.start_at_first_odometry(&sample);
        self.summary.odometry_samples += 1;
        // Refusals, duplicates and clock jumps are the gate's counts.
        if let Ok(Some(forced)) = self.gate.push(sample) {
            self.apply_odometry(forced);
        }
        self.summary.odometry_refused = self.gate.rejected();
        self.summary.odometry_duplicates = self.gate.duplicates();
        self.summary.odometry_clock_jumps = self.gate.clock_jumps();
    }

    fn apply_odometry(&mut self, s: OdometrySample) {
        let before = *self.ekf.stats();
        let from_s = self.ekf.state().time_s();
        if let Err(e) = self.ekf.apply_odometry(s) {
            self.summary.filter_errors += 1;
            warn!(error = %e, "odometry sample rejected by the filter");
        }
        let stats = self.ekf.stats();
        if stats.bridged_gaps > before.bridged_gaps && worth_logging(stats.bridged_gaps) {
            let gap_s = s.timestamp_s - from_s;
            if stats.reanchored_gaps > before.reanchored_gaps {
                warn!(
                    gap_s,
                    bridged = stats.bridged_gaps,
                    dropped = stats.retired - before.retired,
                    "no odometry across the gap and no map to relocalise against: the map starts again, its frame at the pose estimate"
                );
            } else {
                warn!(
                    gap_s,
                    bridged = stats.bridged_gaps,
                    "no odometry across the gap: the pose uncertainty grown by what the vehicle could have done meanwhile"
                );
            }
        }
    }

    /// Processes one azimuth; events for the writer go to `events`.
    pub fn process_azimuth(
        &mut self,
        az: &Azimuth,
        events: &mut Vec<OutputEvent>,
    ) -> Result<(), PipelineError> {
        // A silence of the radar (a link down and back) that the odometry's clock spans is
        // not a jump of the radar's clock: the filter predicts through it on odometry.
        match self.clock.observe_vouched(
            az.timestamp_s,
            self.gate.latest_s(),
            AZIMUTH_MAX_SILENCE_S,
        ) {
            Verdict::Accept => {}
            Verdict::Outlier => {
                // A wild timestamp (far ahead, backwards, not finite) costs this azimuth.
                self.summary.bad_azimuths += 1;
                self.summary.clock_outliers += 1;
                if worth_logging(self.summary.clock_outliers) {
                    warn!(
                        time_s = az.timestamp_s,
                        clock_s = self.clock.now_s(),
                        dropped = self.summary.clock_outliers,
                        "azimuth timestamp far from the radar's clock: azimuth dropped"
                    );
                }
                return Ok(());
            }
            Verdict::Jump { from_s, to_s } => {
                warn!(
                    from_s,
                    to_s,
                    "the radar's clock jumped: the filter moves to the new clock (map kept, pose uncertainty grown, odometry awaited)"
                );
                self.summary.clock_jumps += 1;
                self.summary.clock_jumped();
                self.end_rotation(events);
                self.last_rotation = None;
                if let Err(e) = self.ekf.resync_clock(to_s) {
                    warn!(error = %e, "could not move the filter to the new clock");
                }
            }
        }
        let Some(index) = az.geometry.azimuth_index(az.encoder) else {
            // An encoder value past the revolution: malformed, and it would index nothing.
            self.summary.bad_azimuths += 1;
            return Ok(());
        };
        self.front_end.configure(&az.geometry)?;
        // Rotation boundaries are the driver's: it numbers every azimuth's rotation.
        if self.last_rotation.is_some_and(|r| r != az.rotation) {
            self.end_rotation(events);
        }
        self.last_rotation = Some(az.rotation);
        self.last_time_s = Some(az.timestamp_s);
        self.rotation_start_s.get_or_insert(az.timestamp_s);
        self.summary.first_time_s.get_or_insert(az.timestamp_s);
        self.summary.last_time_s = Some(az.timestamp_s);
        let started = Instant::now();
        let bearing = wrap_angle(az.angle_rad);
        let ekf = &self.ekf;
        let radius = self.settings.detector.landmarks.reobserve_radius_m;
        let near_map = |o: &crate::detect::Observation| near_a_feature(ekf, o, radius);
        let speed = self.sensor_speed_mps();
        let counts = self
            .front_end
            .process(az, index, bearing, speed, &mut self.beams, near_map);
        self.summary.extended_returns += counts.extended as u64;
        if self.scan_match.enabled() {
            self.scan_match.add_azimuth(
                &self.ekf,
                az.timestamp_s,
                bearing,
                self.front_end.detections(),
                speed,
            );
        }
        let detected = Instant::now();
        self.run_beams();
        let filtered = Instant::now();
        self.check_spectrum(az, index, bearing);
        let done = Instant::now();
        self.stats.on_azimuth(
            counts,
            StageTimes {
                detect_ms: ms(started, detected),
                filter_ms: ms(detected, filtered),
                spectrum_ms: ms(filtered, done),
            },
        );
        Ok(())
    }

    fn run_beams(&mut self) {
        let beams = std::mem::take(&mut self.beams);
        for beam in &beams {
            self.run_beam(beam);
        }
        self.beams = beams;
        self.beams.clear();
    }

    /// One beam through the odometry gate into the filter.
    fn run_beam(&mut self, offered: &OfferedBeam) {
        let beam = &offered.beam;
        if let Some(q) = self.gyro.as_mut() {
            super::gyro::apply_until(q, &mut self.ekf, &self.settings.motion, beam.timestamp_s);
        }
        while let Some(s) = self.gate.next_until(beam.timestamp_s) {
            self.apply_odometry(s);
        }
        if self
            .gate
            .admit(&self.ekf, beam.timestamp_s, &mut self.summary.refused)
            .is_err()
        {
            return;
        }
        let covered = self.front_end.covered_range_m(beam.bearing_rad);
        let bursts = self.ekf.stats().burst_beams;
        let processed = self
            .ekf
            .process_beam_offered(beam, covered, &offered.may_start);
        if self.ekf.stats().burst_beams > bursts {
            self.summary.burst_beams += 1;
            if beam.timestamp_s - self.burst_warned_s > BURST_WARN_EVERY_S {
                self.burst_warned_s = beam.timestamp_s;
                warn!(
                    time_s = beam.timestamp_s,
                    beams = self.summary.burst_beams,
                    "a burst of targets far above the learned rate (a swamped receiver, interference): the radar is taken as blind, its beams are not used"
                );
            }
        }
        match processed {
            Ok(report) => {
                self.summary.beams += 1;
                let associated = self.stats.on_beam(beam, &report);
                self.summary.associations += u64::from(associated);
                if let Some(truth) = self.truth.as_mut() {
                    let frame = self
                        .submaps
                        .as_ref()
                        .filter(|s| s.current() > 0)
                        .map(|s| s.frame().0);
                    let wrong = truth.on_beam(beam, &report, &self.ekf, frame.as_ref());
                    self.stats.on_association_errors(wrong);
                }
            }
            Err(FilterError::TimeWentBackwards { .. }) => self.summary.refused.late_beams += 1,
            Err(e) => {
                self.summary.filter_errors += 1;
                warn!(error = %e, time_s = beam.timestamp_s, "beam update failed");
            }
        }
    }

    /// The pose predicted to `time_s` from the filter's current estimate with the held
    /// odometry (the filter itself is not moved).
    pub fn predicted_pose(&self, time_s: f64) -> Option<Pose2> {
        self.ekf.pose_at(time_s)
    }

    /// The vehicle's forward speed as the filter has it (the held odometry times its speed
    /// correction; 0 without odometry), for the range-Doppler correction.
    fn sensor_speed_mps(&self) -> f64 {
        self.ekf.held_odometry().map_or(0.0, |o| {
            slam_filter::predict::corrected_input(&o, self.ekf.state().odometry_bias()).0
        })
    }

    /// Whole-spectrum prediction against the measurement, on every k-th azimuth of the
    /// rotation (k counts azimuths, not encoder values).
    fn check_spectrum(&mut self, az: &Azimuth, index: u16, bearing: f64) {
        let every = self.settings.spectrum_every_azimuths;
        if every == 0 || self.ekf.feature_count() == 0 {
            return;
        }
        if !spectrum_due(index, every) {
            return;
        }
        let Some(mut pose) = self.predicted_pose(az.timestamp_s) else {
            return;
        };
        // The measured spectrum reads every return on this beam `shift` short (range-Doppler
        // coupling; the detections were corrected, the bins were not): predict it from the
        // radar moved `shift` along the beam, which shortens every range on it by `shift`.
        let shift = doppler_range_shift_m(
            self.settings.doppler_range_coupling_s,
            self.sensor_speed_mps(),
            bearing,
        );
        if shift != 0.0 {
            let [x, y] = pose.point_at(shift, bearing);
            pose = Pose2::new(x, y, pose.theta);
        }
        let (Some(spectrum), Some(axis), Some(geometry)) = (
            self.front_end.spectrum(),
            self.front_end.axis(),
            self.front_end.geometry(),
        ) else {
            return;
        };
        let measured = self.front_end.measured_db();
        if measured.is_empty() {
            return;
        }
        let found = compare_beam(
            self.ekf.state(),
            &pose,
            bearing,
            0.5 * self.settings.beam_width_rad,
            &self.settings.power,
            spectrum,
            measured,
            self.settings.spectrum_bound_db,
            self.front_end.spectrum_bound_db(),
            &mut self.spectrum,
        );
        let Some((features, tally)) = found else {
            return;
        };
        self.stats.on_spectrum(&tally);
        let every_rot = self.settings.spectrum_sample_every_rotations;
        if every_rot == 0 || self.summary.rotations % every_rot != every_rot - 1 {
            return;
        }
        let chosen = &self.settings.spectrum_bearings_rad;
        let half_step = 0.5 * geometry.azimuth_step_rad();
        let is_chosen = chosen
            .iter()
            .any(|b| wrap_angle(bearing - b).abs() <= half_step);
        if !(is_chosen || (chosen.is_empty() && self.stats.better_sample(features))) {
            return;
        }
        let n = measured.len();
        let sample = SpectrumComparison {
            rotation: self.summary.rotations,
            bearing_rad: bearing,
            first_bin_m: axis.first_bin_m,
            bin_m: axis.bin_m,
            measured_db: measured.to_vec(),
            predicted_db: self
                .spectrum
                .predicted
                .get(..n)
                .unwrap_or_default()
                .to_vec(),
            bound_db: self.settings.spectrum_bound_db,
        };
        self.stats.keep_sample(sample, features, is_chosen);
    }

    /// Warns (the 1st, 2nd, 4th... time) when a rotation took longer to process than the
    /// radar took to send it: the pipeline is falling behind real time.
    fn warn_if_behind(&mut self, rotation_ms: f64) {
        let Some(hz) = self.front_end.geometry().map(|g| g.rotation_hz) else {
            return;
        };
        let period_ms = 1e3 / hz;
        if !(hz > 0.0 && rotation_ms > period_ms) {
            return;
        }
        self.summary.rotations_behind += 1;
        if worth_logging(self.summary.rotations_behind) {
            warn!(
                rotation_ms,
                period_ms,
                features = self.ekf.feature_count(),
                count = self.summary.rotations_behind,
                "behind real time: a rotation took longer to process than the radar took to send it"
            );
        }
    }

    /// The map as written: material variances brought up to date first; with submaps, the
    /// frozen submaps' features through their (optimised) frames and the current one's.
    fn map_snapshot(&mut self) -> MapSnapshot {
        self.ekf.settle_material_noise();
        match self.submaps.as_ref() {
            Some(s) => s.map_snapshot(&self.ekf),
            None => MapSnapshot::from_state(self.ekf.state()),
        }
    }

    /// Closes the current rotation: diagnostics, pose, truth comparison, map snapshot.
    pub fn end_rotation(&mut self, events: &mut Vec<OutputEvent>) {
        if self.stats.is_empty() {
            return;
        }
        self.count_reobservations();
        self.reach_a_still_clocks_end();
        self.register_rotation();
        let front_end = &self.front_end;
        match self
            .ekf
            .retire_unseen_in_view(|bearing, range| front_end.covers(bearing, range))
        {
            Ok(gone) => self.stats.on_retired(gone.len()),
            Err(e) => warn!(error = %e, "retiring unseen features failed"),
        }
        let mut d = self.stats.close(
            self.summary.rotations,
            self.last_time_s.unwrap_or(0.0),
            self.ekf.feature_count(),
            &mut self.summary,
            events,
        );
        self.warn_if_behind(d.total_ms);
        self.measure_cpu();
        // Nothing is published before the filter's clock starts (on the radar alone, the
        // first rotation before a registration): its pose would carry no time (0.0). A
        // filter started at the truth's pose has its clock from the start.
        let now_s = self.ekf.state().time_s();
        let clock_started = self.ekf.held_odometry().is_some() || now_s != 0.0;
        let clock_moved = self.last_published_s != Some(now_s);
        // Localising: nothing is published in the map's frame before the fix.
        if let Some((pose, cov)) = self
            .pose_to_publish()
            .filter(|_| clock_started && clock_moved)
        {
            self.last_published_s = Some(now_s);
            let published = PoseSample {
                timestamp_s: self.ekf.state().time_s(),
                x_m: pose.x,
                y_m: pose.y,
                theta_rad: pose.theta,
                covariance: [
                    [cov[(0, 0)], cov[(0, 1)], cov[(0, 2)]],
                    [cov[(1, 0)], cov[(1, 1)], cov[(1, 2)]],
                    [cov[(2, 0)], cov[(2, 1)], cov[(2, 2)]],
                ],
            };
            // On submaps, the odometry: the filter's pose chained by the switch poses alone.
            let odometry = self.submaps.as_ref().map(|s| {
                let p = s.to_odometry(&self.ekf.pose());
                PoseSample {
                    x_m: p.x,
                    y_m: p.y,
                    theta_rad: p.theta,
                    ..published
                }
            });
            // With truth, the online trajectory is kept to be scored at the end (a pose a
            // rotation: 8.6 MB for six hours at 4 Hz).
            if let Some(truth) = self.truth.as_ref() {
                if let Some(t) = truth.pose_at(published.timestamp_s) {
                    self.online.push((published, t));
                    if let Some(chained) = odometry {
                        self.odometry_track.push((chained, t));
                    }
                }
            }
            events.push(OutputEvent::Pose(published));
            if let Some(chained) = odometry {
                events.push(OutputEvent::OdometryPose(chained));
            }
            if let Some(truth) = self.truth.as_mut() {
                truth.on_rotation(
                    self.ekf.state().time_s(),
                    pose,
                    cov,
                    self.ekf.held_odometry().is_some(),
                    self.settings.filter.max_range_m,
                    &mut d,
                );
            }
        }
        let every = self.settings.map_every_rotations;
        if every > 0 && self.summary.rotations.is_multiple_of(every) {
            let map = self.map_snapshot();
            events.push(OutputEvent::Map(map));
        }
        events.push(OutputEvent::Rotation(Box::new(d)));
        // The submap closes after this rotation's pose was published in it (a rotation that
        // did not move the filter's clock adds nothing to it).
        if let Some(s) = self
            .submaps
            .as_mut()
            .filter(|_| clock_started && clock_moved)
        {
            let t = self.ekf.state().time_s();
            s.end_rotation(&mut self.ekf, t);
            self.summary.current_submap = s.current();
        }
        self.save_map_if_due(events);
    }

    /// A prior pose in the saved map's frame (`[map] initial_pose_topic`): the localiser
    /// starts tracking from it at the next rotation's end. A run that does not localise
    /// has no map frame to take it in: it is counted nowhere and ignored.
    pub fn prior_pose(&mut self, p: super::localise::PriorPose) {
        if let Some(l) = self.localise.as_mut() {
            l.prior(p);
        }
    }

    /// The pose published this rotation: the filter's in the world; localising, the
    /// localiser's in the map's frame once it has a fix (after its rotation's work).
    fn pose_to_publish(&mut self) -> Option<(Pose2, Matrix3<f64>)> {
        if self.extend.as_ref().is_some_and(|x| x.mapping()) {
            return Some(self.world_pose());
        }
        let Some(l) = self.localise.as_mut() else {
            return Some(self.world_pose());
        };
        let t = self.ekf.state().time_s();
        l.end_rotation(&mut self.ekf, t, self.scan_match.last_cloud());
        let published = l.published(&self.ekf);
        if let Some(x) = self.extend.as_mut().filter(|x| x.due(l)) {
            let since = t - self.summary.first_time_s.unwrap_or(t);
            if let Some(run) = x.start(l, &mut self.ekf, &self.settings, since) {
                self.submaps = Some(run);
                // This rotation's pose is published and scored as localisation's.
                self.online_before_mapping = Some(self.online.len() + 1);
            }
        }
        published
    }

    /// Extending before mapping started: nothing to save (the saved map is not rewritten
    /// with the search's local map).
    fn nothing_to_save(&self) -> bool {
        self.extend.as_ref().is_some_and(|x| !x.mapping())
    }

    /// Every `[map] save_every_s` of the run's clock, and when asked (SIGUSR1): the saved
    /// map as it stands.
    fn save_map_if_due(&mut self, events: &mut Vec<OutputEvent>) {
        if self.nothing_to_save() {
            return;
        }
        if saved_map::take_save_request() {
            info!("saving the map, as asked");
            self.last_map_save_s = Some(self.ekf.state().time_s());
            self.ekf.settle_material_noise();
            self.push_saved_map(None, events);
            return;
        }
        let s = &self.settings.map_save;
        let Some(every) = s.every_s.filter(|_| s.enabled) else {
            return;
        };
        let t = self.ekf.state().time_s();
        let last = *self.last_map_save_s.get_or_insert(t);
        if t - last >= every {
            self.last_map_save_s = Some(t);
            self.ekf.settle_material_noise();
            self.push_saved_map(None, events);
        }
    }

    /// Builds the saved map and hands it to the writer (`loops`: the finished global
    /// layer's, at the end of the run).
    fn push_saved_map(
        &mut self,
        loops: Option<&[slam_graph::LoopClosure]>,
        events: &mut Vec<OutputEvent>,
    ) {
        let source = format!(
            "slam-node {}: {} rotations, to t = {:.3} s",
            env!("CARGO_PKG_VERSION"),
            self.summary.rotations,
            self.ekf.state().time_s()
        );
        let started = Instant::now();
        if let Some((map, mut counts)) = saved_map::build(
            &self.settings.map_save,
            self.front_end.geometry(),
            &self.ekf,
            self.submaps.as_ref(),
            loops,
            source,
        ) {
            let previous = self.summary.saved_map.map_or(0.0, |c| c.max_build_ms);
            counts.max_build_ms = previous.max(ms(started, Instant::now()));
            self.summary.saved_maps += 1;
            self.summary.saved_map = Some(counts);
            events.push(OutputEvent::SavedMap(Box::new(map)));
        }
    }

    /// Adds the CPU time this thread spent since the last rotation closed to the summary
    /// (the first rotation only sets the mark: the pipeline may have been built on another
    /// thread). Nothing when the platform has no per-thread CPU clock.
    fn measure_cpu(&mut self) {
        let Ok(now) = cpu_time::ThreadTime::try_now() else {
            return;
        };
        let now = now.as_duration();
        if let Some(mark) = self.cpu_mark.replace(now) {
            let spent = now.saturating_sub(mark);
            self.summary.add_cpu_ms(spent.as_secs_f64() * 1e3);
        }
    }

    /// Radar odometry: registers this rotation's cloud against the previous one's and gives
    /// the measured motion to the filter, then marks the filter for the next rotation; when
    /// it drives the filter, its sample for the next rotation goes through the odometry gate
    /// as any odometry does.
    fn register_rotation(&mut self) {
        if !self.scan_match.enabled() {
            return;
        }
        let started = Instant::now();
        let end_s = self
            .last_time_s
            .unwrap_or_else(|| self.ekf.state().time_s());
        if let Some(sample) = self.scan_match.end_rotation(
            &mut self.ekf,
            self.truth.as_ref(),
            end_s,
            self.settings.doppler_range_coupling_s,
        ) {
            // Radar only: the sample is the only odometry; it is applied at once, at its own
            // time, so that the next rotation is de-skewed with it.
            let t = sample.timestamp_s;
            self.push_odometry(sample);
            while let Some(s) = self.gate.next_until(t) {
                self.apply_odometry(s);
            }
        }
        if let (Some(submaps), Some(cloud)) = (self.submaps.as_mut(), self.scan_match.last_cloud())
        {
            submaps.add_scan(&self.ekf.pose(), cloud);
        }
        if self.ekf.held_odometry().is_some() {
            self.ekf.mark_motion();
        }
        self.stats.on_registration(ms(started, Instant::now()));
    }

    /// The filter's clock moves when a beam takes the odometry up to its time. A rotation
    /// with no beam for the filter (a street without point-like returns, an open field, a
    /// burst that blinds the radar) left it at the last rotation's end: the registration
    /// measured a motion over no time and the pose was published again at that time. Such a
    /// rotation's end is reached here, before the registration; a rotation with a beam is
    /// untouched.
    /// - On the radar alone, with the motion held: the registration's odometry sample had
    ///   carried the same time, the gate found the odometry stale a second later and refused
    ///   every beam after, and the filter never moved again.
    /// - With odometry of its own (wheels, a recording's), with the odometry received up to
    ///   the rotation's last azimuth: the lamp posts of a straight road, 18 beams in 561
    ///   rotations, gave 14 poses in 140 s.
    fn reach_a_still_clocks_end(&mut self) {
        let Some(end_s) = self.last_time_s else {
            return;
        };
        let now_s = self.ekf.state().time_s();
        if self.settings.radar_drives {
            if !self.scan_match.enabled() {
                return;
            }
            let (Some(mark_s), Some(held)) = (
                self.ekf.motion_tally().map(|t| t.since_s),
                self.ekf.held_odometry(),
            ) else {
                return;
            };
            if now_s <= mark_s && end_s > mark_s {
                self.apply_odometry(OdometrySample {
                    timestamp_s: end_s,
                    ..held
                });
                self.scan_match.note_still_clock();
            }
        } else if self.last_published_s.is_some_and(|last_s| now_s <= last_s) {
            while let Some(s) = self.gate.next_until(end_s) {
                self.apply_odometry(s);
            }
            if self.ekf.state().time_s() > now_s {
                self.summary.still_clock_caught_up += 1;
            }
        }
    }

    /// Counts, for every feature mapped before this rotation began and in the radar's view
    /// during it, whether it was associated again (the map's repeatability), and retires
    /// the features that are not repeatable (`[filter] retire_unrepeatable_below`).
    fn count_reobservations(&mut self) {
        let Some(start_s) = self.rotation_start_s.take() else {
            return;
        };
        let front_end = &self.front_end;
        match self
            .ekf
            .score_rotation(start_s, |bearing, range| front_end.covers(bearing, range))
        {
            Ok(score) => {
                self.summary.features_in_view += score.in_view;
                self.summary.features_reobserved += score.reobserved;
                self.summary.features_retired_unrepeatable += score.retired.len() as u64;
                self.stats.on_retired(score.retired.len());
            }
            Err(e) => warn!(error = %e, "scoring the map's repeatability failed"),
        }
    }

    /// Flushes everything still pending (end of stream), closes the last rotation, and
    /// returns the summary with the truth comparison.
    pub fn finish(&mut self, events: &mut Vec<OutputEvent>) -> PipelineSummary {
        self.front_end.flush(&mut self.beams);
        self.run_beams();
        self.end_rotation(events);
        let mut final_loops = None;
        let trajectory = self.submaps.as_mut().map(|s| {
            let (trajectory, map) = s.finish(&mut self.ekf);
            // The saved map keeps the near links among its loop edges (docs/map-format.md).
            final_loops = map
                .as_ref()
                .map(|m| m.loop_edges().cloned().collect::<Vec<_>>());
            if let Some(truth) = self.truth.as_ref() {
                s.score_against(&trajectory, map.as_ref(), |t| truth.pose_at(t));
            }
            trajectory
        });
        let map = self.map_snapshot();
        let map_size = map.features.len();
        events.push(OutputEvent::Map(map));
        if self.settings.map_save.enabled && self.nothing_to_save() {
            warn!("extend mode: not localised in the map long enough to map, so no map is saved (the map given is unchanged)");
        } else if self.settings.map_save.enabled {
            self.push_saved_map(final_loops.as_deref(), events);
        }
        if let Some(t) = trajectory {
            events.push(OutputEvent::Trajectory(t));
        }
        let mut s = self.summary.clone();
        s.map_size = map_size;
        s.submaps = self.submaps.as_ref().map(|x| x.summary().clone());
        s.spectrum_bound_db = self.front_end.spectrum_bound_db().map(|b| {
            b.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
                    (lo.min(x), hi.max(x))
                })
        });
        s.learned_gain_db_per_decade = self.front_end.learned_gain_slope();
        s.odometry_corrections = self.ekf.odometry_bias();
        s.scan_match = self.scan_match.enabled().then(|| self.scan_match.counts());
        s.gyro = self.gyro.as_ref().map(|q| {
            super::gyro::GyroSummary::new(q.counts(), &self.settings.motion, s.odometry_corrections)
        });
        if !self.online.is_empty() {
            let (est, tru): (Vec<PoseSample>, Vec<Pose2>) = self.online.iter().copied().unzip();
            s.online = Some(super::submaps::score_trajectory(&est, &tru));
        }
        if !self.odometry_track.is_empty() {
            let (est, tru): (Vec<PoseSample>, Vec<Pose2>) =
                self.odometry_track.iter().copied().unzip();
            s.odometry_track = Some(super::submaps::score_trajectory(&est, &tru));
        }
        s.odometry_out_of_order = self.gate.out_of_order();
        let localised = &self.online[..self.online_before_mapping.unwrap_or(self.online.len())];
        s.localise = self.localise.as_ref().map(|l| l.summary(localised));
        s.extend = self.extend.as_ref().map(|x| x.summary().clone());
        if let Some(truth) = self.truth.as_ref() {
            let features = match self.submaps.as_ref() {
                Some(sm) => sm.world_features(&self.ekf),
                None => self.ekf.features(),
            };
            truth.score(
                &features,
                self.ekf.state().loss_db(),
                self.settings.filter.initial_rho,
                self.settings.filter.initial_alpha,
                &mut s,
            );
        }
        s
    }
}

/// Whether observation `o`, placed from the pose predicted to its time, lies within
/// `radius_m` of a mapped feature.
fn near_a_feature(ekf: &DaemonEkf, o: &crate::detect::Observation, radius_m: f64) -> bool {
    let Some(pose) = ekf.pose_at(o.timestamp_s) else {
        return false;
    };
    let [x, y] = pose.point_at(o.range_m, o.bearing_rad);
    let state = ekf.state();
    (0..state.feature_count()).any(|slot| {
        state
            .params(slot)
            .is_some_and(|p| (p.x_m - x).hypot(p.y_m - y) <= radius_m)
    })
}

fn ms(a: Instant, b: Instant) -> f64 {
    b.duration_since(a).as_secs_f64() * 1e3
}

/// Whether the azimuth of index `index` in its rotation is one of every `every`-th.
fn spectrum_due(index: u16, every: usize) -> bool {
    every > 0 && usize::from(index) % every == 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use radar_model::geometry::range_bearing;
    use slam_filter::{BeamObservation, OdometrySample, Target};

    #[test]
    fn every_kth_azimuth_counts_azimuths_not_encoder_values() {
        // A CTS350-X: 5600 encoder counts, 400 azimuths (14 counts apart).
        let g = protocol::Geometry::cts350x();
        let checked = (0..400u16)
            .filter_map(|a| g.azimuth_index(a * 14))
            .filter(|&i| spectrum_due(i, 4))
            .count();
        assert_eq!(checked, 100, "every 4th of 400 azimuths");
    }

    #[test]
    fn the_map_written_carries_the_material_random_walk_of_features_not_seen_lately() {
        let settings = PipelineSettings::from_config(&config::Config::default()).unwrap();
        let mut p = Pipeline::new(settings, Some(0.0), None).unwrap();
        let still = |t: f64| OdometrySample {
            timestamp_s: t,
            speed_mps: 0.0,
            steer_rad: 0.0,
        };
        p.ekf.apply_odometry(still(0.0)).unwrap();
        // One post seen from a parked vehicle until it is confirmed into the map.
        let post = [20.0, 0.0];
        let rb = range_bearing(&p.ekf.pose(), post);
        for k in 1..=10 {
            let t = 0.4 * f64::from(k);
            p.ekf.apply_odometry(still(t)).unwrap();
            p.ekf
                .process_beam(&BeamObservation {
                    timestamp_s: t,
                    bearing_rad: rb.bearing_rad,
                    targets: vec![Target {
                        range_m: rb.range_m,
                        bearing_rad: rb.bearing_rad,
                        power_db: -40.0,
                    }],
                })
                .unwrap();
        }
        assert_eq!(p.ekf.feature_count(), 1, "the post is mapped");
        // A minute without seeing it.
        for t in 5..=60 {
            p.ekf.apply_odometry(still(f64::from(t))).unwrap();
        }
        let unsettled = MapSnapshot::from_state(p.ekf.state());
        let mut settled = p.ekf.clone();
        settled.settle_material_noise();
        let written = p.map_snapshot();
        assert_eq!(written, MapSnapshot::from_state(settled.state()));
        let var = |m: &MapSnapshot| m.features[0].covariance[2][2];
        assert!(
            var(&written) > 1.01 * var(&unsettled),
            "rho variance written {} against {} without the random walk",
            var(&written),
            var(&unsettled)
        );
    }
}
