//! Real recorded scans through the real path (the `sim` feature): the simulator replays a
//! folder of polar scans (Oxford Radar RobotCar, Boreas or RADIATE, see
//! `sim_sensor::replay::format`) over TCP on 127.0.0.1, the radar driver reads them, the
//! daemon maps; its odometry is made from the data set's ground truth with a stated, seeded
//! noise and bias, and its pose is scored against the ground truth and against dead
//! reckoning with the same odometry.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Duration;

use radar_driver::odometry::OdometryRecord;
use radar_driver::{OdometryError, OdometryPoll, OdometrySource};
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::MotionModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use sim_sensor::replay::boreas::{boreas_poses, read_radar_poses};
use sim_sensor::replay::radiate::radiate_poses;
use sim_sensor::replay::truth::{
    chain_pose_times, chain_poses, compose, read_oxford_odometry, TruthError,
};
use sim_sensor::replay::{ReplayFormat, ScanSet};
use slam_filter::{OdometrySample, ProcessModel};

pub use super::figures::{OdometryErrors, ReplayFigures};
use crate::pipeline::{TrueFeature, TruthOracle};

/// Odometry samples a second made from the ground truth.
pub const ODOMETRY_HZ: f64 = 20.0;
/// Wheelbase the yaw rate is turned into bicycle steering with (m).
pub const WHEELBASE_M: f64 = 2.7;
/// Why a replay could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The scans could not be listed or read (unknown layout, no scans, bad names, times
    /// out of order, a first scan of the wrong shape).
    #[error(transparent)]
    Scans(#[from] sim_sensor::ReplayError),
    /// Fewer than two scans.
    #[error("{path}: {count} scans; a replay needs at least two")]
    TooFew {
        /// The folder.
        path: PathBuf,
        /// How many.
        count: usize,
    },
    /// The ground truth could not be read.
    #[error("ground truth")]
    Truth(#[from] TruthError),
    /// The odometry could not be written (`--write-odometry`).
    #[error("writing the odometry to {path}")]
    WriteOdometry {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Writes `samples` in the odometry stream's format (docs/contracts.md): the header line,
/// then one `timestamp_s speed_mps steer_rad` line each, every number written so that it
/// reads back to the same `f64`.
pub fn write_odometry(path: &Path, samples: &[OdometrySample]) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "# odometry v1 timestamp_s speed_mps steer_rad")?;
    for s in samples {
        writeln!(out, "{} {} {}", s.timestamp_s, s.speed_mps, s.steer_rad)?;
    }
    out.flush()
}

/// The ground truth of a recorded drive: the scans' times and poses (the first scan's frame),
/// interpolated linearly between scans and extrapolated one scan interval beyond the ends.
#[derive(Debug, Clone)]
pub struct RecordedTruth {
    times_s: Vec<f64>,
    poses: Vec<Pose2>,
}

impl RecordedTruth {
    /// Reads an Oxford folder's scan names (`radar/<µs>.png`) and `radar_odometry.csv`.
    pub fn read_oxford(dir: &Path) -> Result<Self, ReplayError> {
        Self::read(&ScanSet::open(dir, Some(ReplayFormat::Oxford))?)
    }

    /// The ground truth of `scans`, one pose per scan in the first scan's frame. Oxford:
    /// `radar_odometry.csv` chained; Boreas: `applanix/radar_poses.csv`, the row of each
    /// scan's time; RADIATE: GPS fixes and course over ground from `GPS_IMU_Twist`,
    /// interpolated to the scan times.
    pub fn read(scans: &ScanSet) -> Result<Self, ReplayError> {
        let times_us = scans.times_us();
        if times_us.len() < 2 {
            return Err(ReplayError::TooFew {
                path: scans.scan_dir.clone(),
                count: times_us.len(),
            });
        }
        // Oxford's radar odometry places each scan's pose at the middle of its rotation
        // (the row's own times), not at the scan's name (its first azimuth).
        let (pose_times_us, poses) = match scans.format {
            ReplayFormat::Oxford => {
                let csv = scans.dir.join("radar_odometry.csv");
                let rows = read_oxford_odometry(&csv)?;
                (
                    chain_pose_times(&csv, &rows, &times_us)?,
                    chain_poses(&csv, &rows, &times_us)?,
                )
            }
            ReplayFormat::Boreas => {
                let csv = scans.dir.join("applanix").join("radar_poses.csv");
                let rows = read_radar_poses(&csv)?;
                (times_us.clone(), boreas_poses(&csv, &rows, &times_us)?)
            }
            ReplayFormat::Radiate => (times_us.clone(), radiate_poses(&scans.dir, &times_us)?),
        };
        Ok(Self {
            times_s: pose_times_us.iter().map(|&us| us as f64 * 1e-6).collect(),
            poses,
        })
    }

    /// Ground truth from scan times (s, increasing) and poses; `None` unless there are at
    /// least two scans, as many poses as times, and the times increase.
    pub fn from_poses(times_s: Vec<f64>, poses: Vec<Pose2>) -> Option<Self> {
        let ok = times_s.len() >= 2
            && times_s.len() == poses.len()
            && times_s.windows(2).all(|w| w[1] > w[0]);
        ok.then_some(Self { times_s, poses })
    }

    /// Poses at the scan times (the first scan's frame).
    pub fn poses(&self) -> &[Pose2] {
        &self.poses
    }

    /// Scan times (s).
    pub fn times_s(&self) -> &[f64] {
        &self.times_s
    }

    /// Distance driven (m).
    pub fn distance_m(&self) -> f64 {
        self.poses
            .windows(2)
            .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
            .sum()
    }

    /// Speed and yaw rate over segment `k` (between scans k and k + 1).
    fn segment_motion(&self, k: usize) -> Option<(f64, f64)> {
        let (a, b) = (self.poses.get(k)?, self.poses.get(k + 1)?);
        let dt = self.times_s.get(k + 1)? - self.times_s.get(k)?;
        let inv = Pose2::new(
            -(a.theta.cos() * a.x + a.theta.sin() * a.y),
            a.theta.sin() * a.x - a.theta.cos() * a.y,
            -a.theta,
        );
        let rel = compose(&inv, b);
        Some((rel.x.hypot(rel.y) / dt, wrap_angle(rel.theta) / dt))
    }

    /// Odometry made from the ground truth with `errors`: samples at [`ODOMETRY_HZ`] from
    /// half a scan before the first scan to the last, bicycle steering from the yaw rate.
    ///
    /// At most a day and a half of samples (2,592,001 at 20 Hz, 62 MB): the span of the
    /// ground truth the readers accept is at most
    /// [`sim_sensor::replay::truth::MAX_SPAN_US`] (a day, refused by name beyond), and the
    /// odometry starts at most half a span before it, so a truth read from a recording is
    /// never cut short. Truth made otherwise ([`RecordedTruth::from_poses`]) that spans
    /// longer gets that many samples from its start, with a WARN; truth whose times are not
    /// finite gets none. Nothing is allocated from the span before it is bounded.
    pub fn odometry(&self, errors: &OdometryErrors) -> Vec<OdometrySample> {
        const MAX_SPAN_S: f64 = sim_sensor::replay::truth::MAX_SPAN_US as f64 * 1e-6;
        // A day and a half of samples (the span's limit, and half of it before the first
        // scan), plus the one at the start.
        let max_samples = (MAX_SPAN_S * 1.5 * ODOMETRY_HZ) as usize + 1;
        let mut rng = ChaCha8Rng::seed_from_u64(errors.seed);
        let speed_noise = Normal::new(0.0, errors.sigma_speed_mps.max(0.0)).ok();
        let yaw_noise = Normal::new(0.0, errors.sigma_yaw_rate_rps.max(0.0)).ok();
        let n = self.times_s.len();
        let (Some(&first), Some(&last)) = (self.times_s.first(), self.times_s.last()) else {
            return Vec::new();
        };
        let start = first - 0.5 * (self.times_s.get(1).copied().unwrap_or(first) - first);
        let span_s = last - start;
        if !start.is_finite() || !span_s.is_finite() {
            tracing::warn!(
                first_s = first,
                last_s = last,
                "the ground truth's times are not finite: no odometry made from it"
            );
            return Vec::new();
        }
        // Samples after the first: at least 0, at most `max_samples - 1` (a float past
        // usize's range saturates before the bound is applied).
        let wanted = (span_s * ODOMETRY_HZ).floor().max(0.0);
        let steps = (wanted as usize).min(max_samples - 1);
        if wanted > steps as f64 {
            tracing::warn!(
                span_s,
                samples = max_samples,
                "the ground truth spans longer than a day and a half: the odometry stops after its first {} s",
                (max_samples - 1) as f64 / ODOMETRY_HZ
            );
        }
        let mut out = Vec::with_capacity(steps + 1);
        for i in 0..=steps {
            let t = start + i as f64 / ODOMETRY_HZ;
            let k = self
                .times_s
                .partition_point(|&s| s <= t)
                .saturating_sub(1)
                .min(n.saturating_sub(2));
            let (v, w) = self.segment_motion(k).unwrap_or((0.0, 0.0));
            let v = v * errors.speed_scale + speed_noise.map_or(0.0, |d| d.sample(&mut rng));
            let w = w + errors.yaw_rate_bias_rps + yaw_noise.map_or(0.0, |d| d.sample(&mut rng));
            let steer = if v.abs() > 0.1 {
                (w * WHEELBASE_M / v).atan()
            } else {
                0.0
            };
            out.push(OdometrySample {
                timestamp_s: t,
                speed_mps: v,
                steer_rad: steer,
            });
        }
        out
    }

    /// Dead reckoning with `samples` from the true pose at the first sample: the position
    /// error against the truth at every scan time (m).
    pub fn dead_reckoning_errors(&self, samples: &[OdometrySample]) -> Vec<f64> {
        let motion = MotionModel::Bicycle {
            wheelbase_m: WHEELBASE_M,
        };
        let Some(first) = samples.first() else {
            return Vec::new();
        };
        let Some(mut pose) = self.pose_at(first.timestamp_s) else {
            return Vec::new();
        };
        let mut t = first.timestamp_s;
        let mut held = *first;
        let mut next = 1;
        let mut errors = Vec::new();
        for (&scan_t, truth) in self.times_s.iter().zip(&self.poses) {
            if scan_t < t {
                continue;
            }
            while t < scan_t {
                let until = samples
                    .get(next)
                    .map_or(scan_t, |s| s.timestamp_s.min(scan_t));
                if until > t {
                    if let Ok(step) = motion.step(&pose, held.speed_mps, held.steer_rad, until - t)
                    {
                        pose = step.pose;
                    }
                    t = until;
                }
                if let Some(s) = samples.get(next).filter(|s| s.timestamp_s <= t) {
                    held = *s;
                    next += 1;
                }
            }
            errors.push((pose.x - truth.x).hypot(pose.y - truth.y));
        }
        errors
    }
}

impl TruthOracle for RecordedTruth {
    fn pose_at(&self, t_s: f64) -> Option<Pose2> {
        let n = self.times_s.len();
        let (&first, &last) = (self.times_s.first()?, self.times_s.last()?);
        // Extrapolate up to one mean scan interval beyond the ends (the odometry starts half
        // an interval before the first scan).
        let margin = (last - first) / (n.max(2) - 1) as f64;
        if !t_s.is_finite() || t_s < first - margin || t_s > last + margin {
            return None;
        }
        let k = self
            .times_s
            .partition_point(|&s| s <= t_s)
            .saturating_sub(1)
            .min(n.saturating_sub(2));
        let (a, b) = (self.poses.get(k)?, self.poses.get(k + 1)?);
        let (ta, tb) = (*self.times_s.get(k)?, *self.times_s.get(k + 1)?);
        let f = (t_s - ta) / (tb - ta);
        Some(Pose2::new(
            a.x + f * (b.x - a.x),
            a.y + f * (b.y - a.y),
            wrap_angle(a.theta + f * wrap_angle(b.theta - a.theta)),
        ))
    }

    fn features(&self) -> &[TrueFeature] {
        &[]
    }
}

/// Odometry handed to the daemon from memory, in time order.
#[derive(Debug)]
pub struct MemoryOdometry {
    records: VecDeque<OdometrySample>,
}

impl MemoryOdometry {
    /// A source giving `samples` in order, then ending.
    pub fn new(samples: Vec<OdometrySample>) -> Self {
        Self {
            records: samples.into(),
        }
    }
}

impl OdometrySource for MemoryOdometry {
    fn poll_next(&mut self, _timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        Ok(match self.records.pop_front() {
            Some(s) => OdometryPoll::Record(OdometryRecord {
                timestamp_s: s.timestamp_s,
                speed_mps: s.speed_mps,
                steer_rad: s.steer_rad,
            }),
            None => OdometryPoll::Ended,
        })
    }
}

/// The figures of a replay of `truth` with `samples` made with `errors`.
pub fn replay_figures(
    truth: &RecordedTruth,
    samples: &[OdometrySample],
    errors: OdometryErrors,
) -> ReplayFigures {
    let e = truth.dead_reckoning_errors(samples);
    let rms = if e.is_empty() {
        0.0
    } else {
        (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt()
    };
    ReplayFigures {
        errors,
        distance_m: truth.distance_m(),
        dead_reckoning_rms_m: rms,
        dead_reckoning_final_m: e.last().copied().unwrap_or(0.0),
        format: None,
        scans: truth.times_s().len(),
        scans_skipped: 0,
        first_scan_skipped: None,
        doppler_range_coupling_s: 0.0,
        radar_only: false,
        ground_truth: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,destination_radar_timestamp\n";

    fn folder(scans: &[i64], rows: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("radar")).unwrap();
        for us in scans {
            std::fs::write(dir.path().join("radar").join(format!("{us}.png")), b"").unwrap();
        }
        std::fs::write(
            dir.path().join("radar_odometry.csv"),
            format!("{HEADER}{rows}"),
        )
        .unwrap();
        dir
    }

    #[test]
    fn a_straight_drive_gives_its_speed_and_dead_reckoning_follows_exact_odometry() {
        // 2 m every 0.25 s: 8 m/s straight ahead; each pose holds at the middle of its
        // scan's rotation (the rows' own times, 0.125 s after the scans' names).
        let rows = "1375000,1125000,2.0,0,0,0,0,0,1250000,1000000\n1625000,1375000,2.0,0,0,0,0,0,1500000,1250000\n1875000,1625000,2.0,0,0,0,0,0,1750000,1500000\n";
        let dir = folder(&[1_000_000, 1_250_000, 1_500_000, 1_750_000], rows);
        let truth = RecordedTruth::read_oxford(dir.path()).unwrap();
        assert!((truth.distance_m() - 6.0).abs() < 1e-9);
        let exact = OdometryErrors {
            sigma_speed_mps: 0.0,
            sigma_yaw_rate_rps: 0.0,
            ..OdometryErrors::default()
        };
        let samples = truth.odometry(&exact);
        assert!(samples.iter().all(|s| (s.speed_mps - 8.0).abs() < 1e-9));
        let errors = truth.dead_reckoning_errors(&samples);
        assert_eq!(errors.len(), 4);
        assert!(errors.iter().all(|e| *e < 1e-6), "{errors:?}");
        assert_eq!(truth.times_s(), &[1.125, 1.375, 1.625, 1.875]);
        let p = truth.pose_at(1.25).unwrap();
        assert!((p.x - 1.0).abs() < 1e-9);
        // 5 % fast odometry drifts 5 % of the distance, from the first sample half a scan
        // before the first pose: 7 m by the last.
        let fast = OdometryErrors {
            speed_scale: 1.05,
            ..exact
        };
        let errors = truth.dead_reckoning_errors(&truth.odometry(&fast));
        assert!((errors[3] - 0.35).abs() < 1e-6, "{errors:?}");
    }

    #[test]
    fn bad_folders_are_refused_naming_the_file() {
        let empty = folder(&[], "");
        let err = RecordedTruth::read_oxford(empty.path()).unwrap_err();
        assert!(err.to_string().contains("no .png scans"), "{err}");
        let one = folder(&[1_000_000], "");
        let err = RecordedTruth::read_oxford(one.path()).unwrap_err();
        assert!(err.to_string().contains("1 scans"), "{err}");
        let missing = folder(&[1_000_000, 1_250_000], "0,0,2.0,0,0,0,0,0,9,8\n");
        let err = RecordedTruth::read_oxford(missing.path()).unwrap_err();
        let text = format!("{err}: {}", std::error::Error::source(&err).unwrap());
        assert!(
            text.contains("radar_odometry.csv") && text.contains("1250000"),
            "{text}"
        );
        let named = folder(&[1_000_000], "");
        std::fs::write(named.path().join("radar").join("scan-a.png"), b"").unwrap();
        let err = RecordedTruth::read_oxford(named.path()).unwrap_err();
        assert!(err.to_string().contains("scan-a.png"), "{err}");
    }

    /// The error and its causes, as the daemon prints them.
    fn chain(err: &ReplayError) -> String {
        let mut text = err.to_string();
        let mut source = std::error::Error::source(err);
        while let Some(s) = source {
            text = format!("{text}: {s}");
            source = s.source();
        }
        text
    }

    #[test]
    fn a_scan_or_a_row_centuries_away_is_refused_by_its_row_before_any_odometry() {
        // One scan named 9000000000000000000.png, linked by its row: the old code made
        // odometry over 285,000 years of it (1.8e14 samples preallocated: out of memory).
        const FAR: i64 = 9_000_000_000_000_000_000;
        let rows = format!(
            "1375000,1125000,2.0,0,0,0,0,0,1250000,1000000\n{},1375000,2.0,0,0,0,0,0,{FAR},1250000\n",
            FAR + 125_000
        );
        let dir = folder(&[1_000_000, 1_250_000, FAR], &rows);
        let err = RecordedTruth::read_oxford(dir.path()).unwrap_err();
        let text = chain(&err);
        assert!(
            text.contains("radar_odometry.csv") && text.contains("row 3") && text.contains("a day"),
            "{text}"
        );
        // One row whose pose time is centuries after its scans'.
        let dir = folder(
            &[1_000_000, 1_250_000],
            &format!("{FAR},1125000,2.0,0,0,0,0,0,1250000,1000000\n"),
        );
        let text = chain(&RecordedTruth::read_oxford(dir.path()).unwrap_err());
        assert!(text.contains("row 2") && text.contains("a day"), "{text}");
    }

    #[test]
    fn odometry_stops_at_a_day_and_a_half_of_samples_and_a_day_of_truth_is_not_cut() {
        let errors = OdometryErrors::default();
        let poses = vec![Pose2::default(), Pose2::new(10.0, 0.0, 0.0)];
        let max =
            (sim_sensor::replay::truth::MAX_SPAN_US as f64 * 1e-6 * 1.5 * ODOMETRY_HZ) as usize + 1;
        assert_eq!(max, 2_592_001);
        // 32 years (the old code preallocated 2e10 samples, 480 GB: out of memory).
        let started = std::time::Instant::now();
        let truth = RecordedTruth::from_poses(vec![0.0, 1e9], poses.clone()).unwrap();
        let samples = truth.odometry(&errors);
        assert_eq!(samples.len(), max);
        assert!(samples.capacity() <= max);
        // A day, the longest truth the readers accept, from half a day before it: whole.
        let truth = RecordedTruth::from_poses(vec![0.0, 86_400.0], poses.clone()).unwrap();
        let samples = truth.odometry(&errors);
        assert_eq!(samples.len(), max);
        assert_eq!(samples.last().map(|s| s.timestamp_s), Some(86_400.0));
        assert!(
            started.elapsed() < std::time::Duration::from_secs(1),
            "{:?}",
            started.elapsed()
        );
        // Times that are not finite (the old code: usize::MAX steps, an overflow) give none.
        let truth = RecordedTruth::from_poses(vec![0.0, f64::INFINITY], poses).unwrap();
        assert!(truth.odometry(&errors).is_empty());
    }
}
