//! The MCAP recorder read back by the `mcap` crate's reader: every message decodes as its
//! schema's type, the B-scans hold the azimuths bit for bit, a cut file gives its complete
//! chunks, an absurd radar geometry costs only the B-scan.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::sync::Arc;

use bytes::Bytes;
use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;
use radar_model::motion::MotionModel;
use ros_msgs::builtin::Time;
use ros_msgs::geometry::TwistStamped;
use ros_msgs::nav::{Odometry, TFMessage};
use ros_msgs::navtech::{RadarBScanMsg, RadarConfigurationMsg};
use ros_msgs::sensor::PointCloud2;
use ros_msgs::visualization::{Marker, MarkerArray};
use ros_msgs::{from_cdr, RosMessage};
use slam_filter::OdometrySample;
use slam_node::output::recording::{
    TOPIC_BSCAN, TOPIC_DETECTIONS, TOPIC_MAP, TOPIC_MAP_COVARIANCE, TOPIC_ODOMETRY_INPUT,
    TOPIC_POSE, TOPIC_RADAR_CONFIGURATION, TOPIC_TF, TOPIC_TF_STATIC,
};
use slam_node::output::{
    Detection, MapFeature, MapSnapshot, McapRecorder, OutputEvent, PoseSample, RecordingSummary,
    RotationDetections, RotationDiagnostics,
};

const T0: f64 = 1.7e9;
const AZIMUTHS: u16 = 200;
const BINS: u16 = 300;

fn geometry(azimuths: u16, bins: u16) -> Arc<Geometry> {
    Arc::new(Geometry {
        azimuth_samples: azimuths,
        range_in_bins: bins,
        bin_size_m: 0.25,
        encoder_size: 5600,
        rotation_hz: 2.5,
        packet_rate: 500,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data_width: BinWidth::Eight,
        range_resolution_m: Some(0.25),
    })
}

fn azimuth(g: &Arc<Geometry>, rotation: u64, index: u16) -> Azimuth {
    let k = rotation * u64::from(g.azimuth_samples) + u64::from(index);
    let encoder = index * (g.encoder_size / g.azimuth_samples.max(1));
    // Every azimuth different, so a misplaced row shows.
    let bins: Vec<u8> = (0..g.range_in_bins)
        .map(|b| (u64::from(b) * 7 + k * 13) as u8)
        .collect();
    Azimuth {
        encoder,
        angle_rad: g.azimuth_rad(encoder),
        timestamp_s: T0 + k as f64 / 500.0,
        sweep_counter: k as u16,
        width: BinWidth::Eight,
        bins: Bytes::from(bins),
        geometry: Arc::clone(g),
        rotation,
    }
}

/// The events of `rotations` rotations, in the order the pipeline thread sends them.
fn events(g: &Arc<Geometry>, rotations: u64) -> (Vec<OutputEvent>, Vec<Azimuth>) {
    let mut out = Vec::new();
    let mut sent = Vec::new();
    for r in 0..rotations {
        let t_end = T0 + ((r + 1) * u64::from(g.azimuth_samples) - 1) as f64 / 500.0;
        for i in 0..g.azimuth_samples {
            let az = azimuth(g, r, i);
            if i % 25 == 0 {
                out.push(OutputEvent::Odometry(OdometrySample {
                    timestamp_s: az.timestamp_s,
                    speed_mps: 2.0,
                    steer_rad: 0.05,
                }));
            }
            sent.push(az.clone());
            out.push(OutputEvent::Azimuth(az));
        }
        out.push(OutputEvent::Detections(RotationDetections {
            rotation: r,
            timestamp_s: t_end,
            detections: vec![Detection {
                timestamp_s: t_end,
                range_m: 10.0,
                bearing_rad: std::f64::consts::FRAC_PI_2,
                power_db: -40.0,
            }],
        }));
        out.push(OutputEvent::Pose(PoseSample {
            timestamp_s: t_end,
            x_m: r as f64,
            y_m: -0.5 * r as f64,
            theta_rad: 0.1 * r as f64,
            covariance: [[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.001]],
        }));
        let mut covariance = [[0.0; 4]; 4];
        covariance[0][0] = 0.25;
        covariance[1][1] = 0.01;
        out.push(OutputEvent::Map(MapSnapshot {
            format: MapSnapshot::FORMAT.into(),
            timestamp_s: t_end,
            loss_db: 3.0,
            loss_var_db2: 0.5,
            features: vec![MapFeature {
                id: 7,
                x_m: 12.0,
                y_m: -3.5,
                rho: 0.25,
                alpha: 0.45,
                tau: 0.30,
                covariance,
                observations: 31,
            }],
            global: None,
        }));
        out.push(OutputEvent::Rotation(Box::new(RotationDiagnostics {
            rotation: r,
            timestamp_s: t_end,
            total_ms: 10.0,
            ..RotationDiagnostics::default()
        })));
    }
    (out, sent)
}

fn record(g: &Arc<Geometry>, rotations: u64) -> (Vec<u8>, RecordingSummary, Vec<Azimuth>) {
    let mut rec = McapRecorder::new(
        Cursor::new(Vec::new()),
        "test.mcap".into(),
        MotionModel::Bicycle { wheelbase_m: 2.5 },
    )
    .unwrap();
    let (events, sent) = events(g, rotations);
    for e in &events {
        rec.on_event(e).unwrap();
    }
    let (sink, summary) = rec.finish().unwrap();
    (sink.into_inner(), summary, sent)
}

fn decodes_as<T: RosMessage>(m: &mcap::Message<'_>) -> T {
    let schema = m
        .channel
        .schema
        .as_ref()
        .expect("every channel has a schema");
    assert_eq!(schema.name, T::type_name(), "{}", m.channel.topic);
    assert_eq!(schema.encoding, "ros2msg");
    assert_eq!(std::str::from_utf8(&schema.data).unwrap(), T::schema_text());
    assert_eq!(m.channel.message_encoding, "cdr");
    from_cdr::<T>(&m.data).unwrap_or_else(|e| panic!("{}: {e}", m.channel.topic))
}

#[test]
fn a_recording_reads_back_through_the_mcap_crate_with_every_message_decoding_as_its_schema() {
    let g = geometry(AZIMUTHS, BINS);
    let (bytes, summary, sent) = record(&g, 3);
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    let mut scans = Vec::new();
    let mut poses = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        *counts.entry(m.channel.topic.clone()).or_insert(0) += 1;
        match m.channel.topic.as_str() {
            TOPIC_BSCAN => scans.push(decodes_as::<RadarBScanMsg>(&m)),
            TOPIC_RADAR_CONFIGURATION => {
                let c = decodes_as::<RadarConfigurationMsg>(&m);
                assert_eq!((c.azimuth_samples, c.range_in_bins), (AZIMUTHS, BINS));
            }
            TOPIC_ODOMETRY_INPUT => {
                let t = decodes_as::<TwistStamped>(&m);
                let expected = 2.0 * 0.05f64.tan() / 2.5;
                assert!((t.twist.angular.z - expected).abs() < 1e-12);
            }
            TOPIC_POSE => poses.push(decodes_as::<Odometry>(&m)),
            TOPIC_TF | TOPIC_TF_STATIC => {
                decodes_as::<TFMessage>(&m);
            }
            TOPIC_MAP => {
                let c = decodes_as::<PointCloud2>(&m);
                assert_eq!(
                    c.f32_points().unwrap(),
                    vec![vec![12.0, -3.5, 0.0, 0.25, 0.45]]
                );
            }
            TOPIC_DETECTIONS => {
                let c = decodes_as::<PointCloud2>(&m);
                let p = &c.f32_points().unwrap()[0];
                // Bearing 90 degrees clockwise: to the right, -y in ROS.
                assert!(p[0].abs() < 1e-5 && (p[1] + 10.0).abs() < 1e-5, "{p:?}");
            }
            TOPIC_MAP_COVARIANCE => {
                let a = decodes_as::<MarkerArray>(&m);
                assert_eq!(a.markers[0].action, Marker::DELETEALL);
                let e = &a.markers[1];
                // sigma_x = 0.5 m: the 95% ellipse is 2 x 2.448 x 0.5 m across.
                assert!((e.scale.x - 2.0 * 5.991f64.sqrt() * 0.5).abs() < 1e-9);
                assert!((e.scale.y - 2.0 * 5.991f64.sqrt() * 0.1).abs() < 1e-9);
            }
            other => panic!("unexpected topic {other}"),
        }
    }
    assert_eq!(counts, summary.messages);
    assert_eq!(counts[TOPIC_BSCAN], 3);
    assert_eq!(counts[TOPIC_POSE], 3);
    assert_eq!(counts[TOPIC_RADAR_CONFIGURATION], 1);
    assert_eq!(summary.rotations, 3);
    assert_eq!(summary.write_ms.len(), 3);
    // The B-scans hold every azimuth bit for bit, with its encoder value and its time.
    for (r, scan) in scans.iter().enumerate() {
        let img = &scan.b_scan_img;
        assert_eq!((img.height, img.width, img.step), (200, 300, 300));
        assert_eq!(img.encoding, "8UC1");
        for (i, az) in sent
            .iter()
            .skip(r * usize::from(AZIMUTHS))
            .take(usize::from(AZIMUTHS))
            .enumerate()
        {
            assert_eq!(&img.data[i * 300..(i + 1) * 300], &az.bins[..]);
            assert_eq!(scan.encoder_values[i], az.encoder);
            assert_eq!(
                Time::from_nanos(scan.timestamps[i]).as_secs_f64(),
                az.timestamp_s
            );
        }
    }
    // The pose's 3x3 covariance sits at (x, y, yaw) of the 6x6.
    let c = &poses[1].pose.covariance;
    assert_eq!(
        (c[0], c[1], c[5], c[7], c[11], c[35]),
        (0.04, 0.01, 0.0, 0.09, 0.002, 0.001)
    );
    assert!((poses[1].pose.pose.orientation.yaw() - 0.1).abs() < 1e-12);
}

#[test]
fn a_recording_cut_mid_file_yields_every_message_of_its_complete_chunks_then_an_error() {
    let g = geometry(AZIMUTHS, BINS);
    let (bytes, summary, _) = record(&g, 6);
    let total = summary.total_messages();
    for share in [0.3, 0.6, 0.9] {
        let cut = &bytes[..(bytes.len() as f64 * share) as usize];
        let mut read = 0u64;
        let mut scans = 0;
        let mut ended_in_error = false;
        for m in mcap::MessageStream::new(cut).unwrap() {
            match m {
                Ok(m) => {
                    read += 1;
                    if m.channel.topic == TOPIC_BSCAN {
                        decodes_as::<RadarBScanMsg>(&m);
                        scans += 1;
                    }
                }
                Err(_) => {
                    ended_in_error = true;
                    break;
                }
            }
        }
        assert!(ended_in_error, "a cut file ends in an error, not silently");
        // Past 0.9 the cut may fall in the summary section, after every message.
        let lost_some = read < total || share > 0.8;
        assert!(read > 0 && lost_some, "{read} of {total} at {share}");
        assert!(scans >= 1, "at least one whole rotation before {share}");
    }
}

#[test]
fn a_radar_geometry_too_large_for_a_b_scan_costs_the_b_scan_not_the_recording() {
    // 65535 x 65535 bins would be 4 GiB: refused before any allocation.
    let g = geometry(u16::MAX, u16::MAX);
    let mut rec = McapRecorder::new(
        Cursor::new(Vec::new()),
        "test.mcap".into(),
        MotionModel::Paper { step_s: 0.25 },
    )
    .unwrap();
    let mut az = azimuth(&geometry(AZIMUTHS, BINS), 0, 0);
    az.geometry = Arc::clone(&g);
    rec.on_event(&OutputEvent::Azimuth(az)).unwrap();
    rec.on_event(&OutputEvent::Pose(PoseSample {
        timestamp_s: T0,
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: 0.0,
        covariance: [[0.0; 3]; 3],
    }))
    .unwrap();
    let (sink, summary) = rec.finish().unwrap();
    assert_eq!(summary.rotations, 0);
    assert_eq!(summary.rotations_skipped, 1);
    assert_eq!(summary.messages[TOPIC_POSE], 1);
    let bytes = sink.into_inner();
    let read = mcap::MessageStream::new(&bytes).unwrap().count();
    assert_eq!(read as u64, summary.total_messages());
}
