//! A radar whose stream starts stamped in the future (issue 38, item 1): azimuths stamped
//! at 2100-01-01 queued ahead of good data used to cost the odometry wait (500 ms) each, so
//! a queue of them stalled the daemon for as long as it held them (4096 azimuths: half an
//! hour), with no word. Now an azimuth stamped far ahead of the odometry is not waited for,
//! counted, and said (WARN and summary), and the good data behind it is reached at once.

mod support;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use std::collections::VecDeque;
use std::time::Duration;

use radar_driver::odometry::OdometryRecord;
use radar_driver::{OdometryError, OdometryPoll, OdometrySource};
use slam_node::pipeline::{Pipeline, RunControl};
use support::{run_queued, still, still_radar_azimuths, still_radar_settings};

/// A live odometry link: its samples, then nothing new (never ended), as a vehicle's
/// bridge that has sent what it has.
struct LiveOdometry(VecDeque<slam_filter::OdometrySample>);

impl OdometrySource for LiveOdometry {
    fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        Ok(match self.0.pop_front() {
            Some(s) => OdometryPoll::Record(OdometryRecord {
                timestamp_s: s.timestamp_s,
                speed_mps: s.speed_mps,
                steer_rad: s.steer_rad,
            }),
            None => {
                std::thread::sleep(timeout.min(Duration::from_millis(20)));
                OdometryPoll::Pending
            }
        })
    }
}

#[test]
fn azimuths_stamped_in_the_future_do_not_each_wait_for_odometry() {
    let t0_ns: u64 = 1_704_067_200_000_000_000; // 2024-01-01
    let future_ns: u64 = 4_102_444_800_000_000_000; // 2100-01-01
    let mut azimuths: Vec<_> = still_radar_azimuths(1, future_ns)
        .into_iter()
        .take(40)
        .collect();
    azimuths.extend(still_radar_azimuths(3, t0_ns));
    let t0 = t0_ns as f64 * 1e-9;
    // Parked odometry at 20 Hz over the good data's 1.2 s and beyond.
    let odometry: Vec<_> = (0..40).map(|k| still(t0 - 0.1 + 0.05 * k as f64)).collect();
    let settings = still_radar_settings();
    assert!(
        settings.odometry_wait.as_secs_f64() >= 0.5,
        "the shipped wait"
    );
    let pipeline = Pipeline::new(settings, Some(t0), None).expect("the pipeline");
    let report = run_queued(
        pipeline,
        azimuths,
        Box::new(LiveOdometry(odometry.into())),
        RunControl {
            stop: Arc::new(AtomicBool::new(false)),
            max_stream_s: None,
            progress: None,
            end_after_silence: None,
            played_out: None,
        },
    );
    // Today's code waited 40 x 0.5 s = 20 s here; a bound in wall time is the point.
    assert!(
        report.wall_s < 8.0,
        "the future-stamped azimuths cost {:.1} s",
        report.wall_s
    );
    assert!(
        report.far_ahead_of_odometry >= 39,
        "counted: {}",
        report.far_ahead_of_odometry
    );
    // The good data behind them was mapped.
    assert!(
        report.summary.rotations >= 2,
        "{}",
        report.summary.rotations
    );
    assert!(report.summary.beams > 0, "beams {}", report.summary.beams);
}
