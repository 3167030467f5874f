//! Time per rotation of the whole pipeline (detection on every spectrum, grouping,
//! association, batched updates, spectrum prediction) for the paper's 200-azimuth unit and
//! a CTS350-X-like unit, with 20, 100 and 500 features in view, on one thread; and the
//! real-time factor (stream seconds per processing second).
//!
//! The world: a scene built in code, point features uniform in a disk around a vehicle
//! driving a circle (3 m/s), so the map stays the size of the scene. Spectra are rendered
//! by the simulator's renderer (`sim_sensor::render`, untimed) and decoded from the 8-bit
//! frames it sends; only `Pipeline::process_azimuth` is timed.
//!
//! The CTS350-X-like unit runs twice: with the paper's TPP detector, and through the front
//! end for current units (the CTS350-X radar profile, `radar_model::profile::CTS350X`).
//!
//! Run: `cargo bench -p slam-node --bench pipeline_rotation` (one unit: add `-- current`).

#[path = "../tests/support/mod.rs"]
mod support;

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use radar_model::compensation::Compensation;
use radar_model::motion::MotionModel;
use radar_model::noise::seeded_rng;
use radar_model::power::RadarConstants;
use rand::Rng;
use sim_sensor::radar::RadarPreset;
use sim_sensor::scene::MotionSpec;
use sim_sensor::schedule::{ControlKey, ControlSchedule, Interpolation};
use slam_filter::OdometrySample;
use slam_node::pipeline::{Pipeline, PipelineSettings};
use support::SimRadar;

struct Unit {
    name: &'static str,
    preset: RadarPreset,
    /// The front end for current units (learned floor and gain, line-rate detection, only
    /// point-like returns mapped: what `--replay-dir` and `vehicle.toml` run) instead of the
    /// paper's TPP detector.
    current_front_end: bool,
}

/// 200 azimuths x 800 bins of 0.25 m, 2.5 Hz.
const PAPER: Unit = Unit {
    name: "paper-200",
    preset: RadarPreset::Paper200,
    current_front_end: false,
};
/// 400 azimuths x 3768 bins of 0.0438 m, 4 Hz.
const CTS: Unit = Unit {
    name: "cts350x-400",
    preset: RadarPreset::Cts350x400,
    current_front_end: false,
};
/// The same unit through the front end for current units.
const CTS_CURRENT: Unit = Unit {
    name: "cts350x-400, front end for current units",
    preset: RadarPreset::Cts350x400,
    current_front_end: true,
};

const SPEED_MPS: f64 = 3.0;
const STEER_RAD: f64 = 0.15;
const WHEELBASE_M: f64 = 2.7;
/// Unix time of the first azimuth, nanoseconds.
const T0_NS: u64 = 1_700_000_000_000_000_000;
/// Scene time the trajectory is integrated ahead for (azimuths past it still render).
const HORIZON_S: f64 = 3600.0;

struct Rig {
    radar: SimRadar,
    pipeline: Pipeline,
    next_odometry_s: f64,
    index: u64,
    events: Vec<slam_node::output::OutputEvent>,
}

impl Rig {
    fn new(unit: &Unit, features: usize) -> Self {
        let mut scene = support::empty_scene(unit.name, unit.preset, 17);
        scene.motion = MotionSpec::Bicycle {
            wheelbase_m: WHEELBASE_M,
        };
        scene.schedule = ControlSchedule::new(
            vec![ControlKey {
                t_s: 0.0,
                speed_mps: SPEED_MPS,
                steer_rad: STEER_RAD,
            }],
            Interpolation::Hold,
        )
        .unwrap();
        let mut rng = seeded_rng(17);
        let radius = scene.radar.max_range_m().min(150.0) * 0.6;
        for _ in 0..features {
            let r = radius * rng.gen::<f64>().sqrt().max(0.1);
            let a = rng.gen::<f64>() * std::f64::consts::TAU;
            let rho = rng.gen_range(0.02..0.6);
            let alpha = rng.gen_range(0.05..(0.95 - rho));
            support::add_point(&mut scene, r * a.cos(), r * a.sin(), rho, alpha);
        }
        let radar = SimRadar::new(&scene, None, HORIZON_S, T0_NS);
        let bin_m = radar.spectrum.geometry().bin_size_m;
        let mut config = config::Config::default();
        config.filter.max_features = config::values::Capacity::new(4096, 100_000).unwrap();
        let mut settings = PipelineSettings::from_config(&config).unwrap();
        settings.motion = MotionModel::Bicycle {
            wheelbase_m: WHEELBASE_M,
        };
        settings.compensation = Compensation::calibrated(
            scene.receiver.compensation_db_per_decade,
            &RadarConstants::default(),
        );
        settings.noise.range.resolution_fwhm_m = bin_m;
        settings.detector = slam_node::detect::DetectorSettings::default();
        settings.initial_pose = scene.start;
        settings.initial_pose_std = [0.0; 3];
        settings.map_every_rotations = 0;
        settings.spectrum_sample_every_rotations = 0;
        if unit.current_front_end {
            // The CTS350-X profile's front end and model over this configuration.
            let none = std::collections::BTreeSet::new();
            let facts = slam_node::pipeline::SourceFacts {
                motion: Some(settings.motion),
                compensation: Some(settings.compensation.clone()),
                peak_fwhm_m: Some(bin_m),
                initial_pose: Some((scene.start, [0.0; 3])),
                detector: Some(slam_node::detect::DetectorSettings::default()),
                no_radar_odometry: true,
                max_range_m: Some(scene.radar.max_range_m()),
                ..Default::default()
            };
            let choice = radar_model::profile::Choice {
                profile: &radar_model::profile::CTS350X,
                how: radar_model::profile::Chosen::Named,
            };
            settings = PipelineSettings::derive(
                &config,
                slam_node::pipeline::Written::Keys(&none),
                choice,
                &facts,
            )
            .unwrap()
            .settings;
            settings.map_every_rotations = 0;
            settings.spectrum_sample_every_rotations = 0;
        }
        let t0 = T0_NS as f64 * 1e-9;
        let pipeline = Pipeline::new(settings, Some(t0), None).unwrap();
        Self {
            radar,
            pipeline,
            next_odometry_s: t0,
            index: 0,
            events: Vec::new(),
        }
    }

    /// Renders and processes one rotation; returns the time spent processing it.
    fn rotation(&mut self) -> Duration {
        let mut busy = Duration::ZERO;
        for _ in 0..self.radar.azimuths() {
            let az = self.radar.azimuth(self.index);
            while self.next_odometry_s <= az.timestamp_s {
                self.pipeline.push_odometry(OdometrySample {
                    timestamp_s: self.next_odometry_s,
                    speed_mps: SPEED_MPS,
                    steer_rad: STEER_RAD,
                });
                self.next_odometry_s += 0.05;
            }
            let start = Instant::now();
            self.pipeline
                .process_azimuth(&az, &mut self.events)
                .unwrap();
            busy += start.elapsed();
            self.events.clear();
            self.index += 1;
        }
        busy
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("pipeline_rotation");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    group.warm_up_time(Duration::from_secs(1));
    let mut table = Vec::new();
    for unit in [&PAPER, &CTS, &CTS_CURRENT] {
        for features in [20usize, 100, 500] {
            let mut rig = Rig::new(unit, features);
            // Map the world first: a few rotations so the map holds what is in view.
            for _ in 0..8 {
                rig.rotation();
            }
            group.bench_function(format!("{}/{}_features", unit.name, features), |b| {
                b.iter_custom(|iters| (0..iters).map(|_| rig.rotation()).sum())
            });
            let s = rig.pipeline.summary();
            let n = s.rotations.max(1) as f64;
            table.push(format!(
                "{:<41} {:>5} features: map {:>4}, per rotation {:>7.2} ms (detection {:>6.2}, filter {:>6.2}, spectrum {:>5.2}), real-time factor {:>6.1}x",
                unit.name,
                features,
                rig.pipeline.ekf().feature_count(),
                s.mean_rotation_ms(),
                s.detect_ms / n,
                s.filter_ms / n,
                s.spectrum_ms / n,
                (1.0 / unit.preset.params().rotation_hz()) / (s.mean_rotation_ms() * 1e-3)
            ));
        }
    }
    group.finish();
    println!("\nper-stage means over every rotation processed (warm-up included):");
    for line in table {
        println!("{line}");
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
