//! Real data: the recorded Oxford Radar RobotCar scans (Navtech CTS350-X) with the data
//! set's ground-truth relative poses (`radar_odometry.csv`). Predicted against measured
//! spectra from one scan to the next, and the filter's pose against the ground truth.
//!
//! The scans are read with sim-sensor's polar PNG reader (`replay::png`), not streamed
//! through the simulator's server and radar-driver: the comparison needs every azimuth of
//! every scan, in order, with its own timestamp, which the reader gives directly.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use std::sync::Arc;

use bytes::Bytes;
use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::noise::{NoiseModel, RangeSpread};
use radar_model::power::PowerModel;
use radar_model::spectrum::SpectrumGeometry;
use sim_sensor::replay::png::read_polar_png;
use sim_sensor::replay::truth::{chain_pose_times, chain_poses, read_oxford_odometry};
use slam_node::daemon::replay::{OdometryErrors, RecordedTruth};
use slam_node::output::OutputEvent;
use slam_node::pipeline::Pipeline;

use crate::error::EvalError;
use crate::plot::{map_chart, FeatureSet, Labels, Series};
use crate::report::{num, pct, table, Options, Section};
use crate::scan::{Row, Scan};
use crate::sections::spectra::{cells, comparison_header, from_previous_scan};

/// Encoder counts per revolution of the CTS350-X.
pub const ENCODER_SIZE: f64 = 5600.0;
/// Bin size the data set states (m).
pub const BIN_SIZE_M: f64 = 0.0438;
/// The CTS350-X's horizontal beam width (rad).
pub const BEAM_WIDTH_RAD: f64 = 1.8 * std::f64::consts::PI / 180.0;
/// Wheelbase used to turn yaw rates into bicycle steering (m): the daemon's replay's.
pub const WHEELBASE_M: f64 = slam_node::daemon::replay::WHEELBASE_M;

/// The folder, relative to this crate: `../../shared/data/oxford-radar-robotcar`.
pub fn default_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/oxford-radar-robotcar")
}

/// One scan with its file timestamp (s).
#[derive(Debug, Clone)]
pub struct TimedScan {
    /// The scan's timestamp from its file name (s).
    pub time_s: f64,
    /// Its microseconds, as the odometry file writes them.
    pub time_us: i64,
    /// Its azimuths.
    pub scan: Scan,
}

/// Reads every `radar/*.png` in file-name order.
pub fn read_scans(dir: &Path) -> Result<Vec<TimedScan>, EvalError> {
    let radar = dir.join("radar");
    let io = |source| EvalError::Io {
        path: radar.clone(),
        source,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&radar)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    files.sort();
    let mut out = Vec::new();
    for path in files {
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        let time_us: i64 = stem.parse().map_err(|_| EvalError::Data {
            path: path.clone(),
            line: 0,
            reason: "file name is not a microsecond timestamp".into(),
        })?;
        let polar = read_polar_png(&path)?;
        let rows = polar
            .rows
            .iter()
            .filter(|r| r.valid)
            .map(|r| Row {
                timestamp_s: r.timestamp_us as f64 * 1e-6,
                bearing_rad: wrap_angle(
                    f64::from(r.encoder) * std::f64::consts::TAU / ENCODER_SIZE,
                ),
                measured_db: r.bins.iter().map(|&v| protocol::bin8_to_db(v)).collect(),
            })
            .collect();
        out.push(TimedScan {
            time_s: time_us as f64 * 1e-6,
            time_us,
            scan: Scan { rows },
        });
    }
    Ok(out)
}

/// Pose errors of the filter and of dead reckoning, per scan.
#[derive(Debug, Clone, Default)]
pub struct TrackResult {
    /// `(filter position error m, dead-reckoning position error m, filter heading error deg)`.
    pub per_scan: Vec<(f64, f64, f64)>,
    /// Features at the end.
    pub features: usize,
    /// Beams processed and refused.
    pub beams: (u64, u64),
    /// Targets offered.
    pub targets: u64,
    /// The filter's position at each scan's time.
    pub path: Vec<(f64, f64)>,
    /// The map at the end: each feature's position and position covariance.
    pub map: Vec<(f64, f64, [[f64; 2]; 2])>,
}

/// Runs the daemon's own pipeline (front end, odometry gate, filter) over the scans, with
/// the daemon's settings for recorded CTS350-X scans and odometry made from the ground
/// truth exactly as `slam-node --replay-dir` makes it: noise-free here, the speed scaled by
/// `speed_scale` and `yaw_rate_bias` (rad/s) added. `truth` holds at `truth_times_s` (s; the
/// middle of each scan's rotation for Oxford). Only the transport differs: the rows go in as
/// azimuths directly instead of over TCP. With `radar_odometry` the replay's default radar
/// odometry runs (the CTS350-X profile's).
pub fn track(
    scans: &[TimedScan],
    truth: &[Pose2],
    truth_times_s: &[f64],
    speed_scale: f64,
    yaw_rate_bias: f64,
    radar_odometry: bool,
) -> Result<TrackResult, EvalError> {
    let times: Vec<f64> = truth_times_s.to_vec();
    let recorded = RecordedTruth::from_poses(times.clone(), truth.to_vec())
        .ok_or_else(|| EvalError::Setting("the scans' ground truth is not usable".into()))?;
    let errors = OdometryErrors {
        seed: 1,
        sigma_speed_mps: 0.0,
        sigma_yaw_rate_rps: 0.0,
        speed_scale,
        yaw_rate_bias_rps: yaw_rate_bias,
    };
    let samples = recorded.odometry(&errors);
    let dead_reckoning = recorded.dead_reckoning_errors(&samples);
    let bins = scans
        .first()
        .and_then(|s| s.scan.rows.first())
        .map_or(0, |r| r.measured_db.len());
    // The shipped configuration for a CTS350-X, the recorded odometry's bicycle, the
    // radar's full range: what `slam-node --replay-dir` derives.
    let facts = slam_node::pipeline::SourceFacts {
        motion: Some(radar_model::motion::MotionModel::Bicycle {
            wheelbase_m: WHEELBASE_M,
        }),
        no_radar_odometry: !radar_odometry,
        max_range_m: Some(bins as f64 * BIN_SIZE_M),
        ..Default::default()
    };
    let settings =
        slam_node::pipeline::PipelineSettings::for_profile(&radar_model::profile::CTS350X, &facts)
            .map_err(|e| EvalError::Setting(format!("CTS350-X settings: {e}")))?;
    let cts = Geometry::cts350x();
    let geometry = Arc::new(Geometry {
        azimuth_samples: u16::try_from(scans.first().map_or(400, |s| s.scan.rows.len()))
            .unwrap_or(cts.azimuth_samples),
        range_in_bins: u16::try_from(bins).unwrap_or(u16::MAX),
        bin_size_m: BIN_SIZE_M,
        ..cts
    });
    let mut pipeline = Pipeline::new(settings, None, Some(Box::new(recorded.clone())))
        .map_err(|e| EvalError::Setting(format!("pipeline: {e}")))?;
    let mut result = TrackResult::default();
    let mut events = Vec::new();
    let mut numbering = radar_driver::RotationAssembler::new();
    numbering.set_counting_only(true);
    let mut next_odo = 0;
    let mut next_scan = 0;
    let mut record = |pipeline: &Pipeline, k: usize| {
        let (Some(t), Some(&time)) = (truth.get(k), times.get(k)) else {
            return;
        };
        if let Some(e) = pipeline.predicted_pose(time) {
            result.path.push((e.x, e.y));
            result.per_scan.push((
                (e.x - t.x).hypot(e.y - t.y),
                dead_reckoning.get(k).copied().unwrap_or(f64::NAN),
                wrap_angle(e.theta - t.theta).to_degrees(),
            ));
        }
    };
    let rows = scans.iter().flat_map(|s| s.scan.rows.iter());
    for (sweep, row) in rows.enumerate() {
        while times.get(next_scan).is_some_and(|&t| t <= row.timestamp_s) {
            record(&pipeline, next_scan);
            next_scan += 1;
        }
        while let Some(o) = samples
            .get(next_odo)
            .filter(|o| o.timestamp_s <= row.timestamp_s)
        {
            pipeline.push_odometry(*o);
            next_odo += 1;
        }
        let bearing = row.bearing_rad.rem_euclid(std::f64::consts::TAU);
        let encoder = (bearing * ENCODER_SIZE / std::f64::consts::TAU).round() as u16;
        let mut azimuth = Azimuth {
            encoder: encoder % ENCODER_SIZE as u16,
            angle_rad: bearing,
            timestamp_s: row.timestamp_s,
            sweep_counter: (sweep % 65_536) as u16,
            width: BinWidth::Eight,
            bins: Bytes::from(
                row.measured_db
                    .iter()
                    .map(|&db| protocol::db_to_bin8(db))
                    .collect::<Vec<u8>>(),
            ),
            geometry: Arc::clone(&geometry),
            rotation: 0,
        };
        // Rotations numbered by the driver's own numbering.
        numbering.number(&mut azimuth);
        pipeline
            .process_azimuth(&azimuth, &mut events)
            .map_err(|e| EvalError::Setting(format!("pipeline: {e}")))?;
        events.clear();
    }
    while next_scan < times.len() {
        record(&pipeline, next_scan);
        next_scan += 1;
    }
    let summary = pipeline.finish(&mut events);
    result.features = pipeline.ekf().feature_count();
    if let Some(map) = events.iter().rev().find_map(|e| match e {
        OutputEvent::Map(m) => Some(m),
        _ => None,
    }) {
        result.map = map
            .features
            .iter()
            .map(|f| {
                let c = f.covariance;
                (f.x_m, f.y_m, [[c[0][0], c[0][1]], [c[1][0], c[1][1]]])
            })
            .collect();
    }
    result.beams = (
        summary.beams,
        summary.filter_errors + summary.refused.no_odometry + summary.refused.stale_odometry,
    );
    result.targets = summary.observations;
    Ok(result)
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let title = "Real data: Oxford Radar RobotCar scans".to_string();
    let Some(dir) = opts.oxford_dir.clone().filter(|d| d.join("radar").is_dir()) else {
        return Ok(Section {
            title,
            body: format!(
                "Skipped: the Oxford scans were not found (looked for {}). Nothing in this \
                 section was measured.\n",
                opts.oxford_dir
                    .as_ref()
                    .map_or("no folder given".into(), |d| d.display().to_string())
            ),
        });
    };
    let mut scans = read_scans(&dir)?;
    scans.truncate(opts.budget.oxford_scans.max(2));
    // Ground truth with sim-sensor's reader (the one `slam-node --replay-dir` uses).
    let csv = dir.join("radar_odometry.csv");
    let rows = read_oxford_odometry(&csv)?;
    let times_us: Vec<i64> = scans.iter().map(|s| s.time_us).collect();
    let truth = chain_poses(&csv, &rows, &times_us)?;
    let truth_times_s: Vec<f64> = chain_pose_times(&csv, &rows, &times_us)?
        .iter()
        .map(|&us| us as f64 * 1e-6)
        .collect();
    // Relative pose of scan k+1 in scan k's frame (chain_poses found every one).
    let rel: Vec<Pose2> = times_us
        .windows(2)
        .filter_map(|w| {
            rows.iter()
                .find(|r| r.source_us == w[1] && r.destination_us == w[0])
                .map(|r| r.pose)
        })
        .collect();
    let bins = scans
        .first()
        .and_then(|s| s.scan.rows.first())
        .map_or(0, |r| r.measured_db.len());
    let geometry = SpectrumGeometry {
        bins,
        bin_size_m: BIN_SIZE_M,
        range_offset_m: 0.0,
    };
    let noise = NoiseModel {
        range: RangeSpread {
            resolution_fwhm_m: BIN_SIZE_M,
            ..RangeSpread::default()
        },
        ..NoiseModel::default()
    };
    let power = PowerModel {
        range_resolution_m: BIN_SIZE_M,
        ..PowerModel::default()
    };
    let scan_list: Vec<Scan> = scans.iter().map(|s| s.scan.clone()).collect();
    let mut rows = Vec::new();
    for (variant, floor, cmp, clamped) in
        from_previous_scan(&scan_list, &rel, &geometry, &noise, &power, BEAM_WIDTH_RAD)?
    {
        let mut row = vec![variant.name(), floor.to_string()];
        row.extend(cells(&cmp));
        row.push(pct(clamped));
        rows.push(row);
    }
    let mut body = String::new();
    let first_row_t = scans
        .first()
        .and_then(|s| s.scan.rows.first())
        .map_or(f64::NAN, |r| r.timestamp_s);
    let _ = writeln!(
        body,
        "{} scans of {} azimuths x {} bins ({} m bins) read from `{}` with sim-sensor's \
         polar PNG reader (not streamed through the simulator and radar-driver: every azimuth \
         with its own timestamp is needed in order, which the reader gives directly). Relative \
         poses from `radar_odometry.csv`, converted from the data set's x-forward, y-right \
         frame to ours (y left, heading counter-clockwise). The first scan's first azimuth is \
         {:.3} s from its file timestamp; each pose holds at its row's own time          (`source_timestamp`), the middle of the scan's rotation, {:.3} s after the first          scan's file timestamp, as the data set's SDK interpolates them.\n",
        scans.len(),
        scans.first().map_or(0, |s| s.scan.rows.len()),
        bins,
        BIN_SIZE_M,
        dir.display(),
        first_row_t - scans.first().map_or(f64::NAN, |s| s.time_s),
        truth_times_s.first().copied().unwrap_or(f64::NAN)
            - scans.first().map_or(f64::NAN, |s| s.time_s)
    );
    let _ = writeln!(
        body,
        "**Predicted against measured, scan k to scan k+1** (detection by the shipped \
         detector, or, when that is TPP, which needs several scans, by OS-CFAR with the \
         shipped window and threshold; rho fitted by \
         eq. 13 with alpha = {}, L = 0, moved by the ground-truth relative pose; the floor from \
         radar-model's target-absent model, which describes the paper's unit, or from the \
         previous scan's per-bin median):\n",
        crate::scan::ASSUMED_ALPHA
    );
    body.push_str(&table(
        &comparison_header(&["predictor", "floor"], &["rho clamped"]),
        &rows,
    ));
    let _ = writeln!(
        body,
        "\n**Filter pose against the ground truth**: the daemon's own pipeline (front end, \
         odometry gate, filter) with the daemon's settings for recorded CTS350-X scans and \
         odometry made from the ground truth at 20 Hz (bicycle model, {WHEELBASE_M} m \
         wheelbase), exactly as `slam-node --replay-dir` runs them, only without the TCP \
         transport; dead reckoning integrates the same odometry without the radar:\n"
    );
    let mut track_rows = Vec::new();
    let mut paths = vec![Series {
        name: "ground truth".into(),
        points: truth.iter().map(|p| (p.x, p.y)).collect(),
    }];
    let mut sets = Vec::new();
    let cases = [
        ("exact, no radar odometry", 1.0, 0.0, false),
        (
            "speed +5 %, yaw rate +0.02 rad/s, no radar odometry",
            1.05,
            0.02,
            false,
        ),
        ("exact, radar odometry", 1.0, 0.0, true),
        (
            "speed +5 %, yaw rate +0.02 rad/s, radar odometry",
            1.05,
            0.02,
            true,
        ),
    ];
    // The two runs are independent: one thread each.
    let results: Vec<Result<TrackResult, EvalError>> = if opts.budget.skip_heavy {
        Vec::new()
    } else {
        std::thread::scope(|scope| {
            let handles: Vec<_> = cases
                .iter()
                .map(|&(_, scale, bias, radar)| {
                    let (scans, truth, truth_times_s) = (&scans, &truth, &truth_times_s);
                    scope.spawn(move || track(scans, truth, truth_times_s, scale, bias, radar))
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join().unwrap_or_else(|_| {
                        Err(EvalError::Setting("tracking thread panicked".into()))
                    })
                })
                .collect()
        })
    };
    if results.is_empty() {
        let _ = writeln!(body, "(Skipped in this budget: the filter over the real scans takes minutes in a debug build.)\n");
    }
    for ((name, _, _, _), r) in cases.iter().zip(results) {
        let r = r?;
        let last = r
            .per_scan
            .last()
            .copied()
            .unwrap_or((f64::NAN, f64::NAN, f64::NAN));
        let filt: Vec<String> = r.per_scan.iter().map(|p| format!("{:.2}", p.0)).collect();
        paths.push(Series {
            name: format!("filter, odometry {name}"),
            points: r.path.clone(),
        });
        sets.push(FeatureSet {
            name: format!("{} features, odometry {name}", r.map.len()),
            features: r.map.clone(),
        });
        track_rows.push(vec![
            name.to_string(),
            filt.join(" "),
            num(last.0, 3),
            num(last.1, 3),
            num(last.2, 3),
            r.features.to_string(),
            format!("{} ({} refused)", r.beams.0, r.beams.1),
            r.targets.to_string(),
        ]);
    }
    body.push_str(&table(
        &[
            "odometry",
            "filter position error per scan (m)",
            "final filter error (m)",
            "final dead-reckoning error (m)",
            "final heading error (deg)",
            "features",
            "beams",
            "targets",
        ],
        &track_rows,
    ));
    if !sets.is_empty() {
        let fig = "oxford_map.svg";
        map_chart(
            &opts.out_dir.join(fig),
            Labels {
                title: "real scans: the filter's path and map (3-sigma ellipses)",
                x: "x (m), the first scan's frame",
                y: "y (m)",
            },
            &paths,
            &sets,
        )?;
        let _ = writeln!(
            body,
            "\n![the filter's path and map on the real scans]({fig})\n\nThe map: the \
             features in the state at the end of each run, with their 3-sigma position \
             ellipses, over the ground-truth path and the filter's position at each scan's \
             time (`{}`). The scans' Cartesian image is made by `cargo run --release -p \
             sim-sensor --example realism` and not committed (it is the licensed data \
             itself).",
            opts.command
        );
    }
    let _ = writeln!(
        body,
        "\nEight scans span {:.2} s and {:.1} m: far too short to show loop-scale drift; \
         these figures test that real spectra go through the pipeline and what the radar \
         updates do to a short odometry track.",
        scans.last().map_or(0.0, |s| s.time_s) - scans.first().map_or(0.0, |s| s.time_s),
        truth.last().map_or(0.0, |p| p.x.hypot(p.y))
    );
    Ok(Section { title, body })
}
