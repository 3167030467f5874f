//! The run recorded as an MCAP file in ROS 2 encodings (schema encoding `ros2msg`, message
//! encoding `cdr`), readable by `ros2 bag`, Foxglove, `rosbags` and the `mcap` tools without
//! our code. It runs on the writer thread, fed the same [`OutputEvent`]s as the other files
//! plus the radar's azimuths and the odometry the pipeline took.
//!
//! | topic | type | when |
//! |---|---|---|
//! | `/radar_data/b_scan_msg` | `navtech_msgs/msg/RadarBScanMsg` | each rotation |
//! | `/radar_data/configuration_data` | `navtech_msgs/msg/RadarConfigurationMsg` | first azimuth, and when the geometry changes |
//! | `/odom/twist` | `geometry_msgs/msg/TwistStamped` | each odometry sample the pipeline took |
//! | `/slam/odometry` | `nav_msgs/msg/Odometry` | each rotation: the estimated pose with covariance |
//! | `/tf` | `tf2_msgs/msg/TFMessage` | each rotation: `map` to `base_link` |
//! | `/tf_static` | `tf2_msgs/msg/TFMessage` | once: `base_link` to `radar` (identity: the radar is at the vehicle's origin) |
//! | `/slam/map` | `sensor_msgs/msg/PointCloud2` | each map snapshot: x, y, z, reflectivity, absorption |
//! | `/slam/map_covariance` | `visualization_msgs/msg/MarkerArray` | each map snapshot: 95% position ellipses |
//! | `/slam/detections` | `sensor_msgs/msg/PointCloud2` | each rotation: x, y, z, power_db in `radar` |
//!
//! Radar data goes out as Navtech's B-scan, one message a rotation, rather than one
//! `RadarFftDataMsg` per azimuth: 4 records a second instead of 1600 (per-record overhead
//! and index size), the rotation is the unit the daemon works in, and Navtech's own
//! `b_scan_extended_publisher` writes the same layout (a row per azimuth at its index, a
//! column per bin, `8UC1`; `16UC1` little-endian for 16-bit radars; rows never received are
//! zero with timestamp 0).
//!
//! Each rotation closes a chunk (zstd level 1, single-threaded: on simulated CTS350-X
//! B-scans 0.72 of their size at 2.7 ms a rotation, against lz4's 0.975 at 2 ms) and
//! flushes it to the file, so a crash loses at most
//! the rotation in progress: a reader that reads records in order (`mcap` crate's
//! `MessageStream`, Python's `StreamReader`) gets every complete chunk before the cut.
//!
//! Times: `log_time` and `publish_time` are the data's own stream time (the radar's clock),
//! in nanoseconds.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use protocol::Geometry;
use radar_driver::Azimuth;
use radar_model::motion::MotionModel;
use ros_msgs::builtin::{secs_to_nanos, Time};
use ros_msgs::geometry::TwistStamped;
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg};
use ros_msgs::sensor::PointCloud2;
use ros_msgs::visualization::MarkerArray;
use ros_msgs::{to_cdr, CdrError, RosMessage};
use slam_filter::OdometrySample;

use super::detections::RotationDetections;
use super::event::OutputEvent;
use super::map::MapSnapshot;
use super::ros::{self, BScan};
pub use super::ros::{
    steer_from_yaw_rate, yaw_rate, BASE_FRAME, MAP_FRAME, RADAR_FRAME, TOPIC_BSCAN,
    TOPIC_DETECTIONS, TOPIC_MAP, TOPIC_MAP_COVARIANCE, TOPIC_ODOMETRY_INPUT, TOPIC_POSE,
    TOPIC_RADAR_CONFIGURATION, TOPIC_TF, TOPIC_TF_STATIC,
};
use super::trajectory::PoseSample;

/// Why the recording failed (the daemon logs it and carries on without the recording).
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be created.
    #[error("creating {path}")]
    Create {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP writer failed (disk full, IO error).
    #[error("writing the MCAP file")]
    Mcap(#[from] mcap::McapError),
    /// A message could not be encoded.
    #[error("encoding a message for {topic}")]
    Cdr {
        /// The topic.
        topic: &'static str,
        /// The cause.
        #[source]
        source: CdrError,
    },
}

/// What the recording holds and what it cost.
#[derive(Debug, Clone, Default)]
pub struct RecordingSummary {
    /// The file.
    pub path: PathBuf,
    /// Messages written per topic.
    pub messages: BTreeMap<String, u64>,
    /// File size at the end, bytes.
    pub bytes: u64,
    /// Radar stream time from the first B-scan to the last, seconds (plus one rotation's
    /// period, so that one rotation of a 4 Hz radar counts as 0.25 s).
    pub stream_s: f64,
    /// Rotations written (B-scans).
    pub rotations: u64,
    /// Rotations whose B-scan was refused (geometry too large or unusable).
    pub rotations_skipped: u64,
    /// Wall time the recorder spent per rotation, ms (encoding, compressing, writing).
    pub write_ms: Vec<f64>,
    /// The pipeline's processing time of the same rotations, ms (from the diagnostics).
    pub processing_ms: Vec<f64>,
}

impl RecordingSummary {
    /// Messages written over all topics.
    pub fn total_messages(&self) -> u64 {
        self.messages.values().sum()
    }

    /// File size per minute of stream, MB (1e6 bytes).
    pub fn mb_per_minute(&self) -> Option<f64> {
        (self.stream_s > 0.0).then(|| self.bytes as f64 / 1e6 / (self.stream_s / 60.0))
    }
}

#[derive(Debug, Clone, Copy)]
struct Channel {
    id: u16,
    topic: &'static str,
}

#[derive(Debug)]
struct Channels {
    bscan: Channel,
    configuration: Channel,
    odometry_input: Channel,
    pose: Channel,
    tf: Channel,
    tf_static: Channel,
    map: Channel,
    map_covariance: Channel,
    detections: Channel,
}

/// Writes the recording; generic over the sink so tests can record to memory.
pub struct McapRecorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    channels: Channels,
    sequences: BTreeMap<u16, u32>,
    motion: MotionModel,
    bscan: Option<BScan>,
    geometry: Option<Arc<Geometry>>,
    last_input: Option<OdometrySample>,
    busy: Duration,
    first_ns: Option<u64>,
    radar_span_s: Option<(f64, f64)>,
    summary: RecordingSummary,
}

impl<W: Write + Seek> std::fmt::Debug for McapRecorder<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRecorder")
            .field("path", &self.summary.path)
            .field("rotations", &self.summary.rotations)
            .finish_non_exhaustive()
    }
}

fn channel<W: Write + Seek, M: RosMessage>(
    writer: &mut mcap::Writer<W>,
    topic: &'static str,
) -> Result<Channel, RecordingError> {
    let schema = writer.add_schema(&M::type_name(), "ros2msg", M::schema_text().as_bytes())?;
    let id = writer.add_channel(schema, topic, "cdr", &BTreeMap::new())?;
    Ok(Channel { id, topic })
}

impl<W: Write + Seek> McapRecorder<W> {
    /// Starts a recording into `sink`; `motion` turns the odometry's steering input into a
    /// yaw rate for `/odom/twist`.
    pub fn new(sink: W, path: PathBuf, motion: MotionModel) -> Result<Self, RecordingError> {
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("slam-node ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            // On the writer thread: no compression threads competing with the pipeline.
            .compression_threads(0)
            .chunk_size(None)
            .create(sink)?;
        let channels = Channels {
            bscan: channel::<W, RadarBScanMsg>(&mut writer, TOPIC_BSCAN)?,
            configuration: channel::<W, RadarConfigurationMsg>(
                &mut writer,
                TOPIC_RADAR_CONFIGURATION,
            )?,
            odometry_input: channel::<W, TwistStamped>(&mut writer, TOPIC_ODOMETRY_INPUT)?,
            pose: channel::<W, Odometry>(&mut writer, TOPIC_POSE)?,
            tf: channel::<W, TFMessage>(&mut writer, TOPIC_TF)?,
            tf_static: channel::<W, TFMessage>(&mut writer, TOPIC_TF_STATIC)?,
            map: channel::<W, PointCloud2>(&mut writer, TOPIC_MAP)?,
            map_covariance: channel::<W, MarkerArray>(&mut writer, TOPIC_MAP_COVARIANCE)?,
            detections: channel::<W, PointCloud2>(&mut writer, TOPIC_DETECTIONS)?,
        };
        Ok(Self {
            writer,
            channels,
            sequences: BTreeMap::new(),
            motion,
            bscan: None,
            geometry: None,
            last_input: None,
            busy: Duration::ZERO,
            first_ns: None,
            radar_span_s: None,
            summary: RecordingSummary {
                path,
                ..RecordingSummary::default()
            },
        })
    }

    fn write<M: RosMessage>(
        &mut self,
        channel: Channel,
        time_s: f64,
        msg: &M,
    ) -> Result<(), RecordingError> {
        let data = to_cdr(msg).map_err(|source| RecordingError::Cdr {
            topic: channel.topic,
            source,
        })?;
        let ns = secs_to_nanos(time_s);
        let sequence = self.sequences.entry(channel.id).or_insert(0);
        *sequence = sequence.wrapping_add(1);
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel.id,
                sequence: *sequence,
                log_time: ns,
                publish_time: ns,
            },
            &data,
        )?;
        if self.first_ns.is_none() {
            self.first_ns = Some(ns);
            let tf = ros::tf_static(Time::from_nanos(ns));
            let data = to_cdr(&tf).map_err(|source| RecordingError::Cdr {
                topic: TOPIC_TF_STATIC,
                source,
            })?;
            self.writer.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: self.channels.tf_static.id,
                    sequence: 1,
                    log_time: ns,
                    publish_time: ns,
                },
                &data,
            )?;
            *self
                .summary
                .messages
                .entry(TOPIC_TF_STATIC.to_string())
                .or_insert(0) += 1;
        }
        *self
            .summary
            .messages
            .entry(channel.topic.to_string())
            .or_insert(0) += 1;
        Ok(())
    }

    /// Records what `event` carries; the time spent counts against the current rotation.
    pub fn on_event(&mut self, event: &OutputEvent) -> Result<(), RecordingError> {
        let started = Instant::now();
        let result = self.handle(event);
        self.busy += started.elapsed();
        if let OutputEvent::Rotation(d) = event {
            self.summary.write_ms.push(self.busy.as_secs_f64() * 1e3);
            self.summary.processing_ms.push(d.total_ms);
            self.busy = Duration::ZERO;
        }
        result
    }

    fn handle(&mut self, event: &OutputEvent) -> Result<(), RecordingError> {
        match event {
            OutputEvent::Azimuth(az) => self.on_azimuth(az),
            OutputEvent::Odometry(s) => self.on_odometry(s),
            OutputEvent::Pose(p) => self.on_pose(p),
            OutputEvent::Map(m) => self.on_map(m),
            OutputEvent::Detections(d) => self.on_detections(d),
            OutputEvent::Rotation(_) => {
                self.close_bscan()?;
                // Close the chunk and hand it to the OS: a crash keeps it.
                self.writer.flush()?;
                Ok(())
            }
            OutputEvent::Spectrum(_)
            | OutputEvent::Truth(_)
            | OutputEvent::OdometryPose(_)
            | OutputEvent::Trajectory(_)
            | OutputEvent::SavedMap(_) => Ok(()),
        }
    }

    fn on_azimuth(&mut self, az: &Azimuth) -> Result<(), RecordingError> {
        let changed = self
            .geometry
            .as_ref()
            .is_none_or(|g| !(Arc::ptr_eq(g, &az.geometry) || **g == *az.geometry));
        if changed {
            self.geometry = Some(Arc::clone(&az.geometry));
            let msg = ros::radar_configuration(az);
            self.write(self.channels.configuration, az.timestamp_s, &msg)?;
        }
        if self.bscan.as_ref().is_some_and(|b| !b.fits(az)) {
            self.close_bscan()?;
        }
        if self.bscan.is_none() {
            self.bscan = BScan::new(az);
            if self.bscan.is_none() {
                self.summary.rotations_skipped += 1;
                return Ok(());
            }
        }
        if let Some(b) = self.bscan.as_mut() {
            b.push(az);
        }
        Ok(())
    }

    fn close_bscan(&mut self) -> Result<(), RecordingError> {
        let Some(b) = self.bscan.take() else {
            return Ok(());
        };
        if b.rows() == 0 {
            return Ok(());
        }
        let time_s = b.last_time_s();
        let period_s = 1.0 / b.rotation_hz().max(1e-3);
        let (first, _) = *self.radar_span_s.get_or_insert((time_s - period_s, time_s));
        self.radar_span_s = Some((first, time_s));
        let msg = b.into_message();
        self.write(self.channels.bscan, time_s, &msg)?;
        self.summary.rotations += 1;
        Ok(())
    }

    fn on_odometry(&mut self, s: &OdometrySample) -> Result<(), RecordingError> {
        self.last_input = Some(*s);
        let msg = ros::odometry_input(&self.motion, s);
        self.write(self.channels.odometry_input, s.timestamp_s, &msg)
    }

    fn on_pose(&mut self, p: &PoseSample) -> Result<(), RecordingError> {
        let (odometry, tf) = ros::pose_messages(p, self.last_input.as_ref(), &self.motion);
        self.write(self.channels.pose, p.timestamp_s, &odometry)?;
        self.write(self.channels.tf, p.timestamp_s, &tf)
    }

    fn on_map(&mut self, m: &MapSnapshot) -> Result<(), RecordingError> {
        let (cloud, markers) = ros::map_messages(m);
        self.write(self.channels.map, m.timestamp_s, &cloud)?;
        self.write(self.channels.map_covariance, m.timestamp_s, &markers)
    }

    fn on_detections(&mut self, d: &RotationDetections) -> Result<(), RecordingError> {
        let cloud = ros::detections_message(d);
        self.write(self.channels.detections, d.timestamp_s, &cloud)
    }

    /// Writes the rotation in progress, the summary section and the footer; returns the
    /// sink and what was recorded.
    pub fn finish(mut self) -> Result<(W, RecordingSummary), RecordingError> {
        self.close_bscan()?;
        self.writer.finish()?;
        let mut sink = self.writer.into_inner();
        let mut summary = self.summary;
        summary.bytes = sink.stream_position().unwrap_or(0);
        summary.stream_s = self
            .radar_span_s
            .map_or(0.0, |(first, last)| (last - first).max(0.0));
        Ok((sink, summary))
    }
}
