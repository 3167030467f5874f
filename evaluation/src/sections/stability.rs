//! Numerical stability at scale: a million filter steps (a predict to every azimuth's time,
//! an update wherever a feature is in the beam) with the covariance's health measured
//! throughout; and named hard cases: targets at equal range down one beam, `rho + alpha`
//! near 1, variances spanning 1e-12 to 1e6 in one covariance.

use std::fmt::Write as _;

use nalgebra::{DMatrix, DVector, Matrix3};
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::motion::MotionModel;
use radar_model::noise::{seeded_rng, NoiseModel};
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::power::PowerModel;
use rand::Rng;
use sim_sensor::scene::shipped;
use sim_sensor::schedule::{ControlKey, ControlSchedule, Interpolation};
use slam_filter::state::{feature_index, FEATURE_BASE, FEATURE_DIM, LOSS_INDEX};
use slam_filter::{
    batched_update, BeamObservation, CovarianceHealth, Ekf, FilterSettings, LinearisedObservation,
    OdometrySample, RadarBeamModel, SlamState, Target,
};

use crate::error::EvalError;
use crate::metrics::{mean, rms};
use crate::plot::{line_chart, Labels, Series};
use crate::report::{num, table, Options, Section};
use crate::run::{run, Mode};
use crate::sections::shipped_spec;

/// Running extremes of the health figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HealthExtremes {
    /// Measurements taken.
    pub samples: usize,
    /// Smallest correlation-matrix eigenvalue seen.
    pub min_corr_eig: f64,
    /// Smallest eigenvalue of P seen.
    pub min_eig: f64,
    /// Largest symmetry error seen.
    pub max_symmetry: f64,
    /// Every Cholesky succeeded.
    pub cholesky_always: bool,
    /// Every element always finite.
    pub finite_always: bool,
    /// Smallest and largest variance seen.
    pub variance_range: (f64, f64),
}

impl Default for HealthExtremes {
    fn default() -> Self {
        Self {
            samples: 0,
            min_corr_eig: f64::INFINITY,
            min_eig: f64::INFINITY,
            max_symmetry: 0.0,
            cholesky_always: true,
            finite_always: true,
            variance_range: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl HealthExtremes {
    /// Folds one measurement in.
    pub fn add(&mut self, h: &CovarianceHealth) {
        self.samples += 1;
        if let Some(e) = h.min_correlation_eigenvalue {
            self.min_corr_eig = self.min_corr_eig.min(e);
        }
        if let Some(e) = h.min_eigenvalue {
            self.min_eig = self.min_eig.min(e);
        }
        self.max_symmetry = self.max_symmetry.max(h.max_symmetry_error);
        self.cholesky_always &= h.cholesky_ok;
        self.finite_always &= h.all_finite;
        self.variance_range = (
            self.variance_range.0.min(h.min_variance),
            self.variance_range.1.max(h.max_variance),
        );
    }

    fn row(&self, case: &str, steps: String, errors: String, note: String) -> Vec<String> {
        vec![
            case.to_string(),
            steps,
            errors,
            self.samples.to_string(),
            format!("{:.2e}", self.min_corr_eig),
            format!("{:.2e}", self.min_eig),
            format!("{:.1e}", self.max_symmetry),
            if self.cholesky_always { "yes" } else { "NO" }.into(),
            if self.finite_always { "yes" } else { "NO" }.into(),
            format!(
                "{:.1e} .. {:.1e}",
                self.variance_range.0, self.variance_range.1
            ),
            note,
        ]
    }
}

/// A stationary vehicle looking down azimuth 0 at `features`, `beams` times: the filter's
/// errors, its health extremes (measured every `health_every` beams) and the final estimates.
fn stare(
    features: &[([f64; 2], Material)],
    beams: usize,
    health_every: usize,
    settings: FilterSettings,
    pose_cov: Matrix3<f64>,
    seed: u64,
) -> Result<(u64, HealthExtremes, Ekf<MotionModel, RadarBeamModel>), EvalError> {
    let power = PowerModel::default();
    let noise = NoiseModel::default();
    let truth = Pose2::default();
    let mut ekf = Ekf::new(
        settings,
        truth,
        pose_cov,
        0.0,
        MotionModel::Bicycle { wheelbase_m: 2.7 },
        RadarBeamModel { power },
    )?;
    let mut rng = seeded_rng(seed);
    let feats: Vec<BeamFeature> = features
        .iter()
        .map(|(xy, material)| BeamFeature {
            xy: *xy,
            material: *material,
        })
        .collect();
    let mut errors = 0u64;
    let mut health = HealthExtremes::default();
    let dt = 0.4;
    for k in 0..beams {
        let t = k as f64 * dt;
        if let Err(_e) = ekf.apply_odometry(OdometrySample {
            timestamp_s: t,
            speed_mps: 0.0,
            steer_rad: 0.0,
        }) {
            errors += 1;
        }
        let obs = observe_beam(&truth, &feats, 0.0, &power)?;
        let targets = obs
            .z
            .iter()
            .map(|z| {
                let n = noise.perturb_observation(z.as_array(), &mut rng);
                Target {
                    range_m: n[0],
                    bearing_rad: n[1],
                    power_db: n[2],
                }
            })
            .collect();
        if ekf
            .process_beam(&BeamObservation {
                timestamp_s: t,
                bearing_rad: 0.0,
                targets,
            })
            .is_err()
        {
            errors += 1;
        }
        if k % health_every.max(1) == 0 || k + 1 == beams {
            health.add(&ekf.covariance_health(true));
        }
    }
    Ok((errors, health, ekf))
}

/// Random batched updates on a state whose variances span 1e-12 to 1e6 (log-spaced) with
/// random correlations: the update's own numerics, without a model in between.
fn wide_variances(updates: usize, seed: u64) -> Result<(u64, HealthExtremes), EvalError> {
    let features = 12;
    let n = FEATURE_BASE + FEATURE_DIM * features;
    let mut rng = seeded_rng(seed);
    let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
    let mut c = &a * a.transpose() + DMatrix::identity(n, n) * (n as f64);
    let d: Vec<f64> = (0..n).map(|i| c[(i, i)].sqrt()).collect();
    for j in 0..n {
        for i in 0..n {
            c[(i, j)] /= d[i] * d[j];
        }
    }
    let sd: Vec<f64> = (0..n)
        .map(|i| 10f64.powf(-6.0 + 9.0 * i as f64 / (n - 1) as f64))
        .collect();
    let cov = DMatrix::from_fn(n, n, |i, j| c[(i, j)] * sd[i] * sd[j]);
    let mean = DVector::from_fn(n, |i, _| {
        if i < FEATURE_BASE {
            0.0
        } else {
            rng.gen_range(-50.0..50.0)
        }
    });
    let mut state = SlamState::from_parts(mean, cov, 0.0)?;
    let mut health = HealthExtremes::default();
    health.add(&slam_filter::health::covariance_health(
        &state.covariance(),
        true,
    ));
    let mut errors = 0u64;
    for k in 0..updates {
        // Observe the pose, L and one feature with a random dense Jacobian and noise
        // spanning several decades.
        let slot = k % features;
        let mut columns: Vec<usize> = vec![0, 1, 2, LOSS_INDEX];
        columns.extend(feature_index(slot)..feature_index(slot) + FEATURE_DIM);
        let m = 3;
        let jacobian = DMatrix::from_fn(m, columns.len(), |_, _| rng.gen_range(-1.0..1.0));
        let noise_sd = 10f64.powf(rng.gen_range(-4.0..2.0));
        let obs = LinearisedObservation {
            columns,
            jacobian,
            innovation: DVector::from_fn(m, |_, _| noise_sd * rng.gen_range(-1.0..1.0)),
            noise: DMatrix::identity(m, m) * (noise_sd * noise_sd),
        };
        if batched_update(&mut state, &obs).is_err() {
            errors += 1;
        }
        if k % 100 == 0 || k + 1 == updates {
            health.add(&slam_filter::health::covariance_health(
                &state.covariance(),
                true,
            ));
        }
    }
    Ok((errors, health))
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let b = &opts.budget;
    let mut body = String::new();
    let mut rows = Vec::new();

    // The long run: the outdoor field driven in circles, targets mode.
    let mut scene = shipped::load("outdoor-field")?;
    let radius_m = 25.0;
    scene.schedule = ControlSchedule::new(
        vec![ControlKey {
            t_s: 0.0,
            speed_mps: 2.0,
            steer_rad: (2.7f64 / radius_m).atan(),
        }],
        Interpolation::Hold,
    )?;
    let per_s = f64::from(scene.radar.azimuths) * scene.radar.rotation_hz();
    let seconds = b.stability_steps as f64 / per_s;
    let rotations = (seconds * scene.radar.rotation_hz()).floor().max(1.0);
    let health_every = ((rotations / 200.0).ceil()).max(1.0) as usize;
    let mut spec = shipped_spec(scene, 99, seconds, Mode::Targets)?;
    spec.health_every_rotations = Some(health_every);
    let started = std::time::Instant::now();
    let r = run(&spec)?;
    let wall_s = started.elapsed().as_secs_f64();
    let mut extremes = HealthExtremes::default();
    for h in r.rotations.iter().filter_map(|x| x.health.as_ref()) {
        extremes.add(h);
    }
    let steps = format!(
        "{} beams (one predict each), {} updates, {} odometry samples",
        r.beams,
        r.stats.updates,
        (seconds * 20.0).round()
    );
    rows.push(extremes.row(
        "long run, circling the outdoor field",
        steps,
        format!(
                "{}{}",
                r.beam_errors.0,
                r.beam_errors
                    .1
                    .as_ref()
                    .map_or(String::new(), |m| format!(" (first: {m})"))
            ),
        format!(
            "{:.0} s simulated in {:.1} s; position RMSE {} m; mean NEES {}; features {}",
            seconds,
            wall_s,
            num(rms(r.rotations.iter().map(|x| x.position_error_m())), 3),
            num(mean(r.rotations.iter().filter_map(|x| x.nees)), 2),
            r.final_features
        ),
    ));
    let fig = "stability_health.svg";
    let health_points = |f: &dyn Fn(&CovarianceHealth) -> f64| -> Vec<(f64, f64)> {
        r.rotations
            .iter()
            .filter_map(|x| x.health.as_ref().map(|h| (x.time_s, f(h))))
            .collect()
    };
    line_chart(
        &opts.out_dir.join(fig),
        Labels {
            title: "covariance health over the long run (log10)",
            x: "time (s)",
            y: "log10 of the figure",
        },
        &[
            Series {
                name: "min eigenvalue of the correlation matrix".into(),
                points: health_points(&|h| {
                    h.min_correlation_eigenvalue.unwrap_or(f64::NAN).log10()
                }),
            },
            Series {
                name: "min variance".into(),
                points: health_points(&|h| h.min_variance.log10()),
            },
            Series {
                name: "max variance".into(),
                points: health_points(&|h| h.max_variance.log10()),
            },
            Series {
                name: "position error (m)".into(),
                points: r
                    .rotations
                    .iter()
                    .map(|x| (x.time_s, x.position_error_m().max(1e-9).log10()))
                    .collect(),
            },
        ],
        &[],
    )?;

    let hard_beams = (b.stability_steps as usize / 50).clamp(50, 5_000);
    let settings = FilterSettings::default();
    let small = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6));
    let m = |rho: f64, alpha: f64| Material::from_rho_alpha(rho, alpha);

    // Equal ranges: two features at exactly 20 m, 0.4 degrees apart, inside one beam.
    let a = 0.4f64.to_radians();
    let equal = [
        ([20.0, 0.0], m(0.2, 0.1)?),
        ([20.0 * a.cos(), -20.0 * a.sin()], m(0.4, 0.1)?),
        ([35.0, 0.0], m(0.5, 0.1)?),
    ];
    let (errors, h, ekf) = stare(&equal, hard_beams, 10, settings.clone(), small, 5)?;
    rows.push(h.row(
        "equal ranges down one beam",
        format!("{hard_beams} beams"),
        errors.to_string(),
        format!(
            "features {}; pose error {} m",
            ekf.feature_count(),
            num(ekf.pose().x.hypot(ekf.pose().y), 4)
        ),
    ));

    // rho + alpha near 1: a nearly opaque front target (tau = 1e-9) before two others.
    let opaque = [
        ([10.0, 0.0], m(0.5, 0.5 - 1e-9)?),
        ([18.0, 0.0], m(0.6, 0.2)?),
        ([30.0, 0.0], m(0.3, 0.2)?),
    ];
    let (errors, h, ekf) = stare(&opaque, hard_beams, 10, settings.clone(), small, 6)?;
    let taus: Vec<String> = ekf
        .features()
        .iter()
        .map(|f| format!("{:.1e}", (1.0 - f.rho - f.alpha).max(0.0)))
        .collect();
    rows.push(h.row(
        "rho + alpha = 1 - 1e-9 in front",
        format!("{hard_beams} beams"),
        errors.to_string(),
        format!("estimated tau per feature: {}", taus.join(", ")),
    ));

    // Wide variances through the whole filter: pose 1e-12, loss and materials 1e6.
    let wide_settings = FilterSettings {
        initial_loss_std_db: 1e3,
        initial_material_std: 1e3,
        ..settings
    };
    let tiny = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-12, 1e-12, 1e-12));
    let spread = [([15.0, 0.0], m(0.3, 0.1)?), ([40.0, 0.0], m(0.4, 0.2)?)];
    let (errors, h, ekf) = stare(&spread, hard_beams, 10, wide_settings, tiny, 7)?;
    rows.push(h.row(
        "variances 1e-12 (pose) to 1e6 (L, u, v) through the filter",
        format!("{hard_beams} beams"),
        errors.to_string(),
        format!(
            "final heading {} rad; L {} dB",
            num(wrap_angle(ekf.pose().theta), 6),
            num(ekf.state().loss_db(), 2)
        ),
    ));

    let updates = (b.stability_steps as usize / 10).clamp(100, 100_000);
    let (errors, h) = wide_variances(updates, 8)?;
    rows.push(h.row(
        "variances log-spaced 1e-12 .. 1e6, random correlations, random updates",
        format!("{updates} batched updates"),
        errors.to_string(),
        "update refused when a variance would turn non-positive (counted as errors)".into(),
    ));

    let _ = writeln!(
        body,
        "Health figures are slam-node's `covariance_health` (with eigenvalues): the smallest \
         eigenvalue of the correlation matrix `D^-1/2 P D^-1/2` (scale-free: in (0, 1] for a \
         positive definite P whatever the spread of variances), the smallest eigenvalue of P \
         itself (its absolute accuracy is about n eps max variance, so it cannot show \
         definiteness when variances span decades), the largest `|P_ij - P_ji|`, whether \
         Cholesky succeeded at every check, and the range of variances. The long run is the \
         outdoor field driven in circles of {radius_m} m at 2 m/s for {} azimuths (targets \
         mode, health every {health_every} rotations); the hard cases stare from a stationary \
         vehicle down azimuth 0.\n",
        b.stability_steps
    );
    body.push_str(&table(
        &[
            "case",
            "steps",
            "errors",
            "health checks",
            "min corr. eigenvalue",
            "min eigenvalue of P",
            "max asymmetry",
            "Cholesky always",
            "finite always",
            "variances",
            "notes",
        ],
        &rows,
    ));
    let _ = writeln!(body, "\n![health]({fig})\n");
    Ok(Section {
        title: "Numerical stability at scale".into(),
        body,
    })
}
