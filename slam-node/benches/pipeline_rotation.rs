//! Time per rotation of the whole pipeline (detection on every spectrum, grouping,
//! association, batched updates, spectrum prediction) for the paper's 200-azimuth unit and
//! a CTS350-X-like unit, with 20, 100 and 500 features in view, on one thread; and the
//! real-time factor (stream seconds per processing second).
//!
//! The world: features uniform in a disk around a vehicle driving a circle (3 m/s), so the
//! map stays the size of the scene. Spectra are rendered through radar-model (untimed) and
//! quantised to 8 bits as on the wire; only `Pipeline::process_azimuth` is timed.
//!
//! Run: `cargo bench -p slam-node --bench pipeline_rotation`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::Bytes;
use criterion::{criterion_group, criterion_main, Criterion};
use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;
use radar_model::compensation::Compensation;
use radar_model::geometry::Pose2;
use radar_model::material::Material;
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::noise::{seeded_rng, NoiseModel};
use radar_model::power::{PowerModel, RadarConstants};
use radar_model::spectrum::{quantize_8bit, SpectrumGeometry, SpectrumModel};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use slam_filter::OdometrySample;
use slam_node::pipeline::{Pipeline, PipelineSettings};
use slam_node::synth::{SynthFeature, SynthRadar, TrueTarget};

struct Unit {
    name: &'static str,
    azimuths: u16,
    bins: u16,
    bin_m: f64,
    rotation_hz: f64,
}

const PAPER: Unit = Unit {
    name: "paper-200",
    azimuths: 200,
    bins: 800,
    bin_m: 0.25,
    rotation_hz: 2.5,
};
const CTS: Unit = Unit {
    name: "cts350x-400",
    azimuths: 400,
    bins: 3768,
    bin_m: 0.0438,
    rotation_hz: 4.0,
};

const SPEED_MPS: f64 = 3.0;
const STEER_RAD: f64 = 0.15;

struct Rig {
    radar: SynthRadar,
    world: Vec<SynthFeature>,
    pipeline: Pipeline,
    geometry: Arc<Geometry>,
    motion: MotionModel,
    pose: Pose2,
    t_s: f64,
    next_odometry_s: f64,
    index: u64,
    rng: ChaCha8Rng,
    measured: Vec<f64>,
    truth: Vec<TrueTarget>,
    events: Vec<slam_node::output::OutputEvent>,
}

impl Rig {
    fn new(unit: &Unit, features: usize) -> Self {
        let constants = RadarConstants::default();
        let compensation = Compensation::calibrated(40.0, &constants);
        let sg = SpectrumGeometry {
            bins: usize::from(unit.bins),
            bin_size_m: unit.bin_m,
            range_offset_m: 0.0,
        };
        // As the simulator renders: a peak's width (FWHM) is one bin.
        let mut noise = NoiseModel::default();
        noise.range.resolution_fwhm_m = unit.bin_m;
        let spectrum = SpectrumModel::new(sg, &compensation, noise).unwrap();
        let radar = SynthRadar::new(
            usize::from(unit.azimuths),
            1.8f64.to_radians(),
            0.0,
            PowerModel::default(),
            spectrum,
        );
        let mut rng = seeded_rng(17);
        let radius = (f64::from(unit.bins) * unit.bin_m).min(150.0) * 0.6;
        let world = (0..features)
            .map(|_| {
                let r = radius * rng.gen::<f64>().sqrt().max(0.1);
                let a = rng.gen::<f64>() * std::f64::consts::TAU;
                let rho = rng.gen_range(0.02..0.6);
                let alpha = rng.gen_range(0.05..(0.95 - rho));
                SynthFeature {
                    x_m: r * a.cos(),
                    y_m: r * a.sin(),
                    material: Material::from_rho_alpha(rho, alpha).unwrap(),
                }
            })
            .collect();
        let mut config = config::Config::default();
        config.filter.max_features = config::values::Capacity::new(4096, 100_000).unwrap();
        let mut settings = PipelineSettings::from_config(&config).unwrap();
        settings.motion = MotionModel::Bicycle { wheelbase_m: 2.7 };
        settings.compensation = compensation;
        settings.noise.range.resolution_fwhm_m = unit.bin_m;
        settings.detector = slam_node::detect::DetectorSettings::default();
        settings.initial_pose = [0.0, 0.0, 0.0];
        settings.initial_pose_std = [0.0; 3];
        settings.map_every_rotations = 0;
        settings.spectrum_sample_every_rotations = 0;
        let t0 = 1.7e9;
        let pipeline = Pipeline::new(settings, Some(t0), None).unwrap();
        let geometry = Arc::new(Geometry {
            azimuth_samples: unit.azimuths,
            range_in_bins: unit.bins,
            bin_size_m: unit.bin_m,
            encoder_size: 5600,
            rotation_hz: unit.rotation_hz,
            packet_rate: (f64::from(unit.azimuths) * unit.rotation_hz) as u16,
            range_gain: 1.0,
            range_offset_m: 0.0,
            data_width: BinWidth::Eight,
            range_resolution_m: Some(unit.bin_m),
        });
        Self {
            radar,
            world,
            pipeline,
            geometry,
            motion: MotionModel::Bicycle { wheelbase_m: 2.7 },
            pose: Pose2::new(0.0, 0.0, 0.0),
            t_s: t0,
            next_odometry_s: t0,
            index: 0,
            rng,
            measured: Vec::new(),
            truth: Vec::new(),
            events: Vec::new(),
        }
    }

    /// Renders and processes one rotation; returns the time spent processing it.
    fn rotation(&mut self) -> Duration {
        let n = u64::from(self.geometry.azimuth_samples);
        let dt = 1.0 / (f64::from(self.geometry.azimuth_samples) * self.geometry.rotation_hz);
        let mut busy = Duration::ZERO;
        for _ in 0..n {
            let i = self.index % n;
            while self.next_odometry_s <= self.t_s {
                self.pipeline.push_odometry(OdometrySample {
                    timestamp_s: self.next_odometry_s,
                    speed_mps: SPEED_MPS,
                    steer_rad: STEER_RAD,
                });
                self.next_odometry_s += 0.05;
            }
            let encoder = u16::try_from(i * 5600 / n).unwrap();
            let bearing = f64::from(encoder) * std::f64::consts::TAU / 5600.0;
            self.radar
                .render(
                    &self.pose,
                    radar_model::geometry::wrap_angle(bearing),
                    &self.world,
                    &mut self.rng,
                    &mut self.measured,
                    &mut self.truth,
                )
                .unwrap();
            let bins: Vec<u8> = self.measured.iter().map(|&p| quantize_8bit(p)).collect();
            let az = Azimuth {
                encoder,
                angle_rad: bearing,
                timestamp_s: self.t_s,
                sweep_counter: (self.index % 65536) as u16,
                width: BinWidth::Eight,
                bins: Bytes::from(bins),
                geometry: Arc::clone(&self.geometry),
            };
            let start = Instant::now();
            self.pipeline
                .process_azimuth(&az, &mut self.events)
                .unwrap();
            busy += start.elapsed();
            self.events.clear();
            self.pose = self
                .motion
                .predict(&self.pose, &ControlInput::new(SPEED_MPS, STEER_RAD), dt)
                .unwrap();
            self.t_s += dt;
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
    for unit in [&PAPER, &CTS] {
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
                "{:<12} {:>5} features: map {:>4}, per rotation {:>7.2} ms (detection {:>6.2}, filter {:>6.2}, spectrum {:>5.2}), real-time factor {:>6.1}x",
                unit.name,
                features,
                rig.pipeline.ekf().feature_count(),
                s.mean_rotation_ms(),
                s.detect_ms / n,
                s.filter_ms / n,
                s.spectrum_ms / n,
                (1.0 / unit.rotation_hz) / (s.mean_rotation_ms() * 1e-3)
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
