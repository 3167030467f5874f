//! The realistic city (issue 35) driven on the radar alone through the whole daemon as a user
//! runs it: `config/examples/realistic-city-radar-only.toml` with the simulator in this
//! process, as fast as it runs (`slam-node --config ... --embedded-sim --fast --duration`),
//! scored against the simulator's truth. The section quotes the daemon's own summary as it
//! prints it, adds the absolute trajectory error after a rigid alignment (as the radar
//! odometry literature reports ATE, `evaluation/ate_aligned.py`'s method), and draws the
//! city's layout with the true route, the online pose (as published during the run) and the
//! optimised trajectory (the global layer's final frames) over it.
//!
//! **IO**: the simulator and the daemon talk over 127.0.0.1:0; the daemon's outputs go to a
//! temporary folder; the figure goes to the report folder.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use sim_sensor::scene::Scene;
use sim_sensor::visits::drive_samples;
use slam_node::daemon::run_daemon;

use crate::city_realism::{read_tum_poses as read_tum, write_map};
use crate::error::EvalError;
use crate::plot::{line_chart, Labels, Series};
use crate::report::{num, table, Options, Section};

/// The configuration driven, relative to the workspace.
pub const CONFIG: &str = "config/examples/realistic-city-radar-only.toml";
/// The scene it drives, relative to the workspace (the main layout).
pub const SCENE: &str = "sim-sensor/scenes/realistic-city.toml";
/// The map's file name in the report folder.
pub const FIGURE: &str = "realistic_city_map.svg";
/// The errors' file name in the report folder.
pub const ERRORS_FIGURE: &str = "realistic_city_error.svg";
/// Two rows of different files are the same rotation's when their times differ by less than
/// this (s).
const SAME_TIME_S: f64 = 1e-3;

/// The workspace's root (this crate's parent folder).
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// One pose of a TUM file: time (s), x, y (m), heading (rad).
type TumPose = [f64; 4];

/// The pairs of `est` and `truth` rows at the same time (within [`SAME_TIME_S`]), each with
/// its truth row's index; `truth` in time order.
fn paired(est: &[TumPose], truth: &[TumPose]) -> Vec<(TumPose, TumPose, usize)> {
    est.iter()
        .filter_map(|e| {
            let j = truth.partition_point(|g| g[0] < e[0]);
            [j.checked_sub(1), Some(j)]
                .into_iter()
                .flatten()
                .filter(|&k| {
                    truth
                        .get(k)
                        .is_some_and(|g| (g[0] - e[0]).abs() < SAME_TIME_S)
                })
                .min_by(|&a, &b| {
                    (truth[a][0] - e[0])
                        .abs()
                        .total_cmp(&(truth[b][0] - e[0]).abs())
                })
                .map(|k| (*e, truth[k], k))
        })
        .collect()
}

/// The distance driven along `truth` (in time order) to each of its rows (m).
fn travelled(truth: &[TumPose]) -> Vec<f64> {
    let mut d = 0.0;
    let mut out = Vec::with_capacity(truth.len());
    for (k, g) in truth.iter().enumerate() {
        if let Some(p) = k.checked_sub(1).map(|j| truth[j]) {
            d += (g[1] - p[1]).hypot(g[2] - p[2]);
        }
        out.push(d);
    }
    out
}

/// Each estimate's position error against the truth at the same time, by the distance
/// driven to it: `(km, m)`.
fn error_along(est: &[TumPose], truth: &[TumPose], along: &[f64]) -> Vec<(f64, f64)> {
    paired(est, truth)
        .into_iter()
        .map(|(e, g, k)| (1e-3 * along[k], (e[1] - g[1]).hypot(e[2] - g[2])))
        .collect()
}

/// An estimate scored against the truth at the same times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryError {
    /// Poses scored.
    pub poses: usize,
    /// Position error RMS, as published (m).
    pub rms_m: f64,
    /// Largest position error, as published (m).
    pub max_m: f64,
    /// Position error RMS after the rigid SE(2) alignment that minimises it (m).
    pub aligned_rms_m: f64,
    /// That alignment's rotation (rad).
    pub alignment_turn_rad: f64,
}

/// Scores `est` against `truth`: RMS and largest error as they are, and the RMS after the
/// closed-form least-squares rigid alignment of the positions (Umeyama without scale, in
/// the plane). `None` with fewer than two poses at common times.
pub fn trajectory_error(est: &[TumPose], truth: &[TumPose]) -> Option<TrajectoryError> {
    let pairs = paired(est, truth);
    let n = pairs.len();
    if n < 2 {
        return None;
    }
    let mean =
        |f: fn(&(TumPose, TumPose, usize)) -> f64| pairs.iter().map(f).sum::<f64>() / n as f64;
    let (ex, ey) = (mean(|p| p.0[1]), mean(|p| p.0[2]));
    let (gx, gy) = (mean(|p| p.1[1]), mean(|p| p.1[2]));
    // The rotation taking the centred estimate onto the centred truth: atan2 of the summed
    // cross and dot products.
    let (mut cross, mut dot) = (0.0, 0.0);
    for (e, g, _) in &pairs {
        let (ax, ay, bx, by) = (e[1] - ex, e[2] - ey, g[1] - gx, g[2] - gy);
        dot += ax * bx + ay * by;
        cross += ax * by - ay * bx;
    }
    let turn = cross.atan2(dot);
    let (s, c) = turn.sin_cos();
    let (mut raw2, mut max, mut aligned2) = (0.0, 0.0_f64, 0.0);
    for (e, g, _) in &pairs {
        let d = (e[1] - g[1]).hypot(e[2] - g[2]);
        raw2 += d * d;
        max = max.max(d);
        let (ax, ay) = (e[1] - ex, e[2] - ey);
        let (x, y) = (c * ax - s * ay + gx, s * ax + c * ay + gy);
        aligned2 += (x - g[1]).powi(2) + (y - g[2]).powi(2);
    }
    Some(TrajectoryError {
        poses: n,
        rms_m: (raw2 / n as f64).sqrt(),
        max_m: max,
        aligned_rms_m: (aligned2 / n as f64).sqrt(),
        alignment_turn_rad: turn,
    })
}

/// Runs the daemon on the realistic city for `seconds` of its drive, radar only, with its
/// outputs in `out`; returns the summary it prints.
fn drive(seconds: f64, out: &Path) -> Result<String, EvalError> {
    let root = workspace();
    let path = root.join(CONFIG);
    let (mut config, written) = config::Config::load_with_written(&path).map_err(|e| {
        EvalError::Setting(format!("{}: {}", path.display(), crate::error_chain(&e)))
    })?;
    config.sim.scene = config::sim::SceneRef::File(root.join(SCENE));
    // Nothing the section does not read: no per-azimuth truth file, spectra or pictures.
    config.output.ground_truth = false;
    config.output.spectra = false;
    config.output.pictures = false;
    config.output.progress = false;
    let mut sim = sim_sensor::SimOptions::from_config(&config.sim)?;
    let any = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    sim.bind = any;
    sim.odometry_bind = Some(any);
    sim.gyro_bind = (config.gyro.source != config::gyro::GyroSource::None).then_some(any);
    sim.pacing = sim_sensor::settings::Pacing::AsFastAsPossible;
    let opts = crate::daemon::embedded_run_options(config, written, sim, seconds, out);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|source| EvalError::Io {
            path: PathBuf::from("(tokio runtime)"),
            source,
        })?;
    let result = runtime.block_on(run_daemon(opts, None));
    // The simulator's writers may still be flushing on the blocking pool.
    runtime.shutdown_timeout(std::time::Duration::from_secs(2));
    let report = result
        .map_err(|e| EvalError::Setting(format!("the daemon: {}", crate::error_chain(&e))))?;
    if let Some(why) = &report.run.start_failure {
        return Err(EvalError::Setting(format!(
            "the pipeline did not start: {why}"
        )));
    }
    // Every line but the temporary folder's name, which is gone when the section ends.
    Ok(slam_node::daemon::report::summary_text(&report)
        .lines()
        .filter(|l| !l.trim_start().starts_with("outputs in "))
        .fold(String::new(), |mut s, l| {
            s.push_str(l);
            s.push('\n');
            s
        }))
}

/// The realistic city on the radar alone: the daemon's summary, the aligned error and the map.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let root = workspace();
    let scene = Scene::load(&root.join(SCENE))?;
    let layout = scene
        .city
        .clone()
        .ok_or_else(|| EvalError::Setting(format!("{SCENE} has no [city]")))?;
    // The stream is asked for the budget's seconds (470: the documented command's
    // `--duration`); the drive ends with the route.
    let seconds = opts.budget.city_seconds;
    let driven_s = seconds.min(layout.drive_duration_s);
    let work = tempfile::tempdir().map_err(|source| EvalError::Io {
        path: std::env::temp_dir(),
        source,
    })?;
    let started = std::time::Instant::now();
    let summary = drive(seconds, work.path())?;
    let wall_s = started.elapsed().as_secs_f64();
    let truth = {
        let mut t = read_tum(&work.path().join("groundtruth.tum"))?;
        t.sort_by(|a, b| a[0].total_cmp(&b[0]));
        t
    };
    let along = travelled(&truth);
    let files = [
        (
            "online pose (trajectory-online.tum)",
            "trajectory-online.tum",
        ),
        ("optimised (trajectory.tum)", "trajectory.tum"),
        (
            "odometry, no global corrections (trajectory-odometry.tum)",
            "trajectory-odometry.tum",
        ),
    ];
    let mut rows = Vec::new();
    let mut drawn = Vec::new();
    let mut errors = Vec::new();
    for (name, file) in files {
        let est = read_tum(&work.path().join(file))?;
        let e = trajectory_error(&est, &truth).ok_or_else(|| {
            EvalError::Setting(format!("{file}: fewer than two poses at the truth's times"))
        })?;
        rows.push(vec![
            name.to_string(),
            e.poses.to_string(),
            num(e.rms_m, 2),
            num(e.max_m, 2),
            num(e.aligned_rms_m, 3),
            num(e.alignment_turn_rad.to_degrees(), 3),
        ]);
        errors.push(Series {
            name: name.to_string(),
            points: error_along(&est, &truth, &along),
        });
        if file != "trajectory-odometry.tum" {
            drawn.push((
                name.to_string(),
                est.iter().map(|p| (p[1], p[2])).collect::<Vec<_>>(),
            ));
        }
    }
    let samples = drive_samples(&scene, driven_s, 0.25)?;
    write_map(&opts.out_dir.join(FIGURE), &scene, &samples, &drawn)?;
    line_chart(
        &opts.out_dir.join(ERRORS_FIGURE),
        Labels {
            title: "realistic city, radar alone: position error against the truth",
            x: "distance driven (km)",
            y: "position error (m)",
        },
        &errors,
        &[],
    )?;
    let mut body = String::new();
    let _ = writeln!(
        body,
        "The realistic city (`{SCENE}`: {:.0} m of route, building fronts with set-backs and \
         gaps, fences, hedges, trees, poles, parked and moving vehicles, the CTS350-X-like \
         unit) driven for {driven_s:.0} s ({:.0} m) on the radar alone (no wheel odometry, no gyro) \
         through the whole daemon as a user runs it: `{CONFIG}` with the simulator in this \
         process over loopback, as fast as it runs (the equivalent command: `cargo run \
         --release -p slam-node -- --config {CONFIG} --embedded-sim --fast --duration \
         {seconds:.0}`), the shipped speckle seed; {wall_s:.0} s of wall time on this \
         machine. One drive, not the ten-drive means slam-node/README.md quotes \
         (\"Registrations at a crawl pair with surfaces only\").\n",
        layout.route_length_m,
        along.last().copied().unwrap_or(0.0)
    );
    let _ = writeln!(
        body,
        "Every estimate against the truth at the same rotations; `aligned`: after the rigid \
         SE(2) alignment that minimises the error (as the radar odometry literature reports \
         ATE; `evaluation/ate_aligned.py` computes the same from the files). The online pose \
         is what a vehicle consumes during the run (the global layer's corrections included \
         as they were found); the optimised trajectory is the global layer's final frames; \
         the odometry is the filter's pose chained through the submaps with no correction.\n"
    );
    body.push_str(&table(
        &[
            "trajectory",
            "poses",
            "RMS (m)",
            "max (m)",
            "aligned RMS (m)",
            "alignment turn (deg)",
        ],
        &rows,
    ));
    let _ = writeln!(
        body,
        "\n![the realistic city, the true route and both trajectories]({FIGURE})\n\n\
         ![the position error along the drive]({ERRORS_FIGURE})\n"
    );
    let _ = writeln!(
        body,
        "The daemon's own summary of the run (drift over 100-800 m segments as KITTI and \
         Boreas define it, loop closures against the truth's revisits, NEES, time per \
         rotation), as it printed it (but for the line naming its temporary output folder):\n\n```text\n{}```\n",
        summary
    );
    Ok(Section {
        title: "The realistic city on the radar alone".into(),
        body,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_and_shifted_copy_of_the_truth_aligns_to_zero() {
        let truth: Vec<TumPose> = (0..50)
            .map(|k| {
                let t = f64::from(k);
                [t * 0.25, t, (0.3 * t).sin() * 5.0, 0.0]
            })
            .collect();
        let (s, c) = 0.2_f64.sin_cos();
        let est: Vec<TumPose> = truth
            .iter()
            .map(|g| {
                [
                    g[0] + 1e-4,
                    c * g[1] - s * g[2] + 3.0,
                    s * g[1] + c * g[2] - 2.0,
                    g[3],
                ]
            })
            .collect();
        let e = trajectory_error(&est, &truth).expect("scored");
        assert_eq!(e.poses, 50);
        assert!(e.rms_m > 1.0, "raw error {}", e.rms_m);
        assert!(e.aligned_rms_m < 1e-9, "aligned {}", e.aligned_rms_m);
        assert!(
            (e.alignment_turn_rad + 0.2).abs() < 1e-9,
            "{}",
            e.alignment_turn_rad
        );
    }

    #[test]
    fn rows_without_a_partner_at_the_same_time_are_left_out() {
        let truth: Vec<TumPose> = (0..10).map(|k| [f64::from(k), 0.0, 0.0, 0.0]).collect();
        let est: Vec<TumPose> = (0..10)
            .map(|k| {
                [
                    f64::from(k) + if k % 2 == 0 { 0.0 } else { 0.5 },
                    1.0,
                    0.0,
                    0.0,
                ]
            })
            .collect();
        let e = trajectory_error(&est, &truth).expect("scored");
        assert_eq!(e.poses, 5);
        assert!((e.rms_m - 1.0).abs() < 1e-12);
        assert!(trajectory_error(&est[..1], &truth).is_none());
    }
}
