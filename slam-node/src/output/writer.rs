//! The writer thread: every output leaves the filter on a bounded channel and is written
//! here, so a slow disk never blocks the filter. When the channel is full the event is
//! dropped and counted (the filter's state is unaffected; a gap appears in the files).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use radar_model::motion::MotionModel;
use tracing::{info, warn};

use super::diagnostics::RotationDiagnostics;
use super::event::OutputEvent;
use super::figures::{draw_map, draw_spectrum, FigureError, TruthOverlay};
use super::foxglove::{FoxgloveError, FoxgloveOutput};
use super::live::{LiveError, LiveOutput};
use super::map::MapSnapshot;
use super::recording::{McapRecorder, RecordingError};
pub use super::summary::WriterSummary;
use super::trajectory::{PoseSample, TumWriter};

/// The MCAP recording of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingFile {
    /// The file (created, or truncated).
    pub path: PathBuf,
    /// The motion model, to turn the odometry's steering into a yaw rate.
    pub motion: MotionModel,
}

/// The spectra file's name inside the output folder.
pub const SPECTRA_FILE: &str = "spectra.jsonl";

/// Where and what to write.
#[derive(Debug, Clone)]
pub struct OutputFiles {
    /// Output folder (created if missing).
    pub dir: PathBuf,
    /// Draw SVG figures at the end.
    pub figures: bool,
    /// At most this many spectrum figures.
    pub spectrum_figures: usize,
    /// Write `spectra.jsonl` (the figures are drawn either way).
    pub spectra: bool,
    /// Channel capacity, events.
    pub capacity: usize,
    /// Trajectory file name inside `dir` (TUM).
    pub trajectory: PathBuf,
    /// Map file name inside `dir`: CSV when it ends in `.csv`, JSON otherwise.
    pub map: PathBuf,
    /// Diagnostics file name inside `dir`: CSV when it ends in `.csv`, JSON Lines otherwise.
    pub diagnostics: PathBuf,
    /// Saved map file name inside `dir` (slam-map's format).
    pub saved_map: PathBuf,
    /// Record the run as MCAP (ROS 2 messages) too.
    pub recording: Option<RecordingFile>,
    /// Publish live over Zenoh too (needs the `zenoh` feature).
    pub live: Option<LiveOutput>,
    /// Serve the live view over Foxglove's WebSocket protocol too (needs the `foxglove`
    /// feature).
    pub foxglove: Option<FoxgloveOutput>,
}

impl OutputFiles {
    /// The default names: `trajectory.tum`, `map.json`, `diagnostics.jsonl`.
    pub fn in_dir(dir: PathBuf) -> Self {
        Self {
            dir,
            figures: true,
            spectrum_figures: 12,
            spectra: true,
            capacity: 8192,
            trajectory: "trajectory.tum".into(),
            map: "map.json".into(),
            diagnostics: "diagnostics.jsonl".into(),
            saved_map: "map.slmap".into(),
            recording: None,
            live: None,
            foxglove: None,
        }
    }
}

fn is_csv(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// A writer failure (the daemon logs it; the filter carries on).
#[derive(Debug, thiserror::Error)]
pub enum WriterError {
    /// A file could not be created or written.
    #[error("writing {path}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A figure failed.
    #[error(transparent)]
    Figure(#[from] FigureError),
    /// The MCAP recording could not start.
    #[error("starting the MCAP recording")]
    Recording(#[from] RecordingError),
    /// The live Zenoh output could not start.
    #[error("starting the live Zenoh output")]
    Live(#[from] LiveError),
    /// The Foxglove output could not start.
    #[error("starting the Foxglove live view")]
    Foxglove(#[from] FoxgloveError),
    /// The writer thread panicked.
    #[error("the writer thread panicked")]
    Panicked,
}

/// The filter's end of the output channel.
#[derive(Debug)]
pub struct OutputHandle {
    sender: Option<Sender<OutputEvent>>,
    dropped: Arc<AtomicU64>,
    join: Option<JoinHandle<Result<WriterSummary, WriterError>>>,
    wants_inputs: bool,
    #[cfg(feature = "zenoh")]
    live: Option<super::live::LivePublisher>,
    #[cfg(feature = "foxglove")]
    foxglove: Option<super::foxglove::FoxglovePublisher>,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> WriterError + '_ {
    move |source| WriterError::Io {
        path: path.display().to_string(),
        source,
    }
}

fn create(path: &Path) -> Result<BufWriter<File>, WriterError> {
    File::create(path).map(BufWriter::new).map_err(io_err(path))
}

impl OutputHandle {
    /// Creates the folder and files and starts the writer thread.
    pub fn spawn(files: OutputFiles) -> Result<Self, WriterError> {
        #[cfg(feature = "zenoh")]
        let live = files
            .live
            .clone()
            .map(super::live::LivePublisher::spawn)
            .transpose()?;
        #[cfg(not(feature = "zenoh"))]
        if files.live.is_some() {
            return Err(LiveError::NotBuilt.into());
        }
        #[cfg(feature = "foxglove")]
        let foxglove = files
            .foxglove
            .clone()
            .map(super::foxglove::FoxglovePublisher::spawn)
            .transpose()?;
        #[cfg(not(feature = "foxglove"))]
        if files.foxglove.is_some() {
            return Err(FoxgloveError::NotBuilt.into());
        }
        std::fs::create_dir_all(&files.dir).map_err(io_err(&files.dir))?;
        let (tx, rx) = bounded(files.capacity.max(1));
        let traj_path = files.dir.join(&files.trajectory);
        let traj = TumWriter::new(create(&traj_path)?).map_err(io_err(&traj_path))?;
        let diag_path = files.dir.join(&files.diagnostics);
        let mut diag = create(&diag_path)?;
        if is_csv(&diag_path) {
            writeln!(diag, "{}", super::csv::DIAGNOSTICS_HEADER).map_err(io_err(&diag_path))?;
        }
        let spec = if files.spectra {
            Some(create(&files.dir.join(SPECTRA_FILE))?)
        } else {
            None
        };
        let recorder = match &files.recording {
            Some(r) => {
                if let Some(parent) = r.path.parent().filter(|p| !p.as_os_str().is_empty()) {
                    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
                }
                let sink = File::create(&r.path).map_err(|source| RecordingError::Create {
                    path: r.path.display().to_string(),
                    source,
                })?;
                Some(McapRecorder::new(
                    BufWriter::with_capacity(1 << 20, sink),
                    r.path.clone(),
                    r.motion,
                )?)
            }
            None => None,
        };
        let wants_inputs = recorder.is_some();
        let join = std::thread::Builder::new()
            .name("slam-writer".into())
            .spawn(move || run(files, rx, traj, diag, spec, recorder))
            .map_err(io_err(Path::new("<writer thread>")))?;
        Ok(Self {
            sender: Some(tx),
            dropped: Arc::new(AtomicU64::new(0)),
            join: Some(join),
            wants_inputs,
            #[cfg(feature = "zenoh")]
            live,
            #[cfg(feature = "foxglove")]
            foxglove,
        })
    }

    /// Whether the azimuths are wanted: by a recording, or by the Foxglove output (the radar
    /// image). Only then are they sent.
    pub fn wants_inputs(&self) -> bool {
        #[cfg(feature = "foxglove")]
        if self.foxglove.is_some() {
            return true;
        }
        self.wants_inputs
    }

    /// Where the Foxglove output listens, when there is one.
    pub fn foxglove_address(&self) -> Option<std::net::SocketAddr> {
        #[cfg(feature = "foxglove")]
        if let Some(f) = &self.foxglove {
            return Some(f.address());
        }
        None
    }

    /// Whether the odometry samples are wanted: by a recording, or by the live output (the
    /// pose message's twist).
    pub fn wants_odometry(&self) -> bool {
        #[cfg(feature = "zenoh")]
        if self.live.is_some() {
            return true;
        }
        self.wants_inputs
    }

    /// Hands an event to the writer (and to the live output, when there is one) without
    /// ever blocking; returns false (and counts a drop) when the writer's channel is full or
    /// the writer has stopped. The live output counts its own drops.
    pub fn send(&self, event: OutputEvent) -> bool {
        #[cfg(feature = "zenoh")]
        if let Some(live) = &self.live {
            live.offer(&event);
        }
        #[cfg(feature = "foxglove")]
        if let Some(f) = &self.foxglove {
            f.offer(&event);
        }
        if matches!(event, OutputEvent::Odometry(_) | OutputEvent::Azimuth(_)) && !self.wants_inputs
        {
            return true;
        }
        match self.sender.as_ref().map(|s| s.try_send(event)) {
            Some(Ok(())) => true,
            Some(Err(TrySendError::Full(_) | TrySendError::Disconnected(_))) | None => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }

    /// Hands an event to the writer, waiting for room (end of run only); the live output
    /// is offered it as by [`OutputHandle::send`].
    pub fn send_blocking(&self, event: OutputEvent) -> bool {
        #[cfg(feature = "zenoh")]
        if let Some(live) = &self.live {
            live.offer(&event);
        }
        #[cfg(feature = "foxglove")]
        if let Some(f) = &self.foxglove {
            f.offer(&event);
        }
        self.sender.as_ref().is_some_and(|s| s.send(event).is_ok())
    }

    /// Events dropped because the writer could not keep up.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Closes the channel, waits for the writer to drain it, draws the figures.
    pub fn finish(mut self) -> Result<WriterSummary, WriterError> {
        self.sender.take();
        #[cfg(feature = "zenoh")]
        let live = self.live.take().map(super::live::LivePublisher::finish);
        #[cfg(not(feature = "zenoh"))]
        let live = None;
        #[cfg(feature = "foxglove")]
        let foxglove = self
            .foxglove
            .take()
            .map(super::foxglove::FoxglovePublisher::finish);
        #[cfg(not(feature = "foxglove"))]
        let foxglove = None;
        match self.join.take().map(JoinHandle::join) {
            Some(Ok(r)) => r.map(|s| WriterSummary {
                live,
                foxglove,
                ..s
            }),
            Some(Err(_)) => Err(WriterError::Panicked),
            None => Ok(WriterSummary::default()),
        }
    }
}

/// The trajectory in the Boreas benchmark's odometry format, next to `trajectory.tum`.
pub const BOREAS_ODOMETRY_FILE: &str = "odometry-boreas.txt";

/// The odometry's trajectory (on submaps: the filter's pose chained by the switch poses
/// alone, the global layer's corrections left out), next to `trajectory.tum` (TUM).
pub const ODOMETRY_TRAJECTORY_FILE: &str = "trajectory-odometry.tum";

/// The ground-truth trajectory's file name, next to the estimated trajectory (TUM).
pub const GROUND_TRUTH_FILE: &str = "groundtruth.tum";

/// The true pose at `pose`'s time, from the rotation's error against the truth (estimate
/// minus truth, computed at the same filter time), when the run knows the truth.
fn true_pose(pose: &PoseSample, r: &RotationDiagnostics) -> Option<PoseSample> {
    let (ex, ey, et) = (
        r.pose_error_x_m?,
        r.pose_error_y_m?,
        r.pose_error_theta_rad?,
    );
    Some(PoseSample {
        timestamp_s: pose.timestamp_s,
        x_m: pose.x_m - ex,
        y_m: pose.y_m - ey,
        theta_rad: radar_model::geometry::wrap_angle(pose.theta_rad - et),
        covariance: [[0.0; 3]; 3],
    })
}

/// An error and its causes on one line.
fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    radar_driver::ErrorChain(e).to_string()
}

fn run(
    files: OutputFiles,
    rx: Receiver<OutputEvent>,
    mut traj: TumWriter<BufWriter<File>>,
    mut diag: BufWriter<File>,
    mut spec: Option<BufWriter<File>>,
    mut recorder: Option<McapRecorder<BufWriter<File>>>,
) -> Result<WriterSummary, WriterError> {
    let mut summary = WriterSummary {
        files: vec![
            files.dir.join(&files.trajectory),
            files.dir.join(&files.map),
            files.dir.join(&files.diagnostics),
        ],
        ..WriterSummary::default()
    };
    if spec.is_some() {
        summary.files.push(files.dir.join(SPECTRA_FILE));
    }
    let mut poses: Vec<PoseSample> = Vec::new();
    // On submaps: the odometry's poses (the Boreas file takes them) and their file.
    let mut odometry_poses: Vec<PoseSample> = Vec::new();
    let mut odometry_traj: Option<TumWriter<BufWriter<File>>> = None;
    let odometry_path = files.dir.join(ODOMETRY_TRAJECTORY_FILE);
    let mut ground_truth: Option<TumWriter<BufWriter<File>>> = None;
    // The pose of the rotation being closed (a Pose comes just before its Rotation).
    let mut rotation_pose: Option<PoseSample> = None;
    let truth_path = files.dir.join(GROUND_TRUTH_FILE);
    let mut last_map: Option<MapSnapshot> = None;
    let mut truth = TruthOverlay::default();
    let map_path = files.dir.join(&files.map);
    let diag_path = files.dir.join(&files.diagnostics);
    let spec_path = files.dir.join(SPECTRA_FILE);
    let traj_path = files.dir.join(&files.trajectory);
    let diag_csv = is_csv(&diag_path);
    let map_csv = is_csv(&map_path);
    for event in rx {
        if let Some(r) = recorder.as_mut() {
            if let Err(e) = r.on_event(&event) {
                // The recording stops; the daemon and the other files go on.
                warn!(error = %error_chain(&e), "MCAP recording stopped");
                summary.recording_error = Some(error_chain(&e));
                recorder = None;
            }
        }
        match event {
            OutputEvent::Pose(p) => {
                traj.write(&p).map_err(io_err(&traj_path))?;
                rotation_pose = Some(p);
                poses.push(p);
                summary.poses += 1;
            }
            OutputEvent::OdometryPose(p) => {
                opened(&mut odometry_traj, &odometry_path, &mut summary.files)?
                    .write(&p)
                    .map_err(io_err(&odometry_path))?;
                odometry_poses.push(p);
            }
            OutputEvent::Rotation(r) => {
                // The rotation's pose came just before it; with its error against the truth
                // the true pose is known: write it for `evo_ape tum groundtruth.tum
                // trajectory.tum`.
                if let Some(t) = rotation_pose.take().and_then(|p| true_pose(&p, &r)) {
                    opened(&mut ground_truth, &truth_path, &mut summary.files)?
                        .write(&t)
                        .map_err(io_err(&truth_path))?;
                }
                if diag_csv {
                    writeln!(diag, "{}", super::csv::diagnostics_row(&r))
                } else {
                    serde_json::to_writer(&mut diag, &r)
                        .map_err(std::io::Error::other)
                        .and_then(|()| writeln!(diag))
                }
                .map_err(io_err(&diag_path))?;
                summary.rotations += 1;
            }
            OutputEvent::Map(m) => {
                let mut tmp_name = map_path.clone().into_os_string();
                tmp_name.push(".tmp");
                let tmp = PathBuf::from(tmp_name);
                let mut w = create(&tmp)?;
                if map_csv {
                    super::csv::write_map(&m, &mut w)
                } else {
                    m.write_json(&mut w)
                }
                .and_then(|()| w.flush())
                .map_err(io_err(&tmp))?;
                drop(w);
                std::fs::rename(&tmp, &map_path).map_err(io_err(&map_path))?;
                last_map = Some(m);
                summary.maps += 1;
            }
            OutputEvent::Spectrum(s) => {
                if let Some(spec) = spec.as_mut() {
                    serde_json::to_writer(&mut *spec, &s)
                        .map_err(std::io::Error::other)
                        .and_then(|()| writeln!(spec))
                        .map_err(io_err(&spec_path))?;
                }
                if files.figures && (summary.spectra as usize) < files.spectrum_figures {
                    let p = files.dir.join(format!(
                        "spectrum_r{}_b{:.0}.svg",
                        s.rotation,
                        s.bearing_rad.to_degrees()
                    ));
                    draw_spectrum(&p, &s)?;
                    summary.figures.push(p);
                }
                summary.spectra += 1;
            }
            OutputEvent::Truth(t) => truth = t,
            OutputEvent::SavedMap(m) => {
                let path = files.dir.join(&files.saved_map);
                super::saved_map::save(&m, &path, &mut summary);
            }
            OutputEvent::Trajectory(t) => {
                traj.flush().map_err(io_err(&traj_path))?;
                let online = online_path(&traj_path);
                std::fs::rename(&traj_path, &online).map_err(io_err(&online))?;
                let mut w = create(&traj_path)?;
                writeln!(
                    w,
                    "# globally optimised: each pose through its submap's frame as the global layer solved it at the end of the run ({} poses; as published during the run: {})",
                    t.len(),
                    online.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
                )
                .map_err(io_err(&traj_path))?;
                let mut tum = TumWriter::new(w).map_err(io_err(&traj_path))?;
                for p in &t {
                    tum.write(p).map_err(io_err(&traj_path))?;
                }
                tum.flush().map_err(io_err(&traj_path))?;
                summary.files.push(online);
                poses = t;
            }
            OutputEvent::Azimuth(_) | OutputEvent::Odometry(_) | OutputEvent::Detections(_) => {}
        }
    }
    if let Some(r) = recorder {
        match r.finish() {
            Ok((_, rec)) => {
                info!(
                    path = %rec.path.display(),
                    messages = rec.total_messages(),
                    bytes = rec.bytes,
                    "MCAP recording written"
                );
                summary.files.push(rec.path.clone());
                summary.recording = Some(rec);
            }
            Err(e) => {
                warn!(error = %error_chain(&e), "MCAP recording could not be finished");
                summary.recording_error = Some(error_chain(&e));
            }
        }
    }
    traj.flush().map_err(io_err(&traj_path))?;
    if let Some(w) = odometry_traj.as_mut() {
        w.flush().map_err(io_err(&odometry_path))?;
    }
    if let Some(w) = ground_truth.as_mut() {
        w.flush().map_err(io_err(&truth_path))?;
    }
    diag.flush().map_err(io_err(&diag_path))?;
    if let Some(spec) = spec.as_mut() {
        spec.flush().map_err(io_err(&spec_path))?;
    }
    // The trajectory in the Boreas benchmark's odometry format (a row per rotation: the time
    // in microseconds and the upper 3x4 of T_vk_v0, z up), for its evaluator as it is: the
    // odometry's on submaps (an odometry benchmark scores motion, and the global layer's
    // corrections arrive as jumps), else the published poses.
    let boreas_poses = if odometry_poses.is_empty() {
        &poses
    } else {
        &odometry_poses
    };
    if !boreas_poses.is_empty() {
        let frames: Vec<(i64, radar_model::geometry::Pose2)> = boreas_poses
            .iter()
            .map(|p| {
                (
                    (p.timestamp_s * 1e6).round() as i64,
                    radar_model::geometry::Pose2::new(p.x_m, p.y_m, p.theta_rad),
                )
            })
            .collect();
        let boreas_path = files.dir.join(BOREAS_ODOMETRY_FILE);
        match slam_filter::drift::boreas::odometry_file(
            &frames,
            slam_filter::drift::boreas::VerticalAxis::Up,
        ) {
            Ok(text) => {
                std::fs::write(&boreas_path, text).map_err(io_err(&boreas_path))?;
                summary.files.push(boreas_path);
            }
            Err(e) => warn!(error = %e, "the Boreas odometry file was not written"),
        }
    }
    if files.figures {
        let p = files.dir.join("map.svg");
        let features = last_map.map(|m| m.features).unwrap_or_default();
        draw_map(&p, &features, &poses, &truth)?;
        summary.figures.push(p);
    }
    Ok(summary)
}

/// The TUM file in `slot`, created at `path` (and listed in `files`) on its first pose.
fn opened<'a>(
    slot: &'a mut Option<TumWriter<BufWriter<File>>>,
    path: &std::path::Path,
    files: &mut Vec<PathBuf>,
) -> Result<&'a mut TumWriter<BufWriter<File>>, WriterError> {
    let w = match slot.take() {
        Some(w) => w,
        None => {
            let w = TumWriter::new(create(path)?).map_err(io_err(path))?;
            files.push(path.to_path_buf());
            w
        }
    };
    Ok(slot.insert(w))
}

/// `dir/name-online.ext` beside `dir/name.ext`.
fn online_path(path: &std::path::Path) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "trajectory".into());
    let name = match path.extension() {
        Some(ext) => format!("{stem}-online.{}", ext.to_string_lossy()),
        None => format!("{stem}-online"),
    };
    path.with_file_name(name)
}
