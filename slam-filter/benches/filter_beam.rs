//! The whole per-beam work of the filter (`Ekf::process_beam`: predict to the azimuth's
//! time, find the beam's candidates, predict, associate, update) against the number of
//! features in the state, for an empty beam and for a beam with one mapped target.
//!
//! `cargo bench -p slam-filter --bench filter_beam`. A rotation is 200 such beams (the paper's
//! radar); most are empty, and a beam with a target costs one batched update.

use std::f64::consts::PI;

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use nalgebra::Matrix3;
use radar_model::geometry::{range_bearing, Pose2};
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use slam_filter::{BeamObservation, Ekf, FilterSettings, OdometrySample, RadarBeamModel, Target};

type Filter = Ekf<MotionModel, RadarBeamModel>;

const T0: f64 = 1_700_000_000.0;

/// A filter holding `features` features on a spiral around the vehicle, one per beam bearing.
fn filter_with(features: usize) -> (Filter, Vec<BeamFeature>) {
    let settings = FilterSettings {
        max_features: features + 10,
        ..FilterSettings::default()
    };
    let p0 = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-2, 1e-2, 1e-4));
    let mut f = Ekf::new(
        settings,
        Pose2::default(),
        p0,
        T0,
        MotionModel::Bicycle { wheelbase_m: 2.5 },
        RadarBeamModel::default(),
    )
    .expect("valid settings");
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 0.0,
        steer_rad: 0.0,
    })
    .expect("finite odometry");
    let material = Material::from_rho_alpha(0.3, 0.2).expect("valid shares");
    let truth = Pose2::default();
    let mut scene = Vec::with_capacity(features);
    for k in 0..features {
        // Spread bearings over several turns so beams hold about features / 200 each.
        let a = (k as f64 * 2.0 * PI * 0.618_034).rem_euclid(2.0 * PI);
        let r = 10.0 + 150.0 * (k as f64 / features as f64);
        let feat = BeamFeature {
            xy: [r * a.cos(), r * a.sin()],
            material,
        };
        let z = observe_beam(&truth, &[feat], 0.0, &PowerModel::default()).expect("observable");
        let rb = range_bearing(&truth, feat.xy);
        let t = Target {
            range_m: z.z[0].range_m,
            bearing_rad: z.z[0].bearing_rad,
            power_db: z.z[0].power_db,
        };
        f.initialise_feature(&t, rb.bearing_rad, T0)
            .expect("feature initialised");
        scene.push(feat);
    }
    (f, scene)
}

fn bench_beam(c: &mut Criterion) {
    let mut group = c.benchmark_group("process_beam");
    group.sample_size(10);
    for &features in &[20usize, 100, 500] {
        let (base, scene) = filter_with(features);
        let truth = Pose2::default();
        let first = scene[0];
        let rb = range_bearing(&truth, first.xy);
        let z = observe_beam(&truth, &[first], 0.0, &PowerModel::default()).expect("observable");
        let with_target = BeamObservation {
            timestamp_s: T0 + 0.01,
            bearing_rad: rb.bearing_rad,
            targets: vec![Target {
                range_m: z.z[0].range_m,
                bearing_rad: z.z[0].bearing_rad,
                power_db: z.z[0].power_db,
            }],
        };
        let empty = BeamObservation {
            timestamp_s: T0 + 0.01,
            bearing_rad: rb.bearing_rad + PI,
            targets: Vec::new(),
        };
        for (name, beam) in [("empty", &empty), ("one_target", &with_target)] {
            group.bench_with_input(
                BenchmarkId::new(name, format!("N{features}")),
                beam,
                |b, beam| {
                    b.iter_batched(
                        || base.clone(),
                        |mut f| {
                            f.process_beam(beam).expect("beam processed");
                            f // dropped outside the timed region
                        },
                        BatchSize::LargeInput,
                    )
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench_beam);
criterion_main!(benches);
