//! Speed against error: one knob at a time away from the shipped settings (azimuth and bin
//! decimation, detector settings, update batching, power in or out of the observation,
//! features kept in the state), each run timed alone, plotted as time per rotation against
//! position error.

use std::fmt::Write as _;

use sim_sensor::scene::shipped;
use slam_node::detect::DetectorKind;

use crate::error::EvalError;
use crate::metrics::{quantile, rms};
use crate::plot::{scatter_chart, LabelledPoint, Labels};
use crate::report::{num, table, Options, Section};
use crate::run::{run, Mode, RunSpec};
use crate::sections::{shipped_daemon, shipped_spec};

/// One point of the sweep.
#[derive(Debug, Clone)]
pub struct Point {
    /// Which knob and value.
    pub label: String,
    /// The shipped settings.
    pub shipped: bool,
    /// Median processing time per rotation (ms).
    pub median_ms: f64,
    /// 95th percentile (ms).
    pub p95_ms: f64,
    /// Position RMSE (m).
    pub position_rmse_m: f64,
    /// Heading RMSE (deg).
    pub heading_rmse_deg: f64,
    /// Features at the end.
    pub features: usize,
}

fn variants(base: &RunSpec) -> Vec<(String, bool, RunSpec)> {
    let mut out = Vec::new();
    let with = |f: &dyn Fn(&mut RunSpec)| {
        let mut s = base.clone();
        f(&mut s);
        s
    };
    let Mode::Daemon(daemon) = &base.mode else {
        return out;
    };
    let daemon = daemon.clone();
    let detector = |f: &dyn Fn(&mut slam_node::detect::DetectorSettings)| {
        let mut d = daemon.clone();
        f(&mut d.detector);
        Mode::Daemon(d)
    };
    for thr in [9.0, 16.0] {
        let mode = detector(&|d| {
            d.kind = DetectorKind::OsCfar;
            d.os_scale_db = thr;
        });
        out.push((
            format!("OS-CFAR {thr} dB"),
            false,
            with(&|s| s.mode = mode.clone()),
        ));
    }
    let ca = detector(&|d| {
        d.kind = DetectorKind::CaCfar;
        d.ca_scale_db = 12.0;
    });
    out.push((
        "CA-CFAR 12 dB".into(),
        false,
        with(&|s| s.mode = ca.clone()),
    ));
    for snr in [14.0, 26.0] {
        let mode = detector(&|d| d.tpp.snr_threshold_db = snr);
        out.push((
            format!("TPP {snr} dB"),
            false,
            with(&|s| s.mode = mode.clone()),
        ));
    }
    out.push((
        "no power".into(),
        false,
        with(&|s| s.filter.use_power = false),
    ));
    out.push((
        "standard EKF (no FEJ)".into(),
        false,
        with(&|s| s.filter.first_estimate_jacobians = false),
    ));
    for n in [40, 15] {
        out.push((
            format!("max {n} features"),
            false,
            with(&|s| s.filter.max_features = n),
        ));
    }
    out
}

/// Runs the sweep on one scene (sequentially: timings are taken one run at a time).
pub fn sweep(scene_name: &str, seconds: f64) -> Result<Vec<Point>, EvalError> {
    let scene = shipped::load(scene_name)?;
    let base = shipped_spec(scene, 11, seconds, shipped_daemon()?)?;
    let mut all = vec![("daemon as shipped".to_string(), true, base.clone())];
    all.extend(variants(&base));
    let mut points = Vec::new();
    for (label, shipped, spec) in all {
        let r = run(&spec)?;
        // Skip the first rotation (warm-up: allocation, first features).
        let times: Vec<f64> = r.rotations.iter().skip(1).map(|x| 1e3 * x.work_s).collect();
        points.push(Point {
            label,
            shipped,
            median_ms: quantile(&times, 0.5),
            p95_ms: quantile(&times, 0.95),
            position_rmse_m: rms(r.rotations.iter().map(|x| x.position_error_m())),
            heading_rmse_deg: rms(r
                .rotations
                .iter()
                .map(|x| x.heading_error_rad().to_degrees())),
            features: r.final_features,
        });
    }
    Ok(points)
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let b = &opts.budget;
    let mut body = String::new();
    let _ = writeln!(
        body,
        "Each point changes one knob from the shipped settings and runs the whole pipeline \
         (simulated spectra, detector, grouper, filter) for {} s, seed 11, alone on the \
         machine's share of 2 cores. Time: wall time per rotation of detection, grouping and \
         filtering (rendering excluded; it is the radar's work), median and 95th percentile \
         over rotations after the first. Error: position and heading RMSE against the truth \
         at each rotation's end. `azimuths 1/k`: every k-th spectrum; `bins 1/k`: the \
         strongest of each k bins; `batch k`: the targets of k consecutive azimuths in one \
         update at the last one's time; `max n features`: the state's feature cap.\n",
        b.sweep_seconds
    );
    let scenes: &[&str] = if b.skip_heavy {
        &["outdoor-field"]
    } else {
        &["outdoor-field", "dense-clutter"]
    };
    for &scene in scenes {
        let period_s = 1.0 / shipped::load(scene)?.radar.rotation_hz();
        let points = sweep(scene, b.sweep_seconds)?;
        let fig = format!("sweep_{scene}.svg");
        let title = format!("time per rotation against position error ({scene})");
        scatter_chart(
            &opts.out_dir.join(&fig),
            Labels {
                title: &title,
                x: "median time per rotation (ms)",
                y: "position RMSE (m)",
            },
            &points
                .iter()
                .map(|p| LabelledPoint {
                    x: p.median_ms,
                    y: p.position_rmse_m,
                    label: p.label.clone(),
                    highlight: p.shipped,
                })
                .collect::<Vec<_>>(),
        )?;
        let rows: Vec<Vec<String>> = points
            .iter()
            .map(|p| {
                vec![
                    if p.shipped {
                        format!("**{}**", p.label)
                    } else {
                        p.label.clone()
                    },
                    num(p.median_ms, 2),
                    num(p.p95_ms, 2),
                    num(p.position_rmse_m, 3),
                    num(p.heading_rmse_deg, 3),
                    p.features.to_string(),
                ]
            })
            .collect();
        let _ = writeln!(
            body,
            "### {scene} (rotation period {} ms)\n",
            (period_s * 1e3) as u32
        );
        body.push_str(&table(
            &[
                "setting",
                "median ms/rotation",
                "p95 ms",
                "position RMSE (m)",
                "heading RMSE (deg)",
                "features",
            ],
            &rows,
        ));
        let _ = writeln!(body, "\n![sweep]({fig})\n");
        if let Some(shipped) = points.iter().find(|p| p.shipped) {
            let faster_and_better: Vec<&Point> = points
                .iter()
                .filter(|p| {
                    !p.shipped
                        && !p.label.starts_with("base")
                        && p.median_ms < shipped.median_ms
                        && p.position_rmse_m <= shipped.position_rmse_m
                })
                .collect();
            let _ = writeln!(
                body,
                "Shipped: {} ms per rotation ({:.1} % of the {} ms rotation), position RMSE {} m.",
                num(shipped.median_ms, 2),
                100.0 * shipped.median_ms / (period_s * 1e3),
                (period_s * 1e3) as u32,
                num(shipped.position_rmse_m, 3)
            );
            if faster_and_better.is_empty() {
                let _ = writeln!(
                    body,
                    "No variant is both faster and at least as accurate in this run.\n"
                );
            } else {
                let names: Vec<&str> = faster_and_better.iter().map(|p| p.label.as_str()).collect();
                let _ = writeln!(
                    body,
                    "Faster than the daemon as shipped and at least as accurate in this run: \
                     {}. One seed and a few seconds per point: position differences of a \
                     few centimetres are within run-to-run spread, and the timings move with \
                     the machine's load.\n",
                    names.join(", ")
                );
            }
        }
    }
    Ok(Section {
        title: "Speed against error".into(),
        body,
    })
}
