//! Builds a filter, feeds it odometry and beams, and reads the estimate.
//!
//! A vehicle drives at 5 m/s past a row of posts; every 0.4 s rotation of a 200-azimuth
//! radar gives one beam per azimuth with the targets the radar saw down it (here made from
//! the true geometry with radar-model's eq. 13 power, no noise). In your software the beams
//! come from your detector and the odometry from the vehicle.
//!
//! `cargo run --release -p slam-filter --example drive_past_posts`

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use slam_filter::{
    BeamObservation, Ekf, FilterSettings, OdometrySample, ProcessModel, RadarBeamModel, Target,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    const AZIMUTHS: usize = 200;
    const ROTATION_S: f64 = 0.4;
    let step_rad = std::f64::consts::TAU / AZIMUTHS as f64;

    // The filter: settings for the radar (noise, beam width), the initial pose and its
    // covariance, the start time, the vehicle's process model and the beam model.
    let settings = FilterSettings {
        range_std_m: 0.1,
        bearing_std_rad: 1.0_f64.to_radians(),
        power_std_db: 1.0,
        beam_half_width_rad: 0.5 * step_rad,
        ..FilterSettings::default()
    };
    let motion = MotionModel::Bicycle { wheelbase_m: 2.7 };
    let t0 = 0.0;
    let mut filter = Ekf::new(
        settings,
        Pose2::new(0.0, 0.0, 0.0),
        Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1e-6)),
        t0,
        motion,
        RadarBeamModel::default(),
    )?;

    // The world (only to make beams here): posts 6 m to the left of the road.
    let post = Material::from_rho_alpha(0.7, 0.1)?;
    let posts: Vec<BeamFeature> = (0..8)
        .map(|i| BeamFeature {
            xy: [5.0 + 5.0 * f64::from(i), 6.0],
            material: post,
        })
        .collect();

    let (speed_mps, steer_rad) = (5.0, 0.0);
    let mut truth = Pose2::new(0.0, 0.0, 0.0);
    let dt = ROTATION_S / AZIMUTHS as f64;
    let mut t = t0;
    filter.apply_odometry(OdometrySample {
        timestamp_s: t,
        speed_mps,
        steer_rad,
    })?;
    for rotation in 0..20 {
        for azimuth in 0..AZIMUTHS {
            t += dt;
            truth = motion.step(&truth, speed_mps, steer_rad, dt)?.pose;
            // Odometry whenever it arrives (here every azimuth).
            filter.apply_odometry(OdometrySample {
                timestamp_s: t,
                speed_mps,
                steer_rad,
            })?;
            // Every target down this beam, nearest first or in any order.
            let bearing_rad = wrap_angle(azimuth as f64 * step_rad);
            let in_beam: Vec<BeamFeature> = posts
                .iter()
                .filter(|p| {
                    wrap_angle(range_bearing(&truth, p.xy).bearing_rad - bearing_rad).abs()
                        <= 0.5 * step_rad
                })
                .copied()
                .collect();
            let targets = if in_beam.is_empty() {
                Vec::new()
            } else {
                observe_beam(&truth, &in_beam, 0.0, &PowerModel::default())?
                    .z
                    .iter()
                    .map(|z| Target {
                        range_m: z.range_m,
                        bearing_rad,
                        power_db: z.power_db,
                    })
                    .collect()
            };
            let report = filter.process_beam(&BeamObservation {
                timestamp_s: t,
                bearing_rad,
                targets,
            })?;
            for id in &report.initialised {
                println!("rotation {rotation:2}: new feature {id:?}");
            }
        }
    }

    // The estimate: pose with covariance, and every feature with its material.
    filter.settle_material_noise();
    let pose = filter.pose();
    let sigma = filter.pose_covariance().diagonal().map(f64::sqrt);
    println!(
        "pose ({:.3}, {:.3}, {:.2} deg) +- ({:.3} m, {:.3} m, {:.2} deg); truth ({:.3}, {:.3})",
        pose.x,
        pose.y,
        pose.theta.to_degrees(),
        sigma[0],
        sigma[1],
        sigma[2].to_degrees(),
        truth.x,
        truth.y
    );
    // Received power fixes only 10 log10(rho) - L: rho and the radar loss L trade against
    // each other until something (a calibrated target, or a feature behind another) pins one.
    println!("radar loss L {:.2} dB", filter.state().loss_db());
    for f in filter.features() {
        println!(
            "feature {:?}: ({:.2}, {:.2}) m, rho {:.2}, alpha {:.2}, seen {} times",
            f.id, f.x_m, f.y_m, f.rho, f.alpha, f.hits
        );
    }
    Ok(())
}
