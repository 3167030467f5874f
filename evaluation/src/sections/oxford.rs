//! Real data: the recorded Oxford Radar RobotCar scans (Navtech CTS350-X) with the data
//! set's ground-truth relative poses (`radar_odometry.csv`). Predicted against measured
//! spectra from one scan to the next, and the filter's pose against the ground truth.
//!
//! The scans are read with sim-sensor's polar PNG reader (`replay::png`), not streamed
//! through the simulator's server and radar-driver: the comparison needs every azimuth of
//! every scan, in order, with its own timestamp, which the reader gives directly.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Matrix3;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::{ControlInput, MotionModel};
use radar_model::noise::{NoiseModel, RangeSpread};
use radar_model::power::PowerModel;
use radar_model::spectrum::SpectrumGeometry;
use sim_sensor::replay::png::read_polar_png;
use slam_filter::{BeamObservation, Ekf, FilterSettings, OdometrySample, RadarBeamModel};
use slam_node::detect::{BeamDetector, FloorProfile, RangeAxis};

use crate::error::EvalError;
use crate::report::{num, pct, table, Options, Section};
use crate::scan::{Row, Scan, Variant};
use crate::sections::spectra::{cells, comparison_header, from_previous_scan};
use crate::source::{grouping_for, AzimuthBeam, BeamAssembler};

/// Encoder counts per revolution of the CTS350-X.
pub const ENCODER_SIZE: f64 = 5600.0;
/// Bin size the data set states (m).
pub const BIN_SIZE_M: f64 = 0.0438;
/// The CTS350-X's horizontal beam width (rad).
pub const BEAM_WIDTH_RAD: f64 = 1.8 * std::f64::consts::PI / 180.0;
/// Wheelbase used to turn yaw rates into bicycle steering (m).
pub const WHEELBASE_M: f64 = 2.7;
/// Largest odometry file accepted (bytes).
const MAX_CSV_BYTES: u64 = 1 << 24;

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
                measured_db: r.bins.iter().map(|&v| f64::from(v) * 0.5).collect(),
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

/// One ground-truth relative pose: the source scan in the destination scan's frame,
/// converted from the data set's x-forward, y-right, yaw-clockwise to our x-forward,
/// y-left, counter-clockwise heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativePose {
    /// Later scan (µs).
    pub source_us: i64,
    /// Earlier scan (µs).
    pub destination_us: i64,
    /// The source's pose in the destination's frame.
    pub pose: Pose2,
}

/// Parses `radar_odometry.csv`.
pub fn read_odometry(path: &Path) -> Result<Vec<RelativePose>, EvalError> {
    let io = |source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    if len > MAX_CSV_BYTES {
        return Err(EvalError::Data {
            path: path.into(),
            line: 0,
            reason: format!("{len} bytes is too large"),
        });
    }
    let text = std::fs::read_to_string(path).map_err(io)?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |reason: String| EvalError::Data {
            path: path.into(),
            line: i + 1,
            reason,
        };
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 10 {
            return Err(bad(format!("{} fields, expected 10", f.len())));
        }
        let num = |k: usize| -> Result<f64, EvalError> {
            f.get(k)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("field {} is not a finite number", k + 1)))
        };
        let int = |k: usize| -> Result<i64, EvalError> {
            f.get(k)
                .and_then(|s| s.parse::<i64>().ok())
                .ok_or_else(|| bad(format!("field {} is not an integer", k + 1)))
        };
        out.push(RelativePose {
            source_us: int(8)?,
            destination_us: int(9)?,
            pose: Pose2::new(num(2)?, -num(3)?, -num(7)?),
        });
    }
    Ok(out)
}

/// `a` followed by `b` (b expressed in a's frame).
pub fn compose(a: &Pose2, b: &Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    Pose2::new(
        a.x + c * b.x - s * b.y,
        a.y + s * b.x + c * b.y,
        wrap_angle(a.theta + b.theta),
    )
}

/// Bicycle controls that move from `a` to `b` (b in a's frame) in `dt_s`.
fn controls(rel: &Pose2, dt_s: f64) -> ControlInput {
    let v = rel.x.hypot(rel.y) / dt_s.max(1e-3);
    let yaw_rate = rel.theta / dt_s.max(1e-3);
    let steer = if v > 0.1 {
        (yaw_rate * WHEELBASE_M / v).atan()
    } else {
        0.0
    };
    ControlInput::new(v, steer)
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
}

/// Runs the filter over the scans with odometry derived from the ground truth, scaled by
/// `speed_scale` and with `yaw_rate_bias` (rad/s) added.
pub fn track(
    scans: &[TimedScan],
    truth: &[Pose2],
    rel: &[Pose2],
    speed_scale: f64,
    yaw_rate_bias: f64,
    slope_db_per_decade: f64,
) -> Result<TrackResult, EvalError> {
    let bins = scans
        .first()
        .and_then(|s| s.scan.rows.first())
        .map_or(0, |r| r.measured_db.len());
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: BIN_SIZE_M,
    };
    let shipped = crate::daemon::shipped_settings()?;
    let comp = Variant {
        form: shipped.power.form,
        slope_db_per_decade,
    }
    .compensation();
    let gain: Vec<f64> = (0..bins)
        .map(|b| comp.gain_db(axis.range_m(b as f64)))
        .collect();
    let azimuths = scans.first().map_or(400, |s| s.scan.rows.len());
    let mut detector = BeamDetector::new(shipped.detector, azimuths);
    let geometry = SpectrumGeometry {
        bins,
        bin_size_m: BIN_SIZE_M,
        range_offset_m: 0.0,
    };
    let floor = FloorProfile::new(
        &radar_model::spectrum::SpectrumModel::new(geometry, &comp, shipped.noise)?,
        &shipped.noise.absent,
        shipped.detector.floor_tail_pfa,
    );
    let mut assembler =
        BeamAssembler::new(grouping_for(azimuths as u64, BEAM_WIDTH_RAD, BIN_SIZE_M, 1));
    let motion = MotionModel::Bicycle {
        wheelbase_m: WHEELBASE_M,
    };
    let settings = FilterSettings {
        max_range_m: shipped.filter.max_range_m.min(bins as f64 * BIN_SIZE_M),
        beam_half_width_rad: 0.5 * BEAM_WIDTH_RAD,
        ..shipped.filter.clone()
    };
    let first_t = scans
        .first()
        .and_then(|s| s.scan.rows.first())
        .map_or(0.0, |r| r.timestamp_s)
        .min(scans.first().map_or(0.0, |s| s.time_s));
    let power = PowerModel {
        range_resolution_m: BIN_SIZE_M,
        ..shipped.power
    };
    let p0 = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-6, 1e-6, 1e-8));
    let mut ekf = Ekf::new(
        settings,
        Pose2::default(),
        p0,
        first_t,
        motion,
        RadarBeamModel { power },
    )?;
    // Odometry: one sample per scan interval, at the interval's start (the first at the
    // first azimuth's time); held until the next.
    let mut odometry = Vec::new();
    for (k, r) in rel.iter().enumerate() {
        let (Some(a), Some(b)) = (scans.get(k), scans.get(k + 1)) else {
            continue;
        };
        let dt = b.time_s - a.time_s;
        let c = controls(r, dt);
        let v = c.speed_mps * speed_scale;
        let yaw = if c.speed_mps > 0.1 {
            c.speed_mps * c.steer_rad.tan() / WHEELBASE_M
        } else {
            0.0
        } + yaw_rate_bias;
        let steer = if v > 0.1 {
            (yaw * WHEELBASE_M / v).atan()
        } else {
            0.0
        };
        let t = if k == 0 { first_t } else { a.time_s };
        odometry.push(OdometrySample {
            timestamp_s: t,
            speed_mps: v,
            steer_rad: steer,
        });
    }
    let mut next_odo = 0usize;
    let mut result = TrackResult::default();
    let mut dr = Pose2::default();
    let mut dr_t = first_t;
    let mut next_scan = 0usize;
    let mut found = Vec::new();
    let mut finals: Vec<AzimuthBeam> = Vec::new();
    let mut index = 0u64;
    let total_rows: usize = scans.iter().map(|s| s.scan.rows.len()).sum();
    let mut fed = 0usize;
    for s in scans {
        for (slot, row) in s.scan.rows.iter().enumerate() {
            found.clear();
            detector.detect(
                slot,
                &row.measured_db,
                &gain,
                floor.floor(row.measured_db.len()),
                &axis,
                &mut found,
            );
            assembler.push(
                AzimuthBeam {
                    index,
                    timestamp_s: row.timestamp_s,
                    bearing_rad: row.bearing_rad,
                    truth: Pose2::default(),
                    targets: Vec::new(),
                },
                &found,
            );
            index += 1;
            fed += 1;
            finals.clear();
            assembler.take_final(fed == total_rows, &mut finals);
            for beam in finals.drain(..) {
                // Record the pose at each scan time passed, then feed odometry up to the beam.
                while let Some(sc) = scans.get(next_scan) {
                    if sc.time_s > beam.timestamp_s {
                        break;
                    }
                    feed(&mut ekf, &odometry, &mut next_odo, sc.time_s);
                    if ekf.predict_to(sc.time_s).is_ok() {
                        // Dead reckoning with the same odometry.
                        dr = dead_reckon(&motion, &odometry, dr, dr_t, sc.time_s);
                        dr_t = sc.time_s;
                        if let Some(t) = truth.get(next_scan) {
                            let e = ekf.pose();
                            result.per_scan.push((
                                (e.x - t.x).hypot(e.y - t.y),
                                (dr.x - t.x).hypot(dr.y - t.y),
                                wrap_angle(e.theta - t.theta).to_degrees(),
                            ));
                        }
                    }
                    next_scan += 1;
                }
                feed(&mut ekf, &odometry, &mut next_odo, beam.timestamp_s);
                if beam.timestamp_s < ekf.state().time_s() {
                    continue;
                }
                result.targets += beam.targets.len() as u64;
                result.beams.0 += 1;
                let obs = BeamObservation {
                    timestamp_s: beam.timestamp_s,
                    bearing_rad: beam.bearing_rad,
                    targets: beam.targets.iter().map(|t| t.target).collect(),
                };
                if ekf.process_beam(&obs).is_err() {
                    result.beams.1 += 1;
                }
            }
        }
    }
    result.features = ekf.feature_count();
    Ok(result)
}

fn feed<M, O>(ekf: &mut Ekf<M, O>, odometry: &[OdometrySample], next: &mut usize, until_s: f64)
where
    M: slam_filter::ProcessModel,
    O: slam_filter::BeamObservationModel,
{
    while let Some(o) = odometry.get(*next) {
        if o.timestamp_s > until_s {
            break;
        }
        let _ = ekf.apply_odometry(*o);
        *next += 1;
    }
}

/// Integrates the held odometry from `from_s` to `to_s` (10 ms steps).
fn dead_reckon(
    motion: &MotionModel,
    odometry: &[OdometrySample],
    mut pose: Pose2,
    from_s: f64,
    to_s: f64,
) -> Pose2 {
    let mut t = from_s;
    while t < to_s {
        let dt = (to_s - t).min(0.01);
        let held = odometry
            .iter()
            .rev()
            .find(|o| o.timestamp_s <= t)
            .or(odometry.first());
        if let Some(o) = held {
            if let Ok(p) = motion.predict(&pose, &ControlInput::new(o.speed_mps, o.steer_rad), dt) {
                pose = p;
            }
        }
        t += dt;
    }
    pose
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
    let odometry = read_odometry(&dir.join("radar_odometry.csv"))?;
    // Relative pose of scan k+1 in scan k's frame, and the accumulated truth.
    let mut rel = Vec::new();
    for w in scans.windows(2) {
        let found = odometry
            .iter()
            .find(|o| o.source_us == w[1].time_us && o.destination_us == w[0].time_us)
            .ok_or_else(|| EvalError::Data {
                path: dir.join("radar_odometry.csv"),
                line: 0,
                reason: format!(
                    "no relative pose from scan {} to {}",
                    w[0].time_us, w[1].time_us
                ),
            })?;
        rel.push(found.pose);
    }
    let mut truth = vec![Pose2::default()];
    for r in &rel {
        let last = truth.last().copied().unwrap_or_default();
        truth.push(compose(&last, r));
    }
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
         {:.3} s from its file timestamp; poses are taken at the file timestamps.\n",
        scans.len(),
        scans.first().map_or(0, |s| s.scan.rows.len()),
        bins,
        BIN_SIZE_M,
        dir.display(),
        first_row_t - scans.first().map_or(f64::NAN, |s| s.time_s)
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
        "\n**Filter pose against the ground truth** (shipped detector under 60 dB/decade, \
         shipped filter settings, bicycle model with a {WHEELBASE_M} m wheelbase, odometry \
         derived from the ground truth: one speed and steering per scan interval; \
         dead reckoning integrates the same odometry without the radar):\n"
    );
    let mut track_rows = Vec::new();
    let cases = [
        ("exact", 1.0, 0.0),
        ("speed +5 %, yaw rate +0.02 rad/s", 1.05, 0.02),
    ];
    // The two runs are independent: one thread each.
    let results: Vec<Result<TrackResult, EvalError>> = if opts.budget.skip_heavy {
        Vec::new()
    } else {
        std::thread::scope(|scope| {
            let handles: Vec<_> = cases
                .iter()
                .map(|&(_, scale, bias)| {
                    let (scans, truth, rel) = (&scans, &truth, &rel);
                    scope.spawn(move || track(scans, truth, rel, scale, bias, 60.0))
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
    for ((name, _, _), r) in cases.iter().zip(results) {
        let r = r?;
        let last = r
            .per_scan
            .last()
            .copied()
            .unwrap_or((f64::NAN, f64::NAN, f64::NAN));
        let filt: Vec<String> = r.per_scan.iter().map(|p| format!("{:.2}", p.0)).collect();
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
