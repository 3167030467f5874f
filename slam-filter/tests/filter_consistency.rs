//! Consistency against known truth: a vehicle circling among landmarks, a rotating radar
//! (200 azimuths per 0.25 s rotation) observing every landmark inside the current beam with
//! radar-model's multi-target physics and noise, noisy odometry at 20 Hz; the whole filter
//! (prediction to each azimuth's timestamp, association, life cycle, batched updates).
//!
//! The pose NEES averaged over Monte Carlo runs must lie in the chi-square band. The full
//! 50-run figure is an ignored test, run in release:
//! `cargo test --release -p slam-filter --test filter_consistency -- --ignored --nocapture`.

use std::f64::consts::PI;

use nalgebra::Matrix3;
use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::noise::NoiseModel;
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use slam_filter::{BeamObservation, Ekf, FilterSettings, OdometrySample, RadarBeamModel, Target};
use statrs::distribution::{ChiSquared, ContinuousCDF};

const AZIMUTHS: usize = 200;
const ROTATION_S: f64 = 0.25;
const ODO_PERIOD_S: f64 = 0.05;
const WHEELBASE_M: f64 = 2.5;
const TRUE_LOSS_DB: f64 = 3.0;

struct Landmark {
    xy: [f64; 2],
    material: Material,
}

fn scene(rng: &mut ChaCha8Rng) -> Vec<Landmark> {
    let mut out: Vec<Landmark> = Vec::new();
    while out.len() < 14 {
        let r = rng.gen_range(8.0..35.0);
        let a = rng.gen_range(-PI..PI);
        let xy = [r * a.cos(), 15.0 + r * a.sin()];
        if out
            .iter()
            .any(|l| (l.xy[0] - xy[0]).hypot(l.xy[1] - xy[1]) < 6.0)
        {
            continue;
        }
        let rho = rng.gen_range(0.05..0.6);
        let alpha = rng.gen_range(0.05..0.3);
        let material = Material::from_rho_alpha(rho, alpha).unwrap();
        out.push(Landmark { xy, material });
    }
    out
}

/// The filter's settings matched to the simulation's noise.
fn settings(noise: &NoiseModel, use_power: bool) -> FilterSettings {
    let var = noise.observation_variances();
    FilterSettings {
        use_power,
        // FILTER_MC_FEJ=0 turns first-estimates Jacobians off, for the comparison.
        first_estimate_jacobians: std::env::var("FILTER_MC_FEJ").map_or(true, |v| v != "0"),
        range_std_m: var[0].sqrt(),
        bearing_std_rad: var[1].sqrt(),
        power_std_db: var[2].sqrt(),
        speed_std_mps: 0.05,
        steer_std_rad: env_f64("FILTER_MC_STEER_STD_DEG", 0.5).to_radians(),
        input_noise_correlation_s: ODO_PERIOD_S,
        material_variance_per_s: 0.0,
        max_predict_step_s: 0.05,
        beam_half_width_rad: 0.9_f64.to_radians(),
        association_margin_rad: 1.0_f64.to_radians(),
        max_range_m: 60.0,
        initial_loss_db: 0.0,
        initial_loss_std_db: 10.0,
        ..FilterSettings::default()
    }
}

/// A positive number from the environment, or `default`.
fn env_f64(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|v| v.is_finite() && *v > 0.0)
        .unwrap_or(default)
}

struct RunResult {
    /// Pose NEES at the end of each rotation.
    nees: Vec<f64>,
    features: usize,
    mean_nis_per_dof: f64,
    /// Position NEES of every feature at the end, against its nearest landmark.
    feature_nees: Vec<f64>,
    /// Heading standard deviation and heading error at the end (rad).
    final_heading: (f64, f64),
}

fn run(seed: u64, seconds: f64, use_power: bool) -> RunResult {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let landmarks = scene(&mut rng);
    let noise = NoiseModel::default();
    let power = PowerModel::default();
    let motion = MotionModel::Bicycle {
        wheelbase_m: WHEELBASE_M,
    };
    let s = settings(&noise, use_power);
    let t0 = 1_700_000_000.0;
    // The true vehicle starts at the origin heading +x and circles at radius 15 m.
    let mut truth = Pose2::new(0.0, 0.0, 0.0);
    let true_input = ControlInput::new(2.0, (WHEELBASE_M / 15.0).atan());
    // Initial heading standard deviation (default 1 mrad); FILTER_MC_HEADING0_STD_DEG raises it.
    let theta0_std = env_f64("FILTER_MC_HEADING0_STD_DEG", 1e-3_f64.to_degrees()).to_radians();
    let p0 = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, theta0_std.powi(2)));
    let n0: [f64; 3] = [
        StandardNormal.sample(&mut rng),
        StandardNormal.sample(&mut rng),
        StandardNormal.sample(&mut rng),
    ];
    let start = Pose2::new(n0[0] * 1e-2, n0[1] * 1e-2, n0[2] * theta0_std);
    let mut ekf = Ekf::new(s.clone(), start, p0, t0, motion, RadarBeamModel { power }).unwrap();
    let dt = ROTATION_S / AZIMUTHS as f64;
    let steps = (seconds / dt).round() as usize;
    let odo_every = (ODO_PERIOD_S / dt).round() as usize;
    let mut nees = Vec::new();
    for k in 0..steps {
        let t = t0 + k as f64 * dt;
        if k % odo_every == 0 {
            let sv: f64 = StandardNormal.sample(&mut rng);
            let ss: f64 = StandardNormal.sample(&mut rng);
            ekf.apply_odometry(OdometrySample {
                timestamp_s: t,
                speed_mps: true_input.speed_mps + s.speed_std_mps * sv,
                steer_rad: true_input.steer_rad + s.steer_std_rad * ss,
            })
            .unwrap();
        }
        // The beam at this azimuth: bearing increases clockwise with the encoder.
        let beam_bearing = wrap_angle((k % AZIMUTHS) as f64 * 2.0 * PI / AZIMUTHS as f64);
        let mut inside: Vec<(f64, &Landmark)> = landmarks
            .iter()
            .filter_map(|l| {
                let rb = range_bearing(&truth, l.xy);
                let inside = wrap_angle(rb.bearing_rad - beam_bearing).abs()
                    <= 0.9_f64.to_radians()
                    && rb.range_m <= 60.0;
                inside.then_some((rb.range_m, l))
            })
            .collect();
        inside.sort_by(|a, b| a.0.total_cmp(&b.0));
        let feats: Vec<BeamFeature> = inside
            .iter()
            .map(|(_, l)| BeamFeature {
                xy: l.xy,
                material: l.material,
            })
            .collect();
        let mut targets = Vec::new();
        if !feats.is_empty() {
            let obs = observe_beam(&truth, &feats, TRUE_LOSS_DB, &power).unwrap();
            for z in &obs.z {
                let zn = noise.perturb_observation(z.as_array(), &mut rng);
                targets.push(Target {
                    range_m: zn[0],
                    bearing_rad: zn[1],
                    power_db: zn[2],
                });
            }
        }
        ekf.process_beam(&BeamObservation {
            timestamp_s: t,
            bearing_rad: beam_bearing,
            targets,
        })
        .unwrap();
        if (k + 1) % AZIMUTHS == 0 {
            // Empty beams do not advance the state (defer_empty_beams): bring it to now.
            ekf.predict_to(t).unwrap();
            nees.push(ekf.pose_nees(&truth).unwrap());
        }
        truth = motion.predict(&truth, &true_input, dt).unwrap();
    }
    let st = ekf.stats();
    let feature_nees = ekf
        .features()
        .iter()
        .filter_map(|f| {
            let nearest = landmarks.iter().min_by(|a, b| {
                let da = (a.xy[0] - f.x_m).hypot(a.xy[1] - f.y_m);
                let db = (b.xy[0] - f.x_m).hypot(b.xy[1] - f.y_m);
                da.total_cmp(&db)
            })?;
            ekf.feature_nees(f.id, nearest.xy).ok()
        })
        .collect();
    let final_heading = (
        ekf.pose_covariance()[(2, 2)].sqrt(),
        wrap_angle(ekf.pose().theta - truth.theta),
    );
    RunResult {
        final_heading,
        nees,
        features: ekf.feature_count(),
        mean_nis_per_dof: st.nis_sum / st.nis_dof_sum.max(1) as f64,
        feature_nees,
    }
}

fn band(runs: usize, dof: usize) -> (f64, f64) {
    let d = ChiSquared::new((runs * dof) as f64).unwrap();
    (
        d.inverse_cdf(0.025) / runs as f64,
        d.inverse_cdf(0.975) / runs as f64,
    )
}

fn summarise(runs: usize, seconds: f64, use_power: bool) -> (f64, f64, (f64, f64)) {
    let results: Vec<RunResult> = (0..runs as u64)
        .map(|s| run(1000 + s, seconds, use_power))
        .collect();
    let len = results.iter().map(|r| r.nees.len()).min().unwrap_or(0);
    let (lo, hi) = band(runs, 3);
    let mut inside = 0usize;
    let mut total = 0.0;
    for i in 0..len {
        let avg = results.iter().map(|r| r.nees[i]).sum::<f64>() / runs as f64;
        total += avg;
        if avg >= lo && avg <= hi {
            inside += 1;
        }
        if i % 20 == 0 || i + 1 == len {
            println!("rotation {i:4}: average pose NEES {avg:.3}");
        }
    }
    let mean = total / len as f64;
    let frac = inside as f64 / len as f64;
    let nis = results.iter().map(|r| r.mean_nis_per_dof).sum::<f64>() / runs as f64;
    let feats = results.iter().map(|r| r.features).sum::<usize>() as f64 / runs as f64;
    // Feature NEES of every mapped feature at the end of each run (2 dof), averaged over
    // features and runs; the band printed is the docs' one for a 50-sample average.
    let all: Vec<f64> = results
        .iter()
        .flat_map(|r| r.feature_nees.iter().copied())
        .collect();
    let feature_mean = all.iter().sum::<f64>() / all.len().max(1) as f64;
    let sigma = results.iter().map(|r| r.final_heading.0).sum::<f64>() / runs as f64;
    let rms = (results
        .iter()
        .map(|r| r.final_heading.1.powi(2))
        .sum::<f64>()
        / runs as f64)
        .sqrt();
    println!(
        "final heading: filter sigma {:.3} deg (mean), actual RMS error {:.3} deg",
        sigma.to_degrees(),
        rms.to_degrees()
    );
    let (flo, fhi) = band(runs, 2);
    println!(
        "feature position NEES (2 dof), mean over {} features x runs: {feature_mean:.3}; \
         {runs}-run band [{flo:.2}, {fhi:.2}]",
        all.len()
    );
    println!(
        "{runs} runs x {seconds} s (power {use_power}): time-averaged pose NEES {mean:.3}, \
         band [{lo:.2}, {hi:.2}], {:.1}% of rotations inside, mean NIS/dof {nis:.3}, features {feats:.1}",
        100.0 * frac
    );
    (mean, frac, (lo, hi))
}

#[test]
fn a_short_monte_carlo_run_is_not_overconfident_and_maps_every_landmark() {
    // Debug-mode budget: 4 runs of 12 s. The band for 4 runs is wide; the full figure is below.
    let runs = 4;
    let (mean, _, (_, hi4)) = summarise(runs, 12.0, true);
    assert!(
        mean < hi4 * 1.5,
        "pose NEES {mean} far above the {runs}-run band"
    );
    let r = run(7, 12.0, true);
    assert!(
        r.features >= 10 && r.features <= 16,
        "features {}",
        r.features
    );
}

#[test]
#[ignore = "50 Monte Carlo runs: run in release (see the module docs)"]
fn fifty_monte_carlo_runs_give_a_pose_nees_inside_the_95_percent_band() {
    // FILTER_MC_SECONDS lengthens the runs (default 60 s), FILTER_MC_STEER_STD_DEG raises
    // the steering noise (default 0.5 degrees) and FILTER_MC_HEADING0_STD_DEG the initial
    // heading uncertainty (default 0.057 degrees), to look for the drift to optimism that
    // EKF-SLAM shows with large heading uncertainty.
    let seconds = env_f64("FILTER_MC_SECONDS", 60.0);
    let (mean, frac, (lo, hi)) = summarise(50, seconds, true);
    let (mean_rb, frac_rb, _) = summarise(50, seconds, false);
    println!(
        "range-bearing only: mean {mean_rb:.3}, inside {:.1}%",
        100.0 * frac_rb
    );
    assert!(
        mean >= lo && mean <= hi,
        "mean NEES {mean} outside [{lo}, {hi}]"
    );
    assert!(
        frac >= 0.8,
        "only {:.1}% of rotations inside the band",
        100.0 * frac
    );
}

#[test]
fn the_chi_square_band_for_fifty_runs_is_the_documented_one() {
    let (lo, hi) = band(50, 3);
    assert!(
        (lo - 2.36).abs() < 0.01 && (hi - 3.72).abs() < 0.01,
        "{lo} {hi}"
    );
}
