//! Accuracy on every shipped scene: position and heading RMSE against the truth, the map's
//! position error, and the error of the estimated reflectivity, absorption and radar loss.

use std::fmt::Write as _;

use sim_sensor::scene::shipped;

use crate::error::EvalError;
use crate::metrics::{mean, nis_per_dof, quantile, rms};
use crate::plot::{line_chart, Labels, Series};
use crate::report::{num, table, Options, Section};
use crate::run::{run_many, Mode, RunOutcome};
use crate::sections::{shipped_daemon, shipped_spec};

/// Simulated seconds for a scene: its schedule's length (at least 10 s), capped by the budget.
fn seconds_for(scene: &sim_sensor::scene::Scene, cap_s: f64) -> f64 {
    let natural = scene.schedule.last_key_s().max(10.0);
    natural.min(cap_s)
}

/// One row of the accuracy table.
/// Scenes with more point features than this run in daemon mode only (see `run`).
const TARGETS_MAX_FEATURES: usize = 500;

pub fn row(
    scene: &str,
    mode: &str,
    seconds: f64,
    r: &RunOutcome,
    true_features: usize,
) -> Vec<String> {
    let pos = rms(r.rotations.iter().map(|x| x.position_error_m()));
    let max_pos = r
        .rotations
        .iter()
        .map(|x| x.position_error_m())
        .fold(0.0, f64::max);
    let heading = rms(r
        .rotations
        .iter()
        .map(|x| x.heading_error_rad().to_degrees()));
    // The daemon scores its own map (nearest scene feature within 2 m of each final
    // feature); the evaluation's runs score by the feature each one was created from.
    let (mapped, clutter, map_err, rho, alpha, nis) =
        match r.daemon.as_ref().and_then(|d| d.map.as_ref()) {
            Some(m) => (
                m.distinct_scene_features_matched,
                format!("{} unmatched", m.mapped.saturating_sub(m.matched)),
                m.mean_match_error_m,
                m.mean_rho_error,
                m.mean_alpha_error,
                f64::NAN,
            ),
            None => {
                let mapped: std::collections::BTreeSet<u32> =
                    r.features.iter().map(|f| f.truth_id).collect();
                (
                    mapped.len(),
                    format!("{} from clutter", r.association.clutter_features),
                    mean(r.features.iter().map(|f| f.position_m)),
                    mean(r.features.iter().map(|f| f.rho.abs())),
                    mean(r.features.iter().map(|f| f.alpha.abs())),
                    nis_per_dof(&r.nis),
                )
            }
        };
    vec![
        scene.to_string(),
        mode.to_string(),
        num(seconds, 1),
        num(pos, 3),
        num(max_pos, 3),
        num(heading, 3),
        format!("{mapped} / {true_features} ({clutter})"),
        r.final_features.to_string(),
        num(map_err, 3),
        num(rho, 3),
        num(alpha, 3),
        format!("{} ({})", num(r.loss_db.0, 2), num(r.loss_db.1, 1)),
        num(nis, 2),
        num(
            1e3 * quantile(
                &r.rotations
                    .iter()
                    .skip(1)
                    .map(|x| x.work_s)
                    .collect::<Vec<_>>(),
                0.5,
            ),
            1,
        ),
        r.beam_errors.0.to_string(),
    ]
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let b = &opts.budget;
    let mut specs = Vec::new();
    let mut meta = Vec::new();
    let mut skipped = Vec::new();
    for name in shipped::NAMES {
        let scene = shipped::load(name)?;
        let seconds = seconds_for(&scene, b.scene_seconds);
        let n = scene.features.len();
        // The CTS350-X-like radar (3768 bins, 1600 azimuths a second) under the shipped
        // detector makes hundreds of features a second: its detection runs are kept short.
        let heavy = scene.radar.range_bins > 1000;
        let pipeline_s = if heavy {
            seconds.min(b.heavy_scene_seconds)
        } else {
            seconds
        };
        // Targets mode keeps every feature it sees in one filter (no submaps): a city's
        // thousands of features cost O(n^2) a beam, hours a run.
        let targets = n <= TARGETS_MAX_FEATURES;
        if !targets {
            skipped.push(format!("`{name}` ({n} features)"));
        }
        if heavy && b.skip_heavy {
            if targets {
                specs.push(shipped_spec(scene, 7, seconds, Mode::Targets)?);
                meta.push((name, "targets", seconds, n));
            }
            continue;
        }
        specs.push(shipped_spec(
            scene.clone(),
            7,
            pipeline_s,
            shipped_daemon()?,
        )?);
        meta.push((name, "daemon", pipeline_s, n));
        if targets {
            specs.push(shipped_spec(scene, 7, seconds, Mode::Targets)?);
            meta.push((name, "targets", seconds, n));
        }
    }
    let results = run_many(&specs, b.jobs);
    let mut rows = Vec::new();
    let mut series = Vec::new();
    let mut failures = String::new();
    for ((name, mode, seconds, n), r) in meta.iter().zip(&results) {
        match r {
            Ok(r) => {
                rows.push(row(name, mode, *seconds, r, *n));
                if *mode == "daemon" {
                    series.push(Series {
                        name: name.to_string(),
                        points: r
                            .rotations
                            .iter()
                            .map(|x| (x.time_s, x.position_error_m()))
                            .collect(),
                    });
                }
            }
            Err(e) => {
                let _ = writeln!(failures, "- `{name}` ({mode}) failed: {e}");
            }
        }
    }
    let fig = "accuracy_position_error.svg";
    line_chart(
        &opts.out_dir.join(fig),
        Labels {
            title: "position error through the whole pipeline, shipped settings",
            x: "time (s)",
            y: "position error (m)",
        },
        &series,
        &[],
    )?;
    let mut body = String::new();
    let _ = writeln!(
        body,
        "Every shipped scene, seed 7, for its control schedule's length (at least 10 s, at most \
         {} s). `daemon`: the daemon's own pipeline as shipped, fed the simulator's wire \
         frames (the only spectra path: the evaluation keeps no copy of its detection or \
         grouping); `targets`: every feature in the beam observed with the \
         filter's own noise model (no detection). Errors are against the simulator's truth \
         at the end of each rotation. Map error: for `daemon`, the daemon's own score (each \
         final feature against the nearest scene feature within 2 m); otherwise each final \
         feature against the true feature it was initialised from. rho and alpha: mean absolute error of the estimated \
         shares. L: estimated radar loss (true value in brackets).\n",
        b.scene_seconds
    );
    body.push_str(&table(
        &[
            "scene",
            "observations",
            "s",
            "position RMSE (m)",
            "max (m)",
            "heading RMSE (deg)",
            "true features mapped",
            "features in state",
            "mean map error (m)",
            "rho MAE",
            "alpha MAE",
            "L dB (true)",
            "NIS/dof",
            "median ms/rotation",
            "refused beams",
        ],
        &rows,
    ));
    body.push_str(&failures);
    if !skipped.is_empty() {
        let _ = writeln!(
            body,
            "\nNot run in targets mode (more than {TARGETS_MAX_FEATURES} features, all in one \
             filter without submaps): {}.",
            skipped.join(", ")
        );
    }
    let _ = writeln!(body, "\n![position error]({fig})\n");
    Ok(Section {
        title: "Accuracy on the shipped scenes".into(),
        body,
    })
}
