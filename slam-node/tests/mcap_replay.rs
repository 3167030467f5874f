//! The daemon's pipeline run on an MCAP recording: a recording it made replays to the same
//! trajectory bit for bit; a cut file, unknown schemas, wrong encodings and malformed CDR
//! cost their messages, are counted, and never stop the replay.

mod mcap_support;

use std::collections::BTreeMap;
use std::io::Cursor;
use std::time::Duration;

use mcap_support::*;
use radar_driver::OdometryPoll;
use ros_msgs::builtin::Time;
use ros_msgs::geometry::{Twist, TwistStamped, Vector3};
use ros_msgs::navtech::RadarBScanMsg;
use ros_msgs::std_msgs::Header;
use ros_msgs::{to_cdr, RosMessage};
use slam_node::output::recording::{TOPIC_BSCAN, TOPIC_ODOMETRY_INPUT, TOPIC_POSE};

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
    assert_eq!(live.len() as u64, POSED_ROTATIONS);
    let stamps = tum_stamps(&live_tum);
    assert_eq!(stamps.len() as u64, POSED_ROTATIONS, "{live_tum}");
    assert!(stamps.iter().all(|t| *t >= T0), "{live_tum}");
    assert_eq!(payloads(&replayed_mcap, TOPIC_POSE), live);
    assert_eq!(
        payloads(&replayed_mcap, TOPIC_BSCAN),
        payloads(&live_mcap, TOPIC_BSCAN)
    );
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
    let scan = ros2_channel::<RadarBScanMsg, _>(&mut w, TOPIC_BSCAN);
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
    let mut write = |channel_id, data: &[u8]| write_message(&mut w, channel_id, data);
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

/// The process's resident memory (kB), from /proc/self/status.
#[cfg(target_os = "linux")]
fn resident_kb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .expect("status")
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("VmRSS")
}

/// An FFT message whose data is far longer than the bins it declares (issue 38, item 4: a
/// 141 KB file made the replay hold 3.5 GB) costs only the declared bins: 32 messages of
/// 4 MiB each declaring 400 bins, every azimuth received and held at once, add much less
/// than one message's data to the process's resident memory (holding each message's buffer
/// would add 128 MiB; large buffers are returned to the system when freed).
#[cfg(target_os = "linux")]
#[test]
fn an_fft_message_holds_only_the_bins_it_declares() {
    use ros_msgs::navtech::{RadarConfigurationMsg, RadarFftDataMsg};
    const MESSAGES: u16 = 32;
    const BINS: u16 = 400;
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("long-data.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(Some(mcap::Compression::Zstd))
        .create(Cursor::new(Vec::new()))
        .expect("writer");
    let config = ros2_channel::<RadarConfigurationMsg, _>(&mut w, "/radar_data/configuration");
    let fft = ros2_channel::<RadarFftDataMsg, _>(&mut w, "/radar_data/fft_data");
    let mut write = |channel_id, data: &[u8]| write_message(&mut w, channel_id, data);
    let configuration = RadarConfigurationMsg {
        header: Header::new(Time::from_secs_f64(T0), "radar"),
        azimuth_samples: 400,
        encoder_size: 5600,
        bin_size: 438.0,
        range_in_bins: BINS,
        expected_rotation_rate: 4000,
        range_gain: 1.0,
        ..RadarConfigurationMsg::default()
    };
    write(config, &to_cdr(&configuration).expect("cdr"));
    for k in 0..MESSAGES {
        let m = RadarFftDataMsg {
            header: Header::new(Time::from_secs_f64(T0), "radar"),
            azimuth: 14 * k,
            sweep_counter: k,
            ntp_seconds: T0 as u32,
            ntp_split_seconds: 625_000 * u32::from(k),
            data: vec![7; 4 << 20],
            data_length: BINS,
            ..RadarFftDataMsg::default()
        };
        write(fft, &to_cdr(&m).expect("cdr"));
    }
    w.finish().expect("finish");
    std::fs::write(&path, w.into_inner().into_inner()).expect("write");

    let before_kb = resident_kb();
    let (az, _odo, handle) = replay(&path);
    let held: Vec<_> = std::iter::from_fn(|| az.recv_timeout(Duration::from_secs(10)).ok())
        .take(usize::from(MESSAGES))
        .collect();
    let grown_kb = resident_kb().saturating_sub(before_kb);
    if held.len() != usize::from(MESSAGES) {
        drop(az);
        panic!("{} azimuths: {:?}", held.len(), handle.finish());
    }
    assert!(held.iter().all(|a| a.bins.len() == usize::from(BINS)));
    assert!(
        grown_kb < 32 * 1024,
        "holding {} azimuths of {BINS} bins grew the process by {grown_kb} kB",
        held.len()
    );
    drop(az);
    let counts = handle.finish();
    assert_eq!(counts.malformed, 0);
}
