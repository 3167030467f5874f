//! The daemon's pipeline run on an MCAP recording: a recording it made replays to the same
//! trajectory bit for bit; a cut file, unknown schemas, wrong encodings and malformed CDR
//! cost their messages, are counted, and never stop the replay.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use crossbeam_channel::Receiver;
use protocol::{BinWidth, Geometry};
use radar_driver::{Azimuth, OdometryError, OdometryPoll, OdometryRecord, OdometrySource};
use ros_msgs::builtin::Time;
use ros_msgs::geometry::{Twist, TwistStamped, Vector3};
use ros_msgs::navtech::RadarBScanMsg;
use ros_msgs::std_msgs::Header;
use ros_msgs::{to_cdr, RosMessage};
use slam_node::daemon::mcap_replay::{self, McapReplayCounts, McapReplaySettings};
use slam_node::output::recording::{TOPIC_BSCAN, TOPIC_ODOMETRY_INPUT, TOPIC_POSE};
use slam_node::output::{OutputFiles, OutputHandle, RecordingFile};
use slam_node::pipeline::{run_pipeline, Pipeline, PipelineInputs, PipelineSettings, RunControl};

const T0: f64 = 1.7e9;
const AZIMUTHS: u64 = 200;
const ROTATIONS: u64 = 8;

/// Odometry from a list, all of it available at once.
#[derive(Debug)]
struct ListOdometry(std::vec::IntoIter<OdometryRecord>);

impl OdometrySource for ListOdometry {
    fn poll_next(&mut self, _timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        Ok(self
            .0
            .next()
            .map_or(OdometryPoll::Ended, OdometryPoll::Record))
    }
}

fn geometry() -> Arc<Geometry> {
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
fn azimuths() -> Vec<Azimuth> {
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

fn odometry() -> Vec<OdometryRecord> {
    (0..80)
        .map(|k| OdometryRecord {
            timestamp_s: T0 - 0.05 + f64::from(k) * 0.05,
            speed_mps: 1.0 + 0.01 * f64::from(k % 7),
            steer_rad: 0.002 * (f64::from(k) * 0.3).sin(),
        })
        .collect()
}

fn settings() -> PipelineSettings {
    PipelineSettings::from_config(&config::Config::default()).expect("valid")
}

/// Runs the pipeline loop as the daemon does, recording to `dir/name`.
fn run(
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

fn payloads(path: &Path, topic: &str) -> Vec<Vec<u8>> {
    let bytes = std::fs::read(path).expect("recording");
    mcap::MessageStream::new(&bytes)
        .expect("mcap")
        .map(|m| m.expect("message"))
        .filter(|m| m.channel.topic == topic)
        .map(|m| m.data.into_owned())
        .collect()
}

fn replay(
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

#[test]
fn a_recording_the_daemon_made_replays_to_the_same_trajectory_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (tx, rx) = crossbeam_channel::unbounded();
    for az in azimuths() {
        tx.send(az).expect("room");
    }
    drop(tx);
    let (live_tum, live_mcap) = run(
        dir.path(),
        "live",
        rx,
        Box::new(ListOdometry(odometry().into_iter())),
    );
    let (az, odo, handle) = replay(&live_mcap);
    let (replayed_tum, replayed_mcap) = run(dir.path(), "replayed", az, odo);
    let counts = handle.finish();
    assert_eq!(counts.rotations, ROTATIONS);
    assert_eq!(counts.azimuths, ROTATIONS * AZIMUTHS);
    assert_eq!(counts.odometry, 80);
    assert_eq!(counts.refused(), 0);
    assert_eq!(counts.file_error, None);
    let moved = live_tum
        .lines()
        .last()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|x| x.parse::<f64>().ok())
        .expect("a pose");
    assert!(moved.abs() > 1.0, "the vehicle moved: x {moved}");
    assert_eq!(replayed_tum, live_tum);
    // The estimated poses, covariances included, to the bit.
    let live = payloads(&live_mcap, TOPIC_POSE);
    assert_eq!(live.len() as u64, ROTATIONS);
    assert_eq!(payloads(&replayed_mcap, TOPIC_POSE), live);
    assert_eq!(
        payloads(&replayed_mcap, TOPIC_BSCAN),
        payloads(&live_mcap, TOPIC_BSCAN)
    );
}

/// A run of the pipeline over the test's azimuths and odometry, recorded: the MCAP file.
fn live_recording(dir: &Path) -> PathBuf {
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

fn replay_counts(path: &Path) -> McapReplayCounts {
    let (az, odo, handle) = replay(path);
    drop(odo);
    let n = az.iter().count() as u64;
    let counts = handle.finish();
    assert_eq!(n, counts.azimuths);
    counts
}

#[test]
fn a_recording_cut_by_a_crash_replays_up_to_the_cut_and_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = live_recording(dir.path());
    let bytes = std::fs::read(&path).expect("recording");
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write");
    let counts = replay_counts(&cut);
    assert!(counts.file_error.is_some(), "the cut is reported");
    assert!(
        counts.rotations > 0 && counts.rotations < ROTATIONS,
        "{counts:?}"
    );
    let garbage = dir.path().join("garbage.mcap");
    std::fs::write(&garbage, vec![0x5a; 4096]).expect("write");
    let counts = replay_counts(&garbage);
    assert!(counts.file_error.is_some());
    assert_eq!(counts.messages, 0);
}

#[test]
fn unknown_schemas_wrong_encodings_and_malformed_cdr_cost_their_messages_only() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("hostile.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(Cursor::new(Vec::new()))
        .expect("writer");
    let none = BTreeMap::new();
    let twist = w
        .add_schema(
            &TwistStamped::type_name(),
            "ros2msg",
            TwistStamped::schema_text().as_bytes(),
        )
        .expect("schema");
    let odo_ok = w
        .add_channel(twist, TOPIC_ODOMETRY_INPUT, "cdr", &none)
        .expect("channel");
    let odo_json = w
        .add_channel(twist, TOPIC_ODOMETRY_INPUT, "json", &none)
        .expect("channel");
    let proto = w
        .add_schema("navtech_msgs/msg/RadarBScanMsg", "protobuf", b"")
        .expect("schema");
    let scan_proto = w
        .add_channel(proto, TOPIC_BSCAN, "cdr", &none)
        .expect("channel");
    let scan_schema = w
        .add_schema(
            &RadarBScanMsg::type_name(),
            "ros2msg",
            RadarBScanMsg::schema_text().as_bytes(),
        )
        .expect("schema");
    let scan = w
        .add_channel(scan_schema, TOPIC_BSCAN, "cdr", &none)
        .expect("channel");
    let good = to_cdr(&TwistStamped {
        header: Header::new(Time::from_secs_f64(T0), "base_link"),
        twist: Twist {
            linear: Vector3 {
                x: 1.0,
                y: 0.0,
                z: 0.0,
            },
            angular: Vector3::default(),
        },
    })
    .expect("cdr");
    let mut write = |channel_id, data: &[u8]| {
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence: 0,
                log_time: 1,
                publish_time: 1,
            },
            data,
        )
        .expect("write");
    };
    write(odo_ok, &good);
    write(odo_json, b"{\"twist\": 1}");
    write(scan_proto, b"\x08\x01");
    write(scan, &[0, 1, 0, 0, 0xff, 0xff]); // truncated CDR
    write(scan, &to_cdr(&RadarBScanMsg::default()).expect("cdr")); // before any configuration
    write(odo_ok, &good[..good.len() - 3]);
    write(odo_ok, &good);
    w.finish().expect("finish");
    let bytes = w.into_inner().into_inner();
    std::fs::write(&path, bytes).expect("write");
    let (az, odo, handle) = replay(&path);
    let odometry = std::iter::from_fn({
        let mut odo = odo;
        move || match odo.poll_next(Duration::from_secs(5)) {
            Ok(OdometryPoll::Record(r)) => Some(r),
            _ => None,
        }
    })
    .count();
    drop(az);
    let counts = handle.finish();
    assert_eq!(counts.messages, 7);
    assert_eq!(odometry, 2);
    assert_eq!(counts.odometry, 2);
    assert_eq!(counts.wrong_encoding, 1);
    assert_eq!(counts.unknown_schema, 1);
    assert_eq!(counts.malformed, 2);
    assert_eq!(counts.before_configuration, 1);
    assert_eq!(counts.file_error, None);
}

/// A chunk whose uncompressed size disagrees with its data (8 bytes changed in a recording
/// the daemon made, or a small file claiming a 1 TiB chunk) used to spin the reader at
/// 100 % CPU for ever (issue 38, item 3): the reader now ends the replay there and says why
/// (mcap 0.26's chunk reader). Run on a thread with a bound, so a spin fails the test.
#[test]
fn a_chunk_whose_size_disagrees_with_its_data_ends_the_replay_and_says_why() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = live_recording(dir.path());
    let mut bytes = std::fs::read(&path).expect("recording");
    // Walk the records (opcode, u64 length, body) to the first chunk (0x06); its body starts
    // with start time, end time, then the uncompressed size.
    let mut pos = 8;
    let mut patched = false;
    while pos + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if bytes[pos] == 0x06 {
            let at = pos + 9 + 16;
            let size = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
            bytes[at..at + 8].copy_from_slice(&(size + 12_345).to_le_bytes());
            patched = true;
            break;
        }
        pos += 9 + len;
    }
    assert!(patched, "the recording has a chunk");
    let bad = dir.path().join("bad-chunk.mcap");
    std::fs::write(&bad, &bytes).expect("write");
    // A file of a few dozen bytes claiming a 1 TiB chunk.
    let mut tib = b"\x89MCAP0\r\n".to_vec();
    tib.extend([0x01]);
    tib.extend(8u64.to_le_bytes());
    tib.extend([0u8; 8]);
    let records = [0x28, 0xb5, 0x2f, 0xfd, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    let mut chunk = Vec::new();
    chunk.extend(0u64.to_le_bytes());
    chunk.extend(0u64.to_le_bytes());
    chunk.extend((1u64 << 40).to_le_bytes());
    chunk.extend(0u32.to_le_bytes());
    chunk.extend(4u32.to_le_bytes());
    chunk.extend(b"zstd");
    chunk.extend((records.len() as u64).to_le_bytes());
    chunk.extend(records);
    tib.extend([0x06]);
    tib.extend((chunk.len() as u64).to_le_bytes());
    tib.extend(chunk);
    let huge = dir.path().join("tib.mcap");
    std::fs::write(&huge, &tib).expect("write");
    for file in [bad, huge] {
        let (done_tx, done_rx) = crossbeam_channel::bounded(1);
        let f = file.clone();
        std::thread::spawn(move || {
            let _ = done_tx.send(replay_counts(&f));
        });
        let counts = done_rx
            .recv_timeout(std::time::Duration::from_secs(20))
            .unwrap_or_else(|_| panic!("{}: the replay did not end", file.display()));
        assert!(
            counts.file_error.is_some(),
            "{}: the bad chunk is reported: {counts:?}",
            file.display()
        );
        // It names the file and the chunk's offset in it.
        let error = counts.file_error.clone().unwrap_or_default();
        assert!(
            error.contains(&file.display().to_string())
                && error.contains("the chunk record at byte"),
            "{error}"
        );
        assert!(counts.rotations < ROTATIONS, "{counts:?}");
    }
}
