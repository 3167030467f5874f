//! A stationary vehicle must not map duplicates of the features it keeps seeing.
//!
//! The radar reports a target at the azimuth of the beam it fell in: the true bearing plus
//! the bearing noise, quantised to the azimuth grid. Standing still, a feature sits at the
//! same place on that grid every rotation and its estimate (and the pose's heading) become
//! precise; its noisier sightings land one azimuth over, more than one beam half width plus
//! the association margin from the estimate. Such a target must still be tried against the
//! feature (the candidate arc is sized on the innovation's bearing sigma, measurement noise
//! included), not made a tentative that the next such sighting confirms as a new feature.

use nalgebra::Matrix3;
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use slam_filter::{BeamObservation, Ekf, FilterSettings, OdometrySample, RadarBeamModel, Target};

const T0: f64 = 1_700_000_000.0;
/// The paper's radar: 200 azimuths a rotation, beams 1.8 degrees wide, 2.5 Hz.
const AZIMUTHS: f64 = 200.0;
const ROTATION_S: f64 = 0.4;

#[test]
fn a_stationary_vehicle_seeing_features_one_azimuth_over_maps_no_duplicates() {
    let step = 2.0 * std::f64::consts::PI / AZIMUTHS;
    let bearing_std = 1.0_f64.to_radians();
    let s = FilterSettings {
        range_std_m: 0.25,
        bearing_std_rad: bearing_std,
        power_std_db: 2.4,
        beam_half_width_rad: 0.5 * step,
        ..FilterSettings::default()
    };
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = Ekf::new(
        s,
        truth,
        Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6)),
        T0,
        MotionModel::Bicycle { wheelbase_m: 2.7 },
        RadarBeamModel::default(),
    )
    .unwrap();
    f.apply_odometry(OdometrySample {
        timestamp_s: T0,
        speed_mps: 0.0,
        steer_rad: 0.0,
    })
    .unwrap();
    // Features at 30 m, each 0.3 of an azimuth step off its nearest azimuth's centre.
    let features: Vec<BeamFeature> = (0..6)
        .map(|i| {
            let beta = (f64::from(i) * 17.0 + 0.3) * step;
            let heading = truth.theta - beta; // beta is clockwise from forward
            BeamFeature {
                xy: [30.0 * heading.cos(), 30.0 * heading.sin()],
                material: Material::from_rho_alpha(0.5, 0.2).unwrap(),
            }
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for rotation in 0..150u32 {
        let t_rot = T0 + ROTATION_S * f64::from(rotation + 1);
        // Which azimuth each feature falls in this rotation (true bearing plus noise).
        let mut beams: Vec<(f64, &BeamFeature)> = features
            .iter()
            .map(|feat| {
                let n: f64 = StandardNormal.sample(&mut rng);
                let beta = range_bearing(&truth, feat.xy).bearing_rad + n * bearing_std;
                (wrap_angle((beta / step).round() * step), feat)
            })
            .collect();
        beams.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (k, (beam, feat)) in beams.into_iter().enumerate() {
            let z = observe_beam(
                &truth,
                std::slice::from_ref(feat),
                0.0,
                &PowerModel::default(),
            )
            .unwrap();
            let targets: Vec<Target> =
                z.z.iter()
                    .map(|z| Target {
                        range_m: z.range_m,
                        bearing_rad: beam,
                        power_db: z.power_db,
                    })
                    .collect();
            f.process_beam(&BeamObservation {
                timestamp_s: t_rot + 1e-3 * k as f64,
                bearing_rad: beam,
                targets,
            })
            .unwrap();
        }
    }
    assert_eq!(
        f.feature_count(),
        features.len(),
        "duplicates mapped while standing still"
    );
}
