//! The ground truth of a simulated run, as a JSON Lines file (one JSON object a line), and a
//! reader for it. The format is documented in `sim-sensor/README.md`:
//!
//! 1. one `header` record: format name and version, scene, radar, motion model, start time;
//! 2. one `feature` record per scene feature: id, kind, position, `rho`, `alpha`;
//! 3. `pose` records, one every N azimuths (N = 1 by default), in azimuth order: the true
//!    pose at that azimuth's own timestamp, its encoder value and the true controls.
//!
//! Poses are written up to the world's frontier (what has been served, or real time), by a
//! blocking thread; the file is flushed about every 100 ms and at shutdown.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use tokio_util::sync::CancellationToken;

use crate::error::SimError;
use crate::radar::azimuth_in_rotation;
use crate::radar::RadarParams;
use crate::scene::{FeatureKind, MotionSpec};
use crate::server::world::World;

/// The `format` field of the header.
pub const FORMAT: &str = "sim-sensor-ground-truth";
/// The `version` field of the header.
pub const VERSION: u32 = 1;
/// Longest line the reader accepts.
pub const MAX_LINE_BYTES: usize = 4096;

/// The radar as the header records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthRadar {
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Encoder counts per revolution.
    pub encoder_size: u16,
    /// Bins per azimuth.
    pub range_bins: u16,
    /// Bin size, metres (range gain applied).
    pub bin_size_m: f64,
    /// Rotation rate, Hz.
    pub rotation_hz: f64,
    /// Beam width, radians.
    pub beam_width_rad: f64,
}

impl From<&RadarParams> for TruthRadar {
    fn from(r: &RadarParams) -> Self {
        Self {
            azimuths: r.azimuths,
            encoder_size: r.encoder_size,
            range_bins: r.range_bins,
            bin_size_m: f64::from(r.range_gain) * r.bin_size_m(),
            rotation_hz: r.rotation_hz(),
            beam_width_rad: r.beam_width_rad,
        }
    }
}

/// The motion model as the header records it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum TruthMotion {
    /// The paper's eq. 2.
    Paper {
        /// Step the steering input refers to, seconds.
        step_s: f64,
    },
    /// The bicycle model.
    Bicycle {
        /// Wheelbase, metres.
        wheelbase_m: f64,
    },
}

impl From<MotionSpec> for TruthMotion {
    fn from(m: MotionSpec) -> Self {
        match m {
            MotionSpec::Paper { step_s } => TruthMotion::Paper { step_s },
            MotionSpec::Bicycle { wheelbase_m } => TruthMotion::Bicycle { wheelbase_m },
        }
    }
}

/// One line of the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum TruthRecord {
    /// The first line.
    Header {
        /// [`FORMAT`].
        format: String,
        /// [`VERSION`].
        version: u32,
        /// The scene's name.
        scene: String,
        /// The seed used.
        seed: u64,
        /// The radar.
        radar: TruthRadar,
        /// The process model the vehicle was driven by (odometry's steering means this).
        motion: TruthMotion,
        /// Radar loss L, dB.
        loss_db: f64,
        /// Unix time of azimuth 0, seconds.
        start_time_s: f64,
    },
    /// A feature of the scene.
    Feature {
        /// Stable id.
        id: u32,
        /// Kind.
        kind: FeatureKind,
        /// World x, metres.
        x_m: f64,
        /// World y, metres.
        y_m: f64,
        /// Normalised reflectivity.
        rho: f64,
        /// Normalised absorption.
        alpha: f64,
    },
    /// The true pose at one azimuth.
    Pose {
        /// Unix time of the azimuth, seconds.
        timestamp_s: f64,
        /// Azimuth index since the start.
        azimuth_index: u64,
        /// Its encoder value.
        encoder: u16,
        /// World x, metres.
        x_m: f64,
        /// World y, metres.
        y_m: f64,
        /// Heading, radians counter-clockwise from +x, wrapped to (-pi, pi].
        theta_rad: f64,
        /// True speed, m/s.
        speed_mps: f64,
        /// True steering, rad.
        steer_rad: f64,
    },
}

/// Writes the ground truth of a served scene.
#[derive(Debug)]
pub(crate) struct TruthWriter {
    path: PathBuf,
    out: BufWriter<File>,
    world: Arc<World>,
    every_n: u64,
    next: u64,
    cursor: Option<crate::trajectory::TrajectoryCursor>,
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |source| SimError::GroundTruth {
        path: path.to_path_buf(),
        source,
    }
}

fn json_line<W: Write>(out: &mut W, record: &TruthRecord) -> std::io::Result<()> {
    serde_json::to_writer(&mut *out, record).map_err(std::io::Error::other)?;
    out.write_all(b"\n")
}

impl TruthWriter {
    /// Creates the file and writes the header and every feature.
    pub(crate) fn create(path: &Path, world: Arc<World>, every_n: u32) -> Result<Self, SimError> {
        let Some(scene) = world.scene().cloned() else {
            return Err(SimError::Setting {
                field: "ground_truth_path".into(),
                reason: "ground truth is written for scenes only".into(),
            });
        };
        let file = File::create(path).map_err(io_err(path))?;
        let mut out = BufWriter::new(file);
        let header = TruthRecord::Header {
            format: FORMAT.into(),
            version: VERSION,
            scene: scene.scene_name().to_string(),
            seed: scene.seed(),
            radar: TruthRadar::from(scene.radar()),
            motion: scene.motion().into(),
            loss_db: scene.loss_db(),
            start_time_s: world.start_unix_ns as f64 * 1e-9,
        };
        json_line(&mut out, &header).map_err(io_err(path))?;
        for f in scene.features() {
            let record = TruthRecord::Feature {
                id: f.id,
                kind: f.kind,
                x_m: f.x_m,
                y_m: f.y_m,
                rho: f.rho,
                alpha: f.alpha,
            };
            json_line(&mut out, &record).map_err(io_err(path))?;
        }
        out.flush().map_err(io_err(path))?;
        Ok(Self {
            path: path.to_path_buf(),
            out,
            world,
            every_n: u64::from(every_n.max(1)),
            next: 0,
            cursor: None,
        })
    }

    /// Writes poses up to the frontier until `cancel`, then up to the final frontier.
    pub(crate) fn run(mut self, cancel: &CancellationToken) -> Result<(), SimError> {
        let mut last_flush = Instant::now();
        loop {
            let stopping = cancel.is_cancelled();
            self.write_up_to_frontier()?;
            if stopping {
                break;
            }
            if last_flush.elapsed() > Duration::from_millis(100) {
                self.out.flush().map_err(io_err(&self.path))?;
                last_flush = Instant::now();
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.out.flush().map_err(io_err(&self.path))
    }

    fn write_up_to_frontier(&mut self) -> Result<(), SimError> {
        let Some(scene) = self.world.scene().cloned() else {
            return Ok(());
        };
        let mut frontier = self.world.current_index();
        if let Some(stop) = self.world.stop_after {
            frontier = frontier.min(stop);
        }
        let trajectory = scene.trajectory();
        let cursor = self.cursor.get_or_insert_with(|| trajectory.cursor());
        while self.next < frontier {
            let k = self.next;
            let offset = scene.offset_ns(k);
            let pose = trajectory.pose_with(cursor, offset)?;
            let (speed_mps, steer_rad) = trajectory.controls_at(offset);
            let record = TruthRecord::Pose {
                timestamp_s: self.world.start_unix_ns.saturating_add(offset) as f64 * 1e-9,
                azimuth_index: k,
                encoder: scene
                    .radar()
                    .encoder_of(azimuth_in_rotation(scene.radar(), k)),
                x_m: pose.x,
                y_m: pose.y,
                theta_rad: pose.theta,
                speed_mps,
                steer_rad,
            };
            json_line(&mut self.out, &record).map_err(io_err(&self.path))?;
            self.next += self.every_n;
        }
        Ok(())
    }
}

/// Why a ground-truth file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TruthReadError {
    /// The file could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A line that is not a record.
    #[error("{path}:{line}: {reason}")]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The first line is not this format's header.
    #[error("{0}: not a sim-sensor ground truth file (version {VERSION})")]
    NotGroundTruth(PathBuf),
}

/// A whole ground-truth file.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruth {
    /// The header record.
    pub header: TruthRecord,
    /// Feature records.
    pub features: Vec<TruthRecord>,
    /// Pose records, in file order.
    pub poses: Vec<TruthRecord>,
}

impl GroundTruth {
    /// Reads a ground-truth file.
    ///
    /// # Errors
    /// IO errors, lines over [`MAX_LINE_BYTES`] or that do not parse, a wrong header.
    pub fn read(path: &Path) -> Result<GroundTruth, TruthReadError> {
        let io = |source| TruthReadError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut reader = BufReader::new(File::open(path).map_err(io)?);
        let mut header = None;
        let mut features = Vec::new();
        let mut poses = Vec::new();
        let mut line = Vec::new();
        let mut number = 0usize;
        loop {
            line.clear();
            let n = (&mut reader)
                .take(MAX_LINE_BYTES as u64 + 1)
                .read_until(b'\n', &mut line)
                .map_err(io)?;
            if n == 0 {
                break;
            }
            number += 1;
            let bad = |reason: String| TruthReadError::Line {
                path: path.to_path_buf(),
                line: number,
                reason,
            };
            if line.len() > MAX_LINE_BYTES {
                return Err(bad(format!("longer than {MAX_LINE_BYTES} bytes")));
            }
            let record: TruthRecord =
                serde_json::from_slice(&line).map_err(|e| bad(e.to_string()))?;
            match (&record, header.is_some()) {
                (
                    TruthRecord::Header {
                        format, version, ..
                    },
                    false,
                ) => {
                    if format != FORMAT || *version != VERSION {
                        return Err(TruthReadError::NotGroundTruth(path.to_path_buf()));
                    }
                    header = Some(record);
                }
                (_, false) => return Err(TruthReadError::NotGroundTruth(path.to_path_buf())),
                (TruthRecord::Header { .. }, true) => return Err(bad("a second header".into())),
                (TruthRecord::Feature { .. }, true) => features.push(record),
                (TruthRecord::Pose { .. }, true) => poses.push(record),
            }
        }
        Ok(GroundTruth {
            header: header.ok_or_else(|| TruthReadError::NotGroundTruth(path.to_path_buf()))?,
            features,
            poses,
        })
    }
}
