//! The daemon run on a rosbag2 MCAP file instead of a radar: Navtech's ROS 2 radar messages
//! (`navtech_msgs/msg/RadarBScanMsg` per rotation or `RadarFftDataMsg` per azimuth, with
//! `RadarConfigurationMsg` for the geometry) and an odometry topic (`geometry_msgs/msg/
//! TwistStamped`, or `nav_msgs/msg/Odometry`'s twist; the yaw rate is turned into the motion
//! model's steering input), as fast as the pipeline goes.
//!
//! A reader thread streams the file through the `mcap` crate's sans-IO linear reader
//! ([`records`]: records bounded to 256 MiB and to what the file holds, the file never held
//! whole; [`chunk`]: a compressed chunk's claimed size bounded by what its bytes can expand
//! to and by a cap, 64 MiB unless `--mcap-max-chunk-mib` says otherwise; [`decompress`]: zstd
//! and lz4 chunks decompressed in 1 MiB blocks) and hands azimuths to the pipeline on a
//! bounded channel (back-pressure: nothing is dropped) and odometry on another. A rotation is
//! handed over once the odometry has reached its last azimuth (or 256 MB of bins later), so the
//! pipeline meets the same odometry, in the same order, as the run that made the recording:
//! a recording the daemon made replays to the same trajectory bit for bit (paper motion model;
//! the bicycle model's steering goes through atan and may differ in the last bits).
//!
//! Bad input costs the message, is counted and the first few are logged: a channel whose
//! schema encoding is not `ros2msg` or whose schema is unknown, a message encoding other than
//! `cdr`, a payload that does not decode, a B-scan whose image does not match its rows, radar
//! data before any configuration. A truncated or corrupt file ends the replay where it breaks
//! (everything before is used) and is reported. The run's stop request (Ctrl-C) ends
//! the reading at the next record, read of the file or block of a chunk's decompression.

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use bytes::Bytes;
use crossbeam_channel::{bounded, unbounded, Receiver, Sender};
use mcap::records::Record;
use protocol::{BinWidth, Geometry};
use radar_driver::{Azimuth, OdometryError, OdometryPoll, OdometryRecord, OdometrySource};
use radar_model::motion::MotionModel;
use ros_msgs::builtin::Time;
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg, RadarFftDataMsg};
use ros_msgs::{from_cdr, RosMessage};
use tracing::warn;

use crate::output::ros::OdometryMessage;

mod chunk;
mod decompress;
mod records;
pub use chunk::{ChunkError, ChunkLimits, DEFAULT_MAX_CHUNK_BYTES};
pub use decompress::{Compression, BLOCK_BYTES, LZ4_MAX_RATIO, ZSTD_MAX_RATIO};
pub use records::{read_records, McapFileError, RecordsEnd};

/// The longest record read (a B-scan of a CTS350-X is 1.5 MB).
const MAX_RECORD_BYTES: usize = 256 << 20;
/// Radar data held back waiting for odometry before it goes anyway, bytes of bins (about
/// 170 rotations of a CTS350-X).
const MAX_PENDING_BYTES: usize = 256 << 20;

/// What to replay.
#[derive(Debug, Clone)]
pub struct McapReplaySettings {
    /// The MCAP file.
    pub path: PathBuf,
    /// The odometry topic (`TwistStamped` or `nav_msgs/Odometry`).
    pub odometry_topic: String,
    /// The motion model, to turn yaw rates into steering inputs.
    pub motion: MotionModel,
    /// Azimuths in flight to the pipeline.
    pub azimuth_capacity: usize,
    /// The largest uncompressed size a chunk may claim, bytes.
    pub max_chunk_bytes: u64,
    /// The run's stop request (Ctrl-C): reading ends at the next record, read of
    /// the file or block of a chunk's decompression once it is set.
    pub stop: Arc<AtomicBool>,
}

impl McapReplaySettings {
    /// `path` with the daemon's own odometry topic (`/odom/twist`).
    pub fn new(path: PathBuf, motion: MotionModel) -> Self {
        Self {
            path,
            odometry_topic: crate::output::recording::TOPIC_ODOMETRY_INPUT.to_string(),
            motion,
            azimuth_capacity: 4096,
            max_chunk_bytes: DEFAULT_MAX_CHUNK_BYTES,
            stop: Arc::new(AtomicBool::new(false)),
        }
    }
}

/// Why the replay could not start.
#[derive(Debug, thiserror::Error)]
pub enum McapReplayError {
    /// The file could not be opened.
    #[error("opening {path}")]
    Open {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The path names a FIFO, a device, a socket or a folder: refused before opening (a
    /// FIFO's open would wait for a writer, a device would be read without end).
    #[error("{path} is not a regular file; an MCAP recording must be one")]
    NotRegularFile {
        /// The path.
        path: String,
    },
    /// The reader thread could not start.
    #[error("starting the MCAP reader thread")]
    Thread(#[source] std::io::Error),
}

/// What the replay read and what it refused.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct McapReplayCounts {
    /// Messages read.
    pub messages: u64,
    /// Radar configurations taken.
    pub configurations: u64,
    /// B-scans (rotations) taken.
    pub rotations: u64,
    /// Azimuths handed to the pipeline.
    pub azimuths: u64,
    /// Odometry samples handed to the pipeline.
    pub odometry: u64,
    /// Messages on topics the daemon does not use.
    pub ignored: u64,
    /// Messages whose channel or schema is unknown, or whose schema is not `ros2msg`.
    pub unknown_schema: u64,
    /// Messages whose encoding is not `cdr`.
    pub wrong_encoding: u64,
    /// Messages that did not decode, or whose content is inconsistent.
    pub malformed: u64,
    /// Radar messages before any configuration.
    pub before_configuration: u64,
    /// Why reading stopped before the end, if it did (truncated or corrupt file).
    pub file_error: Option<String>,
    /// Reading ended early on the run's stop request.
    pub stopped: bool,
}

impl McapReplayCounts {
    /// Messages refused for any reason.
    pub fn refused(&self) -> u64 {
        self.unknown_schema + self.wrong_encoding + self.malformed + self.before_configuration
    }
}

/// The replay's reader thread.
#[derive(Debug)]
pub struct McapReplayHandle {
    join: JoinHandle<McapReplayCounts>,
}

impl McapReplayHandle {
    /// Waits for the reader (it stops once the pipeline has dropped its receivers).
    pub fn finish(self) -> McapReplayCounts {
        self.join.join().unwrap_or_else(|_| McapReplayCounts {
            file_error: Some("the MCAP reader thread panicked".into()),
            ..McapReplayCounts::default()
        })
    }
}

impl super::Running for McapReplayHandle {
    fn stop(self: Box<Self>) -> super::Stopping {
        Box::pin(async move {
            let counts = tokio::task::spawn_blocking(move || self.finish())
                .await
                .unwrap_or_else(|_| McapReplayCounts {
                    file_error: Some("the MCAP reader thread panicked".into()),
                    ..McapReplayCounts::default()
                });
            super::SourceEnd {
                scans_skipped: 0,
                first_scan_skipped: None,
                mcap: Some(counts),
            }
        })
    }
}

/// The daemon's inputs from an MCAP recording: the recorded radar's azimuths, numbered by
/// the radar driver's numbering, and the recorded odometry topic (`odometry_topic`, the
/// daemon's own by default) under `recipe`'s motion model; the pipeline is built on the
/// first azimuth, whose geometry chooses the recorded radar's profile. Reading ends early
/// once `stop` (the run's stop request) is set.
pub fn open(
    recipe: crate::pipeline::SettingsRecipe,
    source: &super::McapSource,
    stop: &Arc<AtomicBool>,
) -> Result<super::Inputs, super::SourceError> {
    let motion = crate::pipeline::settings::motion_model(&recipe.config);
    let mut settings = McapReplaySettings::new(source.path.clone(), motion);
    settings.stop = Arc::clone(stop);
    if let Some(topic) = &source.odometry_topic {
        settings.odometry_topic = topic.clone();
    }
    if let Some(cap) = source.max_chunk_bytes {
        settings.max_chunk_bytes = cap;
    }
    let (azimuths, odometry, reader) = start(settings)?;
    Ok(super::Inputs {
        azimuths,
        driver: None,
        odometry: Some(Box::new(odometry)),
        gyro: None,
        pipeline: crate::pipeline::run::PipelineStart::OnFirstAzimuth(Box::new(
            move |geometry: &protocol::Geometry| {
                let derived =
                    recipe.for_radar(geometry, crate::pipeline::SourceFacts::default())?;
                crate::pipeline::Pipeline::new(derived.settings, None, None)
            },
        )),
        motion,
        name: Some(format!("MCAP recording {}", source.path.display())),
        truth_overlay: crate::output::figures::TruthOverlay::default(),
        end_after_silence: None,
        played_out: None,
        replay: None,
        running: Box::new(reader),
    })
}

/// Odometry from the reader thread.
#[derive(Debug)]
pub struct ReplayOdometry {
    rx: Receiver<OdometryRecord>,
}

impl OdometrySource for ReplayOdometry {
    fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        Ok(radar_driver::odometry::poll_channel(&self.rx, timeout))
    }
}

/// Opens the file and starts reading: the pipeline's azimuths, its odometry, and the handle.
pub fn start(
    settings: McapReplaySettings,
) -> Result<(Receiver<Azimuth>, ReplayOdometry, McapReplayHandle), McapReplayError> {
    let open_error = |source| McapReplayError::Open {
        path: settings.path.display().to_string(),
        source,
    };
    // Checked on the path (following links) before opening, so opening cannot block.
    if !std::fs::metadata(&settings.path)
        .map_err(open_error)?
        .is_file()
    {
        return Err(McapReplayError::NotRegularFile {
            path: settings.path.display().to_string(),
        });
    }
    let file = File::open(&settings.path).map_err(open_error)?;
    let (az_tx, az_rx) = bounded(settings.azimuth_capacity.max(1));
    let (odo_tx, odo_rx) = unbounded();
    let join = std::thread::Builder::new()
        .name("mcap-replay".into())
        .spawn(move || {
            let mut reader = Reader::new(settings, az_tx, odo_tx);
            reader.run(file);
            reader.counts
        })
        .map_err(McapReplayError::Thread)?;
    Ok((
        az_rx,
        ReplayOdometry { rx: odo_rx },
        McapReplayHandle { join },
    ))
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Use {
    BScan,
    Fft,
    Configuration,
    Odometry(OdometryMessage),
    Ignored,
    UnknownSchema,
    WrongEncoding,
}

/// `package/msg/Type` and `package/Type` name the same type.
fn same_type(name: &str, full: &str) -> bool {
    name == full || name == full.replacen("/msg/", "/", 1)
}

struct Reader {
    settings: McapReplaySettings,
    az_tx: Sender<Azimuth>,
    odo_tx: Sender<OdometryRecord>,
    schemas: HashMap<u16, (String, String)>,
    channels: HashMap<u16, Use>,
    geometry: Option<Arc<Geometry>>,
    pending: VecDeque<(f64, Vec<Azimuth>)>,
    pending_bytes: usize,
    latest_odometry_s: f64,
    /// Numbers the azimuths' rotations as the radar driver does.
    numbering: radar_driver::RotationAssembler,
    /// The next sweep counter given to a B-scan's rows.
    next_sweep: u16,
    counts: McapReplayCounts,
    closed: bool,
    odometry_closed: bool,
}

impl Reader {
    fn new(
        settings: McapReplaySettings,
        az_tx: Sender<Azimuth>,
        odo_tx: Sender<OdometryRecord>,
    ) -> Self {
        Self {
            settings,
            az_tx,
            odo_tx,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            geometry: None,
            pending: VecDeque::new(),
            pending_bytes: 0,
            latest_odometry_s: f64::NEG_INFINITY,
            numbering: {
                let mut a = radar_driver::RotationAssembler::new();
                a.set_counting_only(true);
                a
            },
            next_sweep: 0,
            counts: McapReplayCounts::default(),
            closed: false,
            odometry_closed: false,
        }
    }

    fn refuse(&mut self, what: &str, detail: &str) {
        let n = self.counts.refused();
        if n < 10 || n.is_power_of_two() {
            warn!(what, detail, count = n, "MCAP message refused");
        }
    }

    fn run(&mut self, file: File) {
        let limits = ChunkLimits {
            max_uncompressed: self.settings.max_chunk_bytes,
            max_record: MAX_RECORD_BYTES as u64,
        };
        let stop = Arc::clone(&self.settings.stop);
        let read = records::read_records(file, limits, &stop, |opcode, data| {
            if self.closed {
                return ControlFlow::Break(());
            }
            match mcap::parse_record(opcode, data) {
                Ok(record) => self.on_record(record),
                Err(e) => {
                    self.counts.malformed += 1;
                    self.refuse("record", &e.to_string());
                }
            }
            ControlFlow::Continue(())
        });
        if stop.load(Ordering::Relaxed) {
            // The run is ending: what is held back is not handed on.
            self.counts.stopped = true;
            return;
        }
        if let Err(e) = read {
            let e = format!(
                "{}: {}",
                self.settings.path.display(),
                radar_driver::ErrorChain(&e)
            );
            warn!(error = %e, "the MCAP file ends early or is corrupt: replaying what came before");
            self.counts.file_error = Some(e);
        }
        while let Some(group) = self.release() {
            self.send(group);
        }
    }

    fn on_record(&mut self, record: Record<'_>) {
        match record {
            Record::Schema { header, .. } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let use_ = match self.schemas.get(&c.schema_id) {
                    None => Use::UnknownSchema,
                    Some((_, encoding)) if encoding != "ros2msg" => Use::UnknownSchema,
                    Some(_) if c.message_encoding != "cdr" => Use::WrongEncoding,
                    Some((name, _)) => {
                        if same_type(name, &RadarBScanMsg::type_name()) {
                            Use::BScan
                        } else if same_type(name, &RadarFftDataMsg::type_name()) {
                            Use::Fft
                        } else if same_type(name, &RadarConfigurationMsg::type_name()) {
                            Use::Configuration
                        } else if c.topic != self.settings.odometry_topic {
                            Use::Ignored
                        } else if let Some(kind) = OdometryMessage::from_type_name(name) {
                            Use::Odometry(kind)
                        } else {
                            Use::UnknownSchema
                        }
                    }
                };
                self.channels.insert(c.id, use_);
            }
            Record::Message { header, data } => {
                self.counts.messages += 1;
                let use_ = self
                    .channels
                    .get(&header.channel_id)
                    .copied()
                    .unwrap_or(Use::UnknownSchema);
                self.on_message(use_, &data);
            }
            _ => {}
        }
    }

    fn on_message(&mut self, use_: Use, data: &[u8]) {
        match use_ {
            Use::Ignored => self.counts.ignored += 1,
            Use::UnknownSchema => {
                self.counts.unknown_schema += 1;
                self.refuse(
                    "unknown schema",
                    "channel or schema unknown, or not ros2msg",
                );
            }
            Use::WrongEncoding => {
                self.counts.wrong_encoding += 1;
                self.refuse("wrong encoding", "message encoding is not cdr");
            }
            Use::Configuration => match from_cdr::<RadarConfigurationMsg>(data) {
                Ok(m) => self.on_configuration(&m),
                Err(e) => self.malformed("configuration", &e.to_string()),
            },
            Use::BScan => match from_cdr::<RadarBScanMsg>(data) {
                Ok(m) => self.on_bscan(m),
                Err(e) => self.malformed("b-scan", &e.to_string()),
            },
            Use::Fft => match from_cdr::<RadarFftDataMsg>(data) {
                Ok(m) => self.on_fft(m),
                Err(e) => self.malformed("fft data", &e.to_string()),
            },
            Use::Odometry(kind) => match kind.decode(data, &self.settings.motion) {
                Ok(record) => self.on_odometry(record),
                Err(e) => self.malformed("odometry", &e.to_string()),
            },
        }
    }

    fn malformed(&mut self, what: &str, detail: &str) {
        self.counts.malformed += 1;
        self.refuse(what, detail);
    }

    fn on_configuration(&mut self, m: &RadarConfigurationMsg) {
        let valid = m.encoder_size > 0
            && m.azimuth_samples > 0
            && m.bin_size.is_finite()
            && m.bin_size >= 1.0
            && m.bin_size <= f32::from(u16::MAX)
            && m.range_gain.is_finite()
            && m.range_gain > 0.0
            && m.range_offset.is_finite();
        if !valid {
            self.malformed("configuration", "zero sizes or non-finite calibration");
            return;
        }
        // Exactly as the protocol crate derives it from the wire's integers and f32s.
        let rotation_hz = f64::from(m.expected_rotation_rate) / 1000.0;
        self.geometry = Some(Arc::new(Geometry {
            azimuth_samples: m.azimuth_samples,
            range_in_bins: m.range_in_bins,
            bin_size_m: f64::from(m.bin_size.round() as u16) / 10_000.0,
            encoder_size: m.encoder_size,
            rotation_hz,
            packet_rate: (f64::from(m.azimuth_samples) * rotation_hz).round() as u16,
            range_gain: f64::from(m.range_gain),
            range_offset_m: f64::from(m.range_offset),
            data_width: BinWidth::Eight,
            range_resolution_m: None,
        }));
        self.counts.configurations += 1;
    }

    fn on_bscan(&mut self, m: RadarBScanMsg) {
        let Some(geometry) = self.geometry.clone() else {
            self.counts.before_configuration += 1;
            self.refuse("b-scan", "before any radar configuration");
            return;
        };
        let img = &m.b_scan_img;
        let (width, bytes_per_bin) = match img.encoding.as_str() {
            "8UC1" | "mono8" => (BinWidth::Eight, 1usize),
            "16UC1" | "mono16" if img.is_bigendian == 0 => (BinWidth::Sixteen, 2),
            _ => return self.malformed("b-scan", "encoding not 8UC1, mono8 or 16UC1 LE"),
        };
        let rows = img.height as usize;
        let step = img.step as usize;
        let row_bytes = (img.width as usize).saturating_mul(bytes_per_bin);
        let consistent = m.encoder_values.len() == rows
            && m.timestamps.len() == rows
            && row_bytes <= step
            && rows.checked_mul(step).is_some_and(|n| n <= img.data.len());
        if !consistent {
            return self.malformed(
                "b-scan",
                "image size, rows, encoder values and timestamps disagree",
            );
        }
        let geometry = if width == geometry.data_width {
            geometry
        } else {
            Arc::new(Geometry {
                data_width: width,
                ..(*geometry).clone()
            })
        };
        let data = Bytes::from(m.b_scan_img.data);
        let mut group = Vec::with_capacity(rows);
        let mut end_s = f64::NEG_INFINITY;
        for (row, (&encoder, &ns)) in m.encoder_values.iter().zip(&m.timestamps).enumerate() {
            if ns == 0 || encoder >= geometry.encoder_size {
                continue; // a row the radar never sent
            }
            let timestamp_s = Time::from_nanos(ns).as_secs_f64();
            end_s = end_s.max(timestamp_s);
            let mut az = Azimuth {
                encoder,
                angle_rad: geometry.azimuth_rad(encoder),
                timestamp_s,
                // A B-scan carries no sweep counters: numbered in order, as the radar does.
                sweep_counter: self.next_sweep,
                width,
                bins: data.slice(row * step..row * step + row_bytes),
                geometry: Arc::clone(&geometry),
                rotation: 0,
            };
            self.next_sweep = self.next_sweep.wrapping_add(1);
            self.numbering.number(&mut az);
            group.push(az);
        }
        self.counts.rotations += 1;
        self.hold(end_s, group);
    }

    fn on_fft(&mut self, m: RadarFftDataMsg) {
        let Some(geometry) = self.geometry.clone() else {
            self.counts.before_configuration += 1;
            self.refuse("fft data", "before any radar configuration");
            return;
        };
        if m.azimuth >= geometry.encoder_size {
            return self.malformed("fft data", "encoder value past the revolution");
        }
        let n = usize::from(m.data_length);
        let (width, bytes) = if m.data.len() == 2 * n && n > 0 {
            (BinWidth::Sixteen, 2 * n)
        } else {
            (BinWidth::Eight, n.min(m.data.len()))
        };
        let timestamp_s = Duration::new(
            u64::from(m.ntp_seconds),
            m.ntp_split_seconds.min(999_999_999),
        )
        .as_secs_f64();
        // Only the bins the message declares are held, in a buffer of their size: the
        // decoded message may carry far more (issue 38, item 4: a 141 KB file held 3.5 GB).
        let data = Bytes::copy_from_slice(m.data.get(..bytes).unwrap_or(&[]));
        let mut az = Azimuth {
            encoder: m.azimuth,
            angle_rad: geometry.azimuth_rad(m.azimuth),
            timestamp_s,
            sweep_counter: m.sweep_counter,
            width,
            bins: data,
            geometry,
            rotation: 0,
        };
        self.numbering.number(&mut az);
        self.hold(timestamp_s, vec![az]);
    }

    fn on_odometry(&mut self, record: OdometryRecord) {
        let timestamp_s = record.timestamp_s;
        if !self.odometry_closed {
            if self.odo_tx.send(record).is_ok() {
                self.counts.odometry += 1;
            } else {
                // The pipeline has let go of its odometry: the radar still plays.
                self.odometry_closed = true;
            }
        }
        self.latest_odometry_s = self.latest_odometry_s.max(timestamp_s);
        while self
            .pending
            .front()
            .is_some_and(|(end, _)| *end <= self.latest_odometry_s)
        {
            if let Some(group) = self.release() {
                self.send(group);
            }
        }
    }

    /// Holds radar data until the odometry reaches its time (or too much is held).
    fn hold(&mut self, end_s: f64, group: Vec<Azimuth>) {
        if end_s <= self.latest_odometry_s {
            self.send(group);
            return;
        }
        self.pending_bytes += group.iter().map(|a| a.bins.len()).sum::<usize>();
        self.pending.push_back((end_s, group));
        while self.pending_bytes > MAX_PENDING_BYTES {
            let Some(g) = self.release() else {
                break;
            };
            self.send(g);
        }
    }

    /// Takes the oldest held group.
    fn release(&mut self) -> Option<Vec<Azimuth>> {
        let (_, group) = self.pending.pop_front()?;
        let bytes: usize = group.iter().map(|a| a.bins.len()).sum();
        self.pending_bytes = self.pending_bytes.saturating_sub(bytes);
        Some(group)
    }

    fn send(&mut self, group: Vec<Azimuth>) {
        for az in group {
            if self.closed || self.az_tx.send(az).is_err() {
                self.closed = true;
                return;
            }
            self.counts.azimuths += 1;
        }
    }
}
