//! Consistency: the average pose NEES over Monte Carlo runs against the chi-square band,
//! over time; the NIS of the updates; where the filter turns optimistic.

use std::fmt::Write as _;

use sim_sensor::scene::shipped;

use crate::error::EvalError;
use crate::metrics::{average_chi2_band, mean, nis_fraction_inside, nis_per_dof};
use crate::plot::{line_chart, HLine, Labels, Series};
use crate::report::{num, pct, table, Options, Section};
use crate::run::{run_many, Mode, RunOutcome};
use crate::sections::{shipped_daemon, shipped_spec};

/// The scene the Monte Carlo runs use: the paper's outdoor field.
pub const SCENE: &str = "outdoor-field";

/// Average NEES per rotation over the runs (rotations all runs share).
pub fn average_nees(runs: &[RunOutcome]) -> Vec<(f64, f64)> {
    let len = runs.iter().map(|r| r.rotations.len()).min().unwrap_or(0);
    (0..len)
        .map(|i| {
            let t = runs
                .first()
                .and_then(|r| r.rotations.get(i))
                .map_or(f64::NAN, |r| r.time_s);
            let v = mean(
                runs.iter()
                    .filter_map(|r| r.rotations.get(i).and_then(|x| x.nees)),
            );
            (t, v)
        })
        .collect()
}

struct Summary {
    label: String,
    runs: usize,
    series: Vec<(f64, f64)>,
    band: (f64, f64),
    inside: f64,
    time_mean: f64,
    nis_dof: f64,
    nis_inside: f64,
    first_optimistic_s: Option<f64>,
    heading_sigma_deg: f64,
    failed: usize,
    beam_errors: u64,
}

fn summarise(label: &str, results: Vec<Result<RunOutcome, EvalError>>) -> Summary {
    let failed = results.iter().filter(|r| r.is_err()).count();
    let runs: Vec<RunOutcome> = results.into_iter().filter_map(Result::ok).collect();
    let band = average_chi2_band(runs.len(), 3, 0.95);
    let series = average_nees(&runs);
    let finite: Vec<f64> = series
        .iter()
        .map(|p| p.1)
        .filter(|v| v.is_finite())
        .collect();
    let inside = finite
        .iter()
        .filter(|v| **v >= band.0 && **v <= band.1)
        .count() as f64
        / finite.len().max(1) as f64;
    // Optimistic from the first of three consecutive rotations above the band.
    let first_optimistic_s = series
        .windows(3)
        .find(|w| w.iter().all(|p| p.1 > band.1))
        .and_then(|w| w.first().map(|p| p.0));
    let nis: Vec<(f64, usize)> = runs.iter().flat_map(|r| r.nis.iter().copied()).collect();
    let heading_sigma_deg = mean(
        runs.iter()
            .filter_map(|r| r.rotations.last().map(|x| x.sigma[2].to_degrees())),
    );
    Summary {
        label: label.to_string(),
        runs: runs.len(),
        band,
        inside,
        time_mean: mean(finite.iter().copied()),
        nis_dof: nis_per_dof(&nis),
        nis_inside: nis_fraction_inside(&nis, 0.95),
        first_optimistic_s,
        heading_sigma_deg,
        failed,
        beam_errors: runs.iter().map(|r| r.beam_errors.0).sum(),
        series,
    }
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let b = &opts.budget;
    let scene = shipped::load(SCENE)?;
    let mut specs = Vec::new();
    for k in 0..b.mc_runs {
        specs.push(shipped_spec(
            scene.clone(),
            1000 + k as u64,
            b.mc_seconds,
            Mode::Targets,
        )?);
    }
    let targets = summarise("targets (filter's noise model)", run_many(&specs, b.jobs));
    let mut specs = Vec::new();
    for k in 0..b.mc_pipeline_runs {
        specs.push(shipped_spec(
            scene.clone(),
            2000 + k as u64,
            b.mc_seconds,
            shipped_daemon()?,
        )?);
    }
    let pipeline = summarise(
        "daemon as shipped (spectra, detector, filter)",
        run_many(&specs, b.jobs),
    );

    let fig = "consistency_nees.svg";
    let mut series = vec![Series {
        name: format!("average NEES, {} runs, {}", targets.runs, targets.label),
        points: targets.series.clone(),
    }];
    if pipeline.runs > 0 {
        series.push(Series {
            name: format!("average NEES, {} runs, {}", pipeline.runs, pipeline.label),
            points: pipeline.series.clone(),
        });
    }
    line_chart(
        &opts.out_dir.join(fig),
        Labels {
            title: "pose NEES averaged over Monte Carlo runs (outdoor-field)",
            x: "time (s)",
            y: "average pose NEES (3 dof)",
        },
        &series,
        &[
            HLine {
                name: format!("95 % band, {} runs: {:.2}", targets.runs, targets.band.0),
                y: targets.band.0,
            },
            HLine {
                name: format!("upper {:.2}", targets.band.1),
                y: targets.band.1,
            },
        ],
    )?;

    let rows: Vec<Vec<String>> = [&targets, &pipeline]
        .iter()
        .map(|s| {
            vec![
                s.label.clone(),
                format!(
                    "{}{}",
                    s.runs,
                    if s.failed > 0 {
                        format!(" ({} failed)", s.failed)
                    } else {
                        String::new()
                    }
                ),
                format!("[{}, {}]", num(s.band.0, 2), num(s.band.1, 2)),
                num(s.time_mean, 2),
                pct(s.inside),
                num(s.nis_dof, 3),
                pct(s.nis_inside),
                s.first_optimistic_s
                    .map_or("never".into(), |t| format!("{t:.1} s")),
                num(s.heading_sigma_deg, 3),
                s.beam_errors.to_string(),
            ]
        })
        .collect();
    let mut body = String::new();
    let _ = writeln!(
        body,
        "Scene `{SCENE}` (the paper's outdoor field, 40 s drive then standstill), {} s per run, \
         every run from its own seed; the filter starts at the true pose. Rows: the filter fed \
         with every feature in the beam observed with exactly the noise it assumes (its own \
         consistency), and the daemon's own pipeline as shipped (the simulator's 8-bit \
         wire frames decoded, detector, grouper, filter; `config::Config::default()`). The \
         daemon does not expose per-update NIS, so its NIS columns are n/a.\n",
        b.mc_seconds
    );
    body.push_str(&table(
        &[
            "observations",
            "runs",
            "95 % band",
            "time-mean NEES",
            "rotations in band",
            "NIS/dof",
            "updates with NIS in own 95 % gate",
            "optimistic from",
            "final heading sigma (deg)",
            "refused beams",
        ],
        &rows,
    ));
    let _ = writeln!(body, "\n![average NEES]({fig})\n");
    let _ = writeln!(body, "{}", interpretation(&targets, &pipeline));
    Ok(Section {
        title: "Consistency: NEES and NIS".into(),
        body,
    })
}

fn interpretation(t: &Summary, p: &Summary) -> String {
    let mut s = String::new();
    let verdict = |x: &Summary| {
        if !x.time_mean.is_finite() {
            "no figure".to_string()
        } else if x.time_mean > x.band.1 {
            format!(
                "optimistic (time-mean {:.2} above {:.2})",
                x.time_mean, x.band.1
            )
        } else if x.time_mean < x.band.0 {
            format!(
                "conservative (time-mean {:.2} below {:.2})",
                x.time_mean, x.band.0
            )
        } else {
            format!("inside the band on average ({:.2})", x.time_mean)
        }
    };
    let _ = writeln!(
        s,
        "- With its own noise model the filter is {}.",
        verdict(t)
    );
    let _ = writeln!(s, "- Through detection it is {}.", verdict(p));
    for x in [t, p] {
        if let Some(at) = x.first_optimistic_s {
            let _ = writeln!(
                s,
                "- {}: the average NEES first stays above the band from {at:.1} s (heading \
                 standard deviation at the end {:.3} deg). The known mechanism in EKF-SLAM \
                 (Bailey et al. 2006; Huang and Dissanayake 2007) is linearisation about a \
                 wrong heading, which lets updates claim heading information they do not \
                 carry; the filter linearises each feature at its first estimate (FEJ, which \
                 removes the false information along the global rotation), and what remains \
                 is not isolated by this run.",
                x.label, x.heading_sigma_deg,
            );
        }
    }
    if p.nis_dof.is_finite() && p.nis_dof > 1.5 {
        let _ = writeln!(
            s,
            "- NIS/dof of {:.2} through detection: detected ranges, bearings and powers are \
             noisier than the filter's assumed standard deviations (grouped bearings, \
             quantised bins, peak interpolation), so the updates over-trust them.",
            p.nis_dof
        );
    }
    s
}
