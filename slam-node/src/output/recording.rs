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
use ros_msgs::geometry::{
    Point, Pose, PoseWithCovariance, Quaternion, Transform, TransformStamped, Twist, TwistStamped,
    TwistWithCovariance, Vector3,
};
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg};
use ros_msgs::sensor::{Image, PointCloud2};
use ros_msgs::std_msgs::{ColorRGBA, Header};
use ros_msgs::visualization::{Marker, MarkerArray};
use ros_msgs::{to_cdr, CdrError, RosMessage};
use slam_filter::OdometrySample;

use super::detections::RotationDetections;
use super::map::MapSnapshot;
use super::trajectory::PoseSample;
use super::writer::OutputEvent;

/// Topic of the radar's rotations.
pub const TOPIC_BSCAN: &str = "/radar_data/b_scan_msg";
/// Topic of the radar's configuration.
pub const TOPIC_RADAR_CONFIGURATION: &str = "/radar_data/configuration_data";
/// Topic of the odometry the pipeline took.
pub const TOPIC_ODOMETRY_INPUT: &str = "/odom/twist";
/// Topic of the estimated pose.
pub const TOPIC_POSE: &str = "/slam/odometry";
/// Topic of the transforms.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the static transforms.
pub const TOPIC_TF_STATIC: &str = "/tf_static";
/// Topic of the map's features.
pub const TOPIC_MAP: &str = "/slam/map";
/// Topic of the map's covariance ellipses.
pub const TOPIC_MAP_COVARIANCE: &str = "/slam/map_covariance";
/// Topic of each rotation's detections.
pub const TOPIC_DETECTIONS: &str = "/slam/detections";

/// The world frame.
pub const MAP_FRAME: &str = "map";
/// The vehicle's frame.
pub const BASE_FRAME: &str = "base_link";
/// The radar's frame.
pub const RADAR_FRAME: &str = "radar";

/// A B-scan larger than this (from a radar configuration claiming absurd sizes) is not
/// assembled: the rotation is counted as skipped.
const MAX_BSCAN_BYTES: usize = 64 << 20;
/// Chi-square 95% quantile with 2 degrees of freedom: the ellipses' scale.
const CHI2_2DOF_95: f64 = 5.991;

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

/// One rotation's azimuths being laid out as a B-scan.
#[derive(Debug)]
struct BScan {
    rotation: u64,
    geometry: Arc<Geometry>,
    bytes_per_bin: usize,
    width: usize,
    data: Vec<u8>,
    encoders: Vec<u16>,
    stamps: Vec<u64>,
    last_time_s: f64,
    rows: usize,
}

impl BScan {
    fn new(az: &Azimuth) -> Option<Self> {
        let g = &az.geometry;
        let height = usize::from(g.azimuth_samples);
        let width = usize::from(g.range_in_bins);
        let bytes_per_bin = az.width.bytes_per_bin();
        let size = height.checked_mul(width)?.checked_mul(bytes_per_bin)?;
        if size == 0 || size > MAX_BSCAN_BYTES {
            return None;
        }
        Some(Self {
            rotation: az.rotation,
            geometry: Arc::clone(&az.geometry),
            bytes_per_bin,
            width,
            data: vec![0; size],
            encoders: vec![0; height],
            stamps: vec![0; height],
            last_time_s: az.timestamp_s,
            rows: 0,
        })
    }

    fn fits(&self, az: &Azimuth) -> bool {
        az.rotation == self.rotation
            && az.width.bytes_per_bin() == self.bytes_per_bin
            && (Arc::ptr_eq(&az.geometry, &self.geometry) || *az.geometry == *self.geometry)
    }

    fn push(&mut self, az: &Azimuth) {
        let Some(row) = self.geometry.azimuth_index(az.encoder).map(usize::from) else {
            return;
        };
        let step = self.width * self.bytes_per_bin;
        let (Some(dst), Some(enc), Some(stamp)) = (
            self.data.get_mut(row * step..(row + 1) * step),
            self.encoders.get_mut(row),
            self.stamps.get_mut(row),
        ) else {
            return;
        };
        let n = az.bins.len().min(step);
        dst[..n].copy_from_slice(&az.bins[..n]);
        dst[n..].fill(0);
        *enc = az.encoder;
        *stamp = secs_to_nanos(az.timestamp_s);
        self.last_time_s = self.last_time_s.max(az.timestamp_s);
        self.rows += 1;
    }

    fn into_message(self) -> RadarBScanMsg {
        let step = self.width * self.bytes_per_bin;
        RadarBScanMsg {
            b_scan_img: Image {
                header: Header::new(Time::from_secs_f64(self.last_time_s), RADAR_FRAME),
                height: u32::from(self.geometry.azimuth_samples),
                width: u32::from(self.geometry.range_in_bins),
                encoding: if self.bytes_per_bin == 2 {
                    "16UC1".into()
                } else {
                    "8UC1".into()
                },
                is_bigendian: 0,
                step: u32::try_from(step).unwrap_or(u32::MAX),
                data: self.data,
            },
            encoder_values: self.encoders,
            timestamps: self.stamps,
        }
    }
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

/// The yaw rate (rad/s) an odometry sample stands for under `motion`. With the paper's
/// model the value is chosen among the nearest floats so that [`steer_from_yaw_rate`] gives
/// the sample's steering back bit for bit (a recording replays to the same trajectory).
pub fn yaw_rate(motion: &MotionModel, s: &OdometrySample) -> f64 {
    match *motion {
        MotionModel::Paper { step_s } if step_s > 0.0 => {
            let guess = s.steer_rad / step_s;
            if !guess.is_finite() {
                return guess;
            }
            (0..=8i64)
                .flat_map(|d| [d, -d])
                .map(|d| f64::from_bits(guess.to_bits().wrapping_add_signed(d)))
                .find(|y| y.is_finite() && y * step_s == s.steer_rad)
                .unwrap_or(guess)
        }
        MotionModel::Bicycle { wheelbase_m } if wheelbase_m > 0.0 => {
            s.speed_mps * s.steer_rad.tan() / wheelbase_m
        }
        _ => 0.0,
    }
}

/// The steering input a yaw rate stands for under `motion` (the inverse of [`yaw_rate`]):
/// `yaw_rate * step_s` for the paper's model, `atan(yaw_rate * wheelbase / speed)` for the
/// bicycle (0 when the speed is below 1 mm/s).
pub fn steer_from_yaw_rate(motion: &MotionModel, speed_mps: f64, yaw_rate_rps: f64) -> f64 {
    match *motion {
        MotionModel::Paper { step_s } => yaw_rate_rps * step_s,
        MotionModel::Bicycle { wheelbase_m } => {
            if speed_mps.abs() < 1e-3 {
                0.0
            } else {
                (yaw_rate_rps * wheelbase_m / speed_mps).atan()
            }
        }
    }
}

/// The pose's 3x3 covariance over (x, y, theta) placed in ROS's 6x6 over (x, y, z, roll,
/// pitch, yaw); the plane's other three are left 0.
fn covariance6(c: &[[f64; 3]; 3]) -> [f64; 36] {
    let mut out = [0.0; 36];
    let at = [0usize, 1, 5];
    for (r, row) in c.iter().enumerate() {
        for (k, v) in row.iter().enumerate() {
            out[at[r] * 6 + at[k]] = *v;
        }
    }
    out
}

/// Semi-axes (1 sigma) and the major axis's angle of a 2x2 covariance.
fn ellipse(c: &[[f64; 4]; 4]) -> (f64, f64, f64) {
    let (a, b, d) = (c[0][0], c[0][1], c[1][1]);
    let mean = 0.5 * (a + d);
    let diff = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let major = (mean + diff).max(0.0).sqrt();
    let minor = (mean - diff).max(0.0).sqrt();
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    (major, minor, angle)
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
            let tf = TFMessage {
                transforms: vec![TransformStamped {
                    header: Header::new(Time::from_nanos(ns), BASE_FRAME),
                    child_frame_id: RADAR_FRAME.into(),
                    transform: Transform::default(),
                }],
            };
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
            OutputEvent::Spectrum(_) | OutputEvent::Truth(_) | OutputEvent::Trajectory(_) => Ok(()),
        }
    }

    fn on_azimuth(&mut self, az: &Azimuth) -> Result<(), RecordingError> {
        let changed = self.geometry.as_ref().map_or(true, |g| {
            !(Arc::ptr_eq(g, &az.geometry) || **g == *az.geometry)
        });
        if changed {
            self.geometry = Some(Arc::clone(&az.geometry));
            let g = &az.geometry;
            let msg = RadarConfigurationMsg {
                header: Header::new(Time::from_secs_f64(az.timestamp_s), RADAR_FRAME),
                azimuth_samples: g.azimuth_samples,
                encoder_size: g.encoder_size,
                azimuth_offset: 0,
                // As Navtech's driver fills it: the wire's tenths of a millimetre.
                bin_size: (g.bin_size_m * 1e4).round() as f32,
                range_in_bins: g.range_in_bins,
                expected_rotation_rate: (g.rotation_hz * 1000.0).round().clamp(0.0, 65535.0) as u16,
                range_gain: g.range_gain as f32,
                range_offset: g.range_offset_m as f32,
            };
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
        if b.rows == 0 {
            return Ok(());
        }
        let time_s = b.last_time_s;
        let period_s = 1.0 / b.geometry.rotation_hz.max(1e-3);
        let (first, _) = *self.radar_span_s.get_or_insert((time_s - period_s, time_s));
        self.radar_span_s = Some((first, time_s));
        let msg = b.into_message();
        self.write(self.channels.bscan, time_s, &msg)?;
        self.summary.rotations += 1;
        Ok(())
    }

    fn on_odometry(&mut self, s: &OdometrySample) -> Result<(), RecordingError> {
        self.last_input = Some(*s);
        let msg = TwistStamped {
            header: Header::new(Time::from_secs_f64(s.timestamp_s), BASE_FRAME),
            twist: Twist {
                linear: Vector3 {
                    x: s.speed_mps,
                    y: 0.0,
                    z: 0.0,
                },
                angular: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: yaw_rate(&self.motion, s),
                },
            },
        };
        self.write(self.channels.odometry_input, s.timestamp_s, &msg)
    }

    fn on_pose(&mut self, p: &PoseSample) -> Result<(), RecordingError> {
        let stamp = Time::from_secs_f64(p.timestamp_s);
        let pose = Pose {
            position: Point {
                x: p.x_m,
                y: p.y_m,
                z: 0.0,
            },
            orientation: Quaternion::from_yaw(p.theta_rad),
        };
        // The twist is the odometry input in force (not estimated): covariance 0.
        let twist = self.last_input.map_or(Twist::default(), |s| Twist {
            linear: Vector3 {
                x: s.speed_mps,
                y: 0.0,
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: yaw_rate(&self.motion, &s),
            },
        });
        let msg = Odometry {
            header: Header::new(stamp, MAP_FRAME),
            child_frame_id: BASE_FRAME.into(),
            pose: PoseWithCovariance {
                pose,
                covariance: covariance6(&p.covariance),
            },
            twist: TwistWithCovariance {
                twist,
                covariance: [0.0; 36],
            },
        };
        self.write(self.channels.pose, p.timestamp_s, &msg)?;
        let tf = TFMessage {
            transforms: vec![TransformStamped {
                header: Header::new(stamp, MAP_FRAME),
                child_frame_id: BASE_FRAME.into(),
                transform: Transform {
                    translation: Vector3 {
                        x: p.x_m,
                        y: p.y_m,
                        z: 0.0,
                    },
                    rotation: pose.orientation,
                },
            }],
        };
        self.write(self.channels.tf, p.timestamp_s, &tf)
    }

    fn on_map(&mut self, m: &MapSnapshot) -> Result<(), RecordingError> {
        let stamp = Time::from_secs_f64(m.timestamp_s);
        let points: Vec<Vec<f32>> = m
            .features
            .iter()
            .map(|f| {
                vec![
                    f.x_m as f32,
                    f.y_m as f32,
                    0.0,
                    f.rho as f32,
                    f.alpha as f32,
                ]
            })
            .collect();
        let cloud = PointCloud2::from_f32_points(
            Header::new(stamp, MAP_FRAME),
            &["x", "y", "z", "reflectivity", "absorption"],
            &points,
        );
        self.write(self.channels.map, m.timestamp_s, &cloud)?;
        let header = Header::new(stamp, MAP_FRAME);
        let mut markers = Vec::with_capacity(m.features.len() + 1);
        markers.push(Marker {
            header: header.clone(),
            ns: "covariance".into(),
            action: Marker::DELETEALL,
            ..Marker::default()
        });
        let k = CHI2_2DOF_95.sqrt();
        for f in &m.features {
            let (major, minor, angle) = ellipse(&f.covariance);
            markers.push(Marker {
                header: header.clone(),
                ns: "covariance".into(),
                id: i32::try_from(f.id).unwrap_or(i32::MAX),
                type_: Marker::CYLINDER,
                action: Marker::ADD,
                pose: Pose {
                    position: Point {
                        x: f.x_m,
                        y: f.y_m,
                        z: 0.0,
                    },
                    orientation: Quaternion::from_yaw(angle),
                },
                scale: Vector3 {
                    x: (2.0 * k * major).max(1e-3),
                    y: (2.0 * k * minor).max(1e-3),
                    z: 0.05,
                },
                color: ColorRGBA {
                    r: f.rho.clamp(0.0, 1.0) as f32,
                    g: f.alpha.clamp(0.0, 1.0) as f32,
                    b: 0.3,
                    a: 0.6,
                },
                ..Marker::default()
            });
        }
        self.write(
            self.channels.map_covariance,
            m.timestamp_s,
            &MarkerArray { markers },
        )
    }

    fn on_detections(&mut self, d: &RotationDetections) -> Result<(), RecordingError> {
        let points: Vec<Vec<f32>> = d
            .detections
            .iter()
            .map(|t| {
                let (x, y) = t.xy_ros();
                vec![x as f32, y as f32, 0.0, t.power_db as f32]
            })
            .collect();
        let cloud = PointCloud2::from_f32_points(
            Header::new(Time::from_secs_f64(d.timestamp_s), RADAR_FRAME),
            &["x", "y", "z", "power_db"],
            &points,
        );
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
