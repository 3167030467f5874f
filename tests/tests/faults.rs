//! The simulator's fault modes injected mid-run: the daemon recovers (reconnects, skips
//! garbage, waits out a stall keeping its state) and finishes with its map intact.

use std::num::NonZeroU64;
use std::time::Duration;

use e2e_tests::{print, run, Run};
use sim_sensor::{FaultScope, FaultSettings, Stall};

const LIMIT: Duration = Duration::from_secs(300);

fn assert_map_intact(report: &slam_node::daemon::DaemonReport) {
    let s = &report.run.summary;
    let map = s.map.as_ref().expect("truth is known");
    let found = map.distinct_scene_features_matched as f64 / map.scene_features_in_range as f64;
    assert!(
        found >= 0.8,
        "only {found:.2} of the features in range were mapped"
    );
    let pose = s.pose.as_ref().expect("truth is known");
    assert!(
        pose.final_position_m < 0.5,
        "final pose error {:.3} m",
        pose.final_position_m
    );
    assert!(
        s.stream_s() >= 19.0,
        "the run reached {:.1} s of stream",
        s.stream_s()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_connection_mid_run_is_reconnected_and_the_map_survives() {
    let out = tempfile::tempdir().unwrap();
    let mut r = Run::new("outdoor-field", 20.0);
    r.faults = FaultSettings {
        drop_after_messages: NonZeroU64::new(2_000),
        ..FaultSettings::default()
    };
    r.fault_scope = FaultScope::FirstConnections(1);
    let report = run(&r, out.path(), LIMIT).await.unwrap();
    print(&report);
    let driver = report.driver.as_ref().expect("driver stopped cleanly");
    assert!(driver.reconnects >= 1, "the driver reconnected");
    assert_map_intact(&report);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrupted_frames_and_skipped_azimuths_cost_only_those_azimuths() {
    let out = tempfile::tempdir().unwrap();
    let mut r = Run::new("outdoor-field", 20.0);
    r.faults = FaultSettings {
        corrupt_every_n: NonZeroU64::new(97),
        skip_azimuth_every_n: NonZeroU64::new(50),
        ..FaultSettings::default()
    };
    let report = run(&r, out.path(), LIMIT).await.unwrap();
    print(&report);
    let driver = report.driver.as_ref().expect("driver stopped cleanly");
    assert!(driver.decode_errors.total() > 0, "corruption was seen");
    assert_map_intact(&report);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_radar_is_reported_and_the_state_is_kept_until_it_returns() {
    let out = tempfile::tempdir().unwrap();
    let mut r = Run::new("outdoor-field", 20.0);
    r.faults = FaultSettings {
        stall: Some(Stall {
            after_messages: NonZeroU64::new(3_000).unwrap(),
            duration: Duration::from_millis(3_500),
        }),
        ..FaultSettings::default()
    };
    r.fault_scope = FaultScope::FirstConnections(1);
    let report = run(&r, out.path(), LIMIT).await.unwrap();
    print(&report);
    assert!(report.run.stalls >= 1, "the stall was declared");
    assert_map_intact(&report);
}
