//! Shared by the MCAP replay tests: a small radar's rotations and odometry, the daemon's
//! pipeline run over them with an MCAP recording, and a replay of a recording.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use crossbeam_channel::Receiver;
use protocol::{BinWidth, Geometry};
use radar_driver::{Azimuth, OdometryError, OdometryPoll, OdometryRecord, OdometrySource};
use slam_node::daemon::mcap_replay::{self, McapReplayCounts, McapReplaySettings};
use slam_node::output::{OutputFiles, OutputHandle, RecordingFile};
use slam_node::pipeline::{run_pipeline, Pipeline, PipelineInputs, PipelineSettings, RunControl};

pub const T0: f64 = 1.7e9;
pub const AZIMUTHS: u64 = 200;
pub const ROTATIONS: u64 = 8;
/// Rotations a pose is published for: the first two hold no detection, so no beam brings
/// the odometry into the filter and its clock has not started (a pose then would carry no
/// time).
pub const POSED_ROTATIONS: u64 = ROTATIONS - 2;

/// The TUM trajectory's timestamps (comment lines skipped).
pub fn tum_stamps(tum: &str) -> Vec<f64> {
    tum.lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| l.split(' ').next()?.parse().ok())
        .collect()
}

/// Odometry from a list, all of it available at once.
#[derive(Debug)]
pub struct ListOdometry(pub std::vec::IntoIter<OdometryRecord>);

impl OdometrySource for ListOdometry {
    fn poll_next(&mut self, _timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        Ok(self
            .0
            .next()
            .map_or(OdometryPoll::Ended, OdometryPoll::Record))
    }
}

pub fn geometry() -> Arc<Geometry> {
    Arc::new(Geometry {
        azimuth_samples: 200,
        range_in_bins: 800,
        bin_size_m: 0.25,
        encoder_size: 5600,
        rotation_hz: 2.5,
        packet_rate: 500,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data_width: BinWidth::Eight,
        range_resolution_m: None,
    })
}

/// Rotations of a 200-azimuth radar seeing a few posts (bright bins at azimuth-dependent
/// ranges) over a noise floor.
pub fn azimuths() -> Vec<Azimuth> {
    let g = geometry();
    (0..ROTATIONS * AZIMUTHS)
        .map(|k| {
            let index = k % AZIMUTHS;
            let encoder = u16::try_from(index * 28).expect("fits");
            let mut bins: Vec<u8> = (0..800u64)
                .map(|b| 40 + ((b * 31 + k * 7) % 9) as u8)
                .collect();
            for (centre, post) in [(20u64, 80usize), (70, 120), (130, 60), (170, 150)] {
                if index.abs_diff(centre) <= 2 {
                    for b in bins.iter_mut().skip(post).take(3) {
                        *b = 200;
                    }
                }
            }
            Azimuth {
                encoder,
                angle_rad: g.azimuth_rad(encoder),
                timestamp_s: T0 + k as f64 / 500.0,
                sweep_counter: u16::try_from(k % 65536).expect("fits"),
                width: BinWidth::Eight,
                bins: Bytes::from(bins),
                geometry: Arc::clone(&g),
                rotation: k / AZIMUTHS,
            }
        })
        .collect()
}

pub fn odometry() -> Vec<OdometryRecord> {
    (0..80)
        .map(|k| OdometryRecord {
            timestamp_s: T0 - 0.05 + f64::from(k) * 0.05,
            speed_mps: 1.0 + 0.01 * f64::from(k % 7),
            steer_rad: 0.002 * (f64::from(k) * 0.3).sin(),
        })
        .collect()
}

pub fn settings() -> PipelineSettings {
    PipelineSettings::from_config(&config::Config::default()).expect("valid")
}

/// Runs the pipeline loop as the daemon does, recording to `dir/name`.
pub fn run(
    dir: &Path,
    name: &str,
    azimuths: Receiver<Azimuth>,
    odometry: Box<dyn OdometrySource>,
) -> (String, PathBuf) {
    let settings = settings();
    let mut files = OutputFiles::in_dir(dir.join(name));
    files.figures = false;
    let recording = dir.join(name).join("run.mcap");
    files.recording = Some(RecordingFile {
        path: recording.clone(),
        motion: settings.motion,
    });
    let output = OutputHandle::spawn(files).expect("writer");
    let pipeline = Pipeline::new(settings, None, None).expect("pipeline");
    let report = run_pipeline(
        pipeline,
        PipelineInputs {
            azimuths,
            odometry: Some(odometry),
            gyro: None,
            priors: None,
        },
        &output,
        RunControl {
            stop: Arc::new(AtomicBool::new(false)),
            end_after_silence: None,
            played_out: None,
            max_stream_s: None,
            progress: None,
        },
    );
    assert!(report.summary.beams > 0, "beams reached the filter");
    let summary = output.finish().expect("outputs written");
    assert!(
        summary.recording_error.is_none(),
        "{:?}",
        summary.recording_error
    );
    let tum = std::fs::read_to_string(dir.join(name).join("trajectory.tum")).expect("tum");
    (tum, recording)
}

pub fn payloads(path: &Path, topic: &str) -> Vec<Vec<u8>> {
    let bytes = std::fs::read(path).expect("recording");
    mcap::MessageStream::new(&bytes)
        .expect("mcap")
        .map(|m| m.expect("message"))
        .filter(|m| m.channel.topic == topic)
        .map(|m| m.data.into_owned())
        .collect()
}

pub fn replay(
    path: &Path,
) -> (
    Receiver<Azimuth>,
    Box<dyn OdometrySource>,
    mcap_replay::McapReplayHandle,
) {
    let (az, odo, handle) = mcap_replay::start(McapReplaySettings::new(
        path.to_path_buf(),
        settings().motion,
    ))
    .expect("replay starts");
    (az, Box::new(odo), handle)
}

/// A run of the pipeline over the test's azimuths and odometry, recorded: the MCAP file.
pub fn live_recording(dir: &Path) -> PathBuf {
    let (tx, rx) = crossbeam_channel::unbounded();
    for az in azimuths() {
        tx.send(az).expect("room");
    }
    drop(tx);
    run(
        dir,
        "live",
        rx,
        Box::new(ListOdometry(odometry().into_iter())),
    )
    .1
}

pub fn replay_counts(path: &Path) -> McapReplayCounts {
    let (az, odo, handle) = replay(path);
    drop(odo);
    let n = az.iter().count() as u64;
    let counts = handle.finish();
    assert_eq!(n, counts.azimuths);
    counts
}

/// A `ros2msg` schema for `M` and a CDR channel on `topic` carrying it, in `w`.
pub fn ros2_channel<M: ros_msgs::RosMessage, W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    topic: &str,
) -> u16 {
    let schema = w
        .add_schema(&M::type_name(), "ros2msg", M::schema_text().as_bytes())
        .expect("schema");
    w.add_channel(schema, topic, "cdr", &std::collections::BTreeMap::new())
        .expect("channel")
}

/// One message of `data` on `channel`, logged and published at time 1.
pub fn write_message<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    channel: u16,
    data: &[u8],
) {
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 0,
            log_time: 1,
            publish_time: 1,
        },
        data,
    )
    .expect("write");
}
