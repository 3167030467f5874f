//! The pipeline thread behind its narrow odometry seam (`radar_driver::OdometrySource`),
//! mocked with mockall: without usable odometry the daemon refuses every beam and counts
//! why; it never fabricates motion.

mod support;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use protocol::{BinWidth, Geometry};
use radar_driver::odometry::LineError;
use radar_driver::{Azimuth, OdometryError, OdometryPoll, OdometrySource};
use slam_node::pipeline::{Pipeline, PipelineSettings, RunControl, RunReport};

mockall::mock! {
    Source {}
    impl OdometrySource for Source {
        fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError>;
    }
}

const T0: f64 = 1.7e9;
const AZIMUTHS: u64 = 200;

/// Three rotations of a 200-azimuth radar that sees a bright return at 25 m in every
/// azimuth (a wall all round), so every beam has targets to refuse.
fn azimuths() -> Vec<Azimuth> {
    let geometry = Arc::new(Geometry {
        azimuth_samples: 200,
        range_in_bins: 800,
        bin_size_m: 0.25,
        encoder_size: 5600,
        rotation_hz: 2.5,
        packet_rate: 500,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data_width: BinWidth::Eight,
        range_resolution_m: Some(0.25),
    });
    let mut bins = vec![40u8; 800];
    for b in bins.iter_mut().skip(99).take(3) {
        *b = 200;
    }
    let bins = Bytes::from(bins);
    (0..3 * AZIMUTHS)
        .map(|k| {
            let encoder = u16::try_from((k % AZIMUTHS) * 28).expect("fits");
            Azimuth {
                encoder,
                angle_rad: f64::from(encoder) * std::f64::consts::TAU / 5600.0,
                timestamp_s: T0 + k as f64 / 500.0,
                sweep_counter: u16::try_from(k).expect("fits"),
                width: BinWidth::Eight,
                bins: bins.clone(),
                geometry: Arc::clone(&geometry),
                rotation: k / AZIMUTHS,
            }
        })
        .collect()
}

/// Runs the pipeline thread's loop over the azimuths with `odometry` behind the seam.
fn run_with(odometry: MockSource) -> RunReport {
    let mut settings = PipelineSettings::from_config(&config::Config::default()).expect("valid");
    // Do not wait for odometry that never comes: the refusal is what is under test.
    settings.odometry_wait = Duration::from_millis(1);
    let pipeline = Pipeline::new(settings, Some(T0), None).expect("pipeline");
    support::run_queued(
        pipeline,
        azimuths(),
        Box::new(odometry),
        RunControl {
            stop: Arc::new(AtomicBool::new(false)),
            end_after_silence: None,
            played_out: None,
            max_stream_s: None,
            progress: None,
        },
    )
}

#[test]
fn a_silent_odometry_source_refuses_every_beam_and_fabricates_no_motion() {
    let mut source = MockSource::new();
    source
        .expect_poll_next()
        .returning(|_| Ok(OdometryPoll::Pending));
    let report = run_with(source);
    let s = &report.summary;
    assert!(s.detections > 0, "the wall is detected");
    assert!(
        s.refused.no_odometry > 0,
        "beams refused for want of odometry"
    );
    assert_eq!(s.beams, 0, "no beam reached the filter");
    assert_eq!(s.odometry_samples, 0);
    assert_eq!(report.odometry_errors, 0);
}

#[test]
fn bad_odometry_lines_are_counted_and_cost_only_themselves() {
    let mut source = MockSource::new();
    let mut line = 0;
    source.expect_poll_next().returning(move |_| {
        line += 1;
        Err(OdometryError::Line {
            line,
            source: LineError::NotAscii,
        })
    });
    let report = run_with(source);
    // Recoverable errors keep the source in use (it is polled again for every azimuth), and
    // still no motion is made up from them.
    assert!(
        report.odometry_errors >= 3 * AZIMUTHS,
        "{} errors counted",
        report.odometry_errors
    );
    assert!(report.summary.refused.no_odometry > 0);
    assert_eq!(report.summary.beams, 0);
}

#[test]
fn a_source_that_ends_is_dropped_and_the_daemon_carries_on_refusing() {
    let mut source = MockSource::new();
    // Ended must be seen once: after it the pipeline stops polling the source.
    source
        .expect_poll_next()
        .times(1)
        .returning(|_| Ok(OdometryPoll::Ended));
    let report = run_with(source);
    assert_eq!(report.summary.rotations, 3);
    assert!(report.summary.refused.no_odometry > 0);
    assert_eq!(report.summary.beams, 0);
}
