//! One run of the filter over a simulated world: odometry and beams in time order, the
//! estimate compared with the truth after every rotation, association checked against
//! labels, and the per-rotation processing time (detection, grouping, filter) measured.

use std::collections::HashMap;
use std::time::Instant;

use nalgebra::Matrix3;
use radar_model::geometry::wrap_angle;
use radar_model::power::PowerModel;
use sim_sensor::scene::Scene;
use sim_sensor::OdometryNoise;
use slam_filter::{
    BeamObservation, BeamReport, Ekf, FeatureId, FilterSettings, FilterStats, RadarBeamModel,
};
use slam_node::pipeline::{PipelineSettings, PipelineSummary};

use crate::error::EvalError;
use crate::source::{AzimuthBeam, TargetSource};
use crate::world::World;

/// Where observations come from (see [`crate::source`]).
#[derive(Debug, Clone)]
pub enum Mode {
    /// Every feature in the beam, with the filter's noise model.
    Targets,
    /// The daemon's own pipeline with these settings (wire bytes in; see [`crate::daemon`]).
    Daemon(Box<PipelineSettings>),
}

/// A new feature is matched to the beam target it was initialised from when that target's
/// position lies within this of the feature's (m).
pub const IDENTITY_RADIUS_M: f64 = 2.0;

/// Everything that defines a run.
#[derive(Debug, Clone)]
pub struct RunSpec {
    /// The world.
    pub scene: Scene,
    /// Seed of every random draw.
    pub seed: u64,
    /// Simulated seconds (whole rotations).
    pub seconds: f64,
    /// Observation source.
    pub mode: Mode,
    /// The filter's settings.
    pub filter: FilterSettings,
    /// The filter's power model (its spreading form may differ from the world's).
    pub filter_power: PowerModel,
    /// Process every `azimuth_stride`-th azimuth only.
    pub azimuth_stride: usize,
    /// Merge the targets of this many processed azimuths into one update.
    pub beam_batch: usize,
    /// The odometry's noise (the filter's input noise is set to match by [`matched_filter`]).
    pub odometry: OdometryNoise,
    /// Initial pose standard deviations `[x m, y m, theta rad]` (the filter starts at the
    /// true pose; these only seed its covariance).
    pub initial_sigma: [f64; 3],
    /// Measure the covariance's health (with eigenvalues) every this many rotations.
    pub health_every_rotations: Option<usize>,
}

/// The filter's settings matched to a world: noise standard deviations from the simulator
/// and odometry, range limits from the radar. `targets_mode` uses the exact observation
/// noise; otherwise the detector's larger errors are allowed for as the daemon does.
pub fn matched_filter(
    world: &World,
    odometry: &OdometryNoise,
    targets_mode: bool,
) -> FilterSettings {
    let var = world.noise.observation_variances();
    let base = FilterSettings::default();
    FilterSettings {
        range_std_m: if targets_mode {
            var[0].sqrt()
        } else {
            base.range_std_m
        },
        bearing_std_rad: var[1].sqrt(),
        power_std_db: if targets_mode {
            var[2].sqrt()
        } else {
            base.power_std_db
        },
        speed_std_mps: odometry.sigma_speed_mps.max(1e-3),
        steer_std_rad: odometry.sigma_steer_rad.max(1e-4),
        input_noise_correlation_s: 1.0 / odometry.rate_hz,
        beam_half_width_rad: 0.5 * world.scene.radar.beam_width_rad,
        max_range_m: world.scene.radar.max_range_m(),
        ..base
    }
}

pub use crate::record::RotationRecord;

/// Association judged against the labels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AssociationCounts {
    /// Labelled targets offered to the filter.
    pub labelled_targets: u64,
    /// Unlabelled targets (clutter, or no feature near).
    pub unlabelled_targets: u64,
    /// Target paired with the feature that it came from.
    pub correct: u64,
    /// Labelled target paired with a feature that came from another true feature or from
    /// clutter.
    pub wrong: u64,
    /// Unlabelled target (clutter) paired with some feature.
    pub unlabelled_paired: u64,
    /// Features initialised from an unlabelled target (clutter).
    pub clutter_features: u64,
    /// Labelled target left unpaired although a feature of its own was a candidate.
    pub missed: u64,
    /// Features created for a true feature that already had one in the state.
    pub duplicates: u64,
}

/// A final feature against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureError {
    /// The true feature it was created from.
    pub truth_id: u32,
    /// Position error (m).
    pub position_m: f64,
    /// Estimated minus true rho.
    pub rho: f64,
    /// Estimated minus true alpha.
    pub alpha: f64,
}

/// Everything a run measured.
#[derive(Debug, Clone, Default)]
pub struct RunOutcome {
    /// One record per rotation.
    pub rotations: Vec<RotationRecord>,
    /// `(NIS, dof)` of every batched update.
    pub nis: Vec<(f64, usize)>,
    /// The filter's own totals.
    pub stats: FilterStats,
    /// Association against the labels.
    pub association: AssociationCounts,
    /// Final features that could be matched to a true feature.
    pub features: Vec<FeatureError>,
    /// Final features in the state.
    pub final_features: usize,
    /// Estimated radar loss L at the end (dB) and the truth.
    pub loss_db: (f64, f64),
    /// Beams the filter refused (with the first message).
    pub beam_errors: (u64, Option<String>),
    /// Beams processed.
    pub beams: u64,
    /// Azimuths processed.
    pub azimuths: u64,
    /// Wall time of the whole run including rendering (s).
    pub wall_s: f64,
    /// The daemon's own summary (daemon mode only).
    pub daemon: Option<PipelineSummary>,
}

/// Runs `spec` and measures it.
pub fn run(spec: &RunSpec) -> Result<RunOutcome, EvalError> {
    if spec.azimuth_stride == 0 || spec.beam_batch == 0 {
        return Err(EvalError::Setting(
            "strides and batch must be at least 1".into(),
        ));
    }
    let started = Instant::now();
    if let Mode::Daemon(settings) = &spec.mode {
        let mut settings = (**settings).clone();
        settings.filter = spec.filter.clone();
        let d = crate::daemon::run_daemon(
            &spec.scene,
            spec.seed,
            spec.seconds,
            settings,
            spec.odometry,
        )?;
        return Ok(RunOutcome {
            final_features: d.summary.map_size,
            beams: d.summary.beams,
            azimuths: d.summary.azimuths,
            beam_errors: (d.summary.filter_errors, None),
            loss_db: (d.loss_db, spec.scene.loss_db),
            rotations: d.rotations,
            wall_s: d.wall_s,
            daemon: Some(d.summary),
            ..RunOutcome::default()
        });
    }
    let world = World::new(spec.scene.clone(), spec.seed, spec.seconds, spec.odometry)?;
    let s = spec.initial_sigma;
    let p0 = Matrix3::from_diagonal(&nalgebra::Vector3::new(
        (s[0] * s[0]).max(1e-8),
        (s[1] * s[1]).max(1e-8),
        (s[2] * s[2]).max(1e-10),
    ));
    let mut ekf = Ekf::new(
        spec.filter.clone(),
        world.start_pose(),
        p0,
        world.azimuth_time_s(0),
        world.motion,
        RadarBeamModel {
            power: spec.filter_power,
        },
    )?;
    let total = world.azimuths_in(spec.seconds);
    let stride = spec.azimuth_stride as u64;
    let mut state = RunState::new(&world, stride);
    state.health_every = spec.health_every_rotations;
    match &spec.mode {
        Mode::Targets => {
            let mut source = TargetSource::new(&world, spec.seed);
            let mut index = 0;
            while index < total {
                let beam = source.beam(&world, index)?;
                let t = Instant::now();
                state.feed_odometry(&world, &mut ekf, beam.timestamp_s);
                state.offer(
                    &world,
                    &mut ekf,
                    beam,
                    spec.beam_batch,
                    t.elapsed().as_secs_f64(),
                );
                index += stride;
            }
        }
        Mode::Daemon(_) => {}
    }
    state.flush(&world, &mut ekf);
    let mut out = state.finish(&world, &ekf);
    out.azimuths = total.div_ceil(stride);
    out.wall_s = started.elapsed().as_secs_f64();
    Ok(out)
}

/// The run's book-keeping between beams.
struct RunState {
    next_odometry: u64,
    batch: Vec<AzimuthBeam>,
    batch_work_s: f64,
    pending_work_s: f64,
    rotation_work_s: f64,
    /// Which true feature each filter feature was created from (`None`: from clutter).
    identity: HashMap<FeatureId, Option<u32>>,
    /// How many live filter features each true feature has.
    owners: HashMap<u32, u32>,
    out: RunOutcome,
    azimuths: u64,
    stride: u64,
    health_every: Option<usize>,
}

impl RunState {
    fn new(world: &World, stride: u64) -> Self {
        Self {
            next_odometry: 0,
            batch: Vec::new(),
            batch_work_s: 0.0,
            pending_work_s: 0.0,
            rotation_work_s: 0.0,
            identity: HashMap::new(),
            owners: HashMap::new(),
            out: RunOutcome::default(),
            azimuths: world.azimuths(),
            stride: stride.max(1),
            health_every: None,
        }
    }

    fn feed_odometry<M, O>(&mut self, world: &World, ekf: &mut Ekf<M, O>, until_s: f64)
    where
        M: slam_filter::ProcessModel,
        O: slam_filter::BeamObservationModel,
    {
        while world.odometry_time_s(self.next_odometry) <= until_s {
            let sample = world.odometry(self.next_odometry);
            if let Err(e) = ekf.apply_odometry(sample) {
                self.note_error(&e.to_string());
            }
            self.next_odometry += 1;
        }
    }

    fn note_error(&mut self, message: &str) {
        self.out.beam_errors.0 += 1;
        if self.out.beam_errors.1.is_none() {
            self.out.beam_errors.1 = Some(message.to_string());
        }
    }

    fn offer(
        &mut self,
        world: &World,
        ekf: &mut Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
        beam: AzimuthBeam,
        batch: usize,
        work_s: f64,
    ) {
        let ends_rotation = self.ends_rotation(beam.index);
        self.batch_work_s += work_s;
        self.batch.push(beam);
        if self.batch.len() >= batch || ends_rotation {
            self.process_batch(world, ekf);
        }
    }

    /// True when the next processed azimuth after `index` falls in a new rotation.
    fn ends_rotation(&self, index: u64) -> bool {
        (index + self.stride) / self.azimuths != index / self.azimuths
    }

    fn process_batch(
        &mut self,
        world: &World,
        ekf: &mut Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
    ) {
        let Some(last) = self.batch.last().cloned() else {
            return;
        };
        // Merged beam: the last azimuth's time, the circular mean of the bearings.
        let (sin, cos) = self.batch.iter().fold((0.0, 0.0), |(s, c), b| {
            (s + b.bearing_rad.sin(), c + b.bearing_rad.cos())
        });
        let bearing = wrap_angle(sin.atan2(cos));
        let labelled: Vec<_> = self
            .batch
            .iter()
            .flat_map(|b| b.targets.iter().copied())
            .collect();
        let obs = BeamObservation {
            timestamp_s: last.timestamp_s,
            bearing_rad: bearing,
            targets: labelled.iter().map(|t| t.target).collect(),
        };
        let t = Instant::now();
        let result = ekf.process_beam(&obs);
        let filter_s = t.elapsed().as_secs_f64();
        self.rotation_work_s += self.batch_work_s + self.pending_work_s + filter_s;
        self.batch_work_s = 0.0;
        self.pending_work_s = 0.0;
        self.out.beams += 1;
        match result {
            Ok(report) => self.judge(ekf, &labelled, &report),
            Err(e) => self.note_error(&e.to_string()),
        }
        self.batch.clear();
        if self.ends_rotation(last.index) {
            self.record_rotation(world, ekf, &last);
        }
    }

    fn judge(
        &mut self,

        ekf: &Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
        targets: &[crate::source::LabelledTarget],
        report: &BeamReport,
    ) {
        if let Some(u) = report.update {
            self.out.nis.push((u.nis, u.dof));
        }
        for id in &report.retired {
            if let Some(Some(truth)) = self.identity.remove(id) {
                if let Some(n) = self.owners.get_mut(&truth) {
                    *n = n.saturating_sub(1);
                }
            }
        }
        for t in targets {
            if t.label.is_some() {
                self.out.association.labelled_targets += 1;
            } else {
                self.out.association.unlabelled_targets += 1;
            }
        }
        let mut paired = vec![false; targets.len()];
        for &(j, id) in &report.associated {
            let Some(t) = targets.get(j) else {
                continue;
            };
            if let Some(p) = paired.get_mut(j) {
                *p = true;
            }
            let owner = self.identity.get(&id).copied().flatten();
            match (t.label, owner) {
                (Some(l), Some(o)) if l == o => self.out.association.correct += 1,
                (Some(_), _) => self.out.association.wrong += 1,
                (None, _) => self.out.association.unlabelled_paired += 1,
            }
        }
        for (t, was_paired) in targets.iter().zip(&paired) {
            let Some(l) = t.label else {
                continue;
            };
            if !was_paired
                && report
                    .candidates
                    .iter()
                    .any(|c| self.identity.get(c).copied().flatten() == Some(l))
            {
                self.out.association.missed += 1;
            }
        }
        // New features: each was initialised from one of this beam's unclaimed targets, at
        // the position that target gives from the current pose; it takes that target's
        // label (None: made from clutter).
        let pose = ekf.pose();
        for id in &report.initialised {
            let Some(f) = ekf.feature(*id) else {
                continue;
            };
            let nearest = targets
                .iter()
                .map(|t| {
                    let p = pose.point_at(t.target.range_m, t.target.bearing_rad);
                    ((p[0] - f.x_m).hypot(p[1] - f.y_m), t.label)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .filter(|(d, _)| *d <= IDENTITY_RADIUS_M)
                .and_then(|(_, label)| label);
            match nearest {
                Some(n) => {
                    let owners = self.owners.entry(n).or_insert(0);
                    if *owners > 0 {
                        self.out.association.duplicates += 1;
                    }
                    *owners += 1;
                }
                None => self.out.association.clutter_features += 1,
            }
            self.identity.insert(*id, nearest);
        }
    }

    fn record_rotation(
        &mut self,
        world: &World,
        ekf: &Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
        last: &AzimuthBeam,
    ) {
        let estimate = ekf.pose();
        let p = ekf.pose_covariance();
        let health = self
            .health_every
            .filter(|k| *k > 0 && self.out.rotations.len().is_multiple_of(*k))
            .map(|_| ekf.covariance_health(true));
        self.out.rotations.push(RotationRecord {
            health,
            sigma: [
                p[(0, 0)].max(0.0).sqrt(),
                p[(1, 1)].max(0.0).sqrt(),
                p[(2, 2)].max(0.0).sqrt(),
            ],
            time_s: last.timestamp_s - world.azimuth_time_s(0),
            truth: last.truth,
            estimate,
            nees: ekf.pose_nees(&last.truth).ok(),
            features: ekf.feature_count(),
            work_s: self.rotation_work_s,
        });
        self.rotation_work_s = 0.0;
    }

    fn flush(
        &mut self,
        world: &World,
        ekf: &mut Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
    ) {
        if !self.batch.is_empty() {
            self.process_batch(world, ekf);
        }
    }

    fn finish(
        mut self,
        world: &World,
        ekf: &Ekf<radar_model::motion::MotionModel, RadarBeamModel>,
    ) -> RunOutcome {
        self.out.stats = *ekf.stats();
        self.out.final_features = ekf.feature_count();
        self.out.loss_db = (ekf.state().loss_db(), world.scene.loss_db);
        for f in ekf.features() {
            let Some(truth) = self
                .identity
                .get(&f.id)
                .copied()
                .flatten()
                .and_then(|id| world.feature(id))
            else {
                continue;
            };
            self.out.features.push(FeatureError {
                truth_id: truth.id,
                position_m: (f.x_m - truth.xy[0]).hypot(f.y_m - truth.xy[1]),
                rho: f.rho - truth.rho,
                alpha: f.alpha - truth.alpha,
            });
        }
        self.out
    }
}

/// Runs every spec on up to `jobs` threads; results in the order given.
pub fn run_many(specs: &[RunSpec], jobs: usize) -> Vec<Result<RunOutcome, EvalError>> {
    let jobs = jobs.clamp(1, specs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut slots: Vec<Option<Result<RunOutcome, EvalError>>> = Vec::new();
    slots.resize_with(specs.len(), || None);
    let results = std::sync::Mutex::new(slots);
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(spec) = specs.get(k) else {
                    break;
                };
                let r = run(spec);
                if let Ok(mut guard) = results.lock() {
                    if let Some(slot) = guard.get_mut(k) {
                        *slot = Some(r);
                    }
                }
            });
        }
    });
    results
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err(EvalError::Setting("a worker thread failed".into()))))
        .collect()
}
