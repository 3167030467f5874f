//! Support for the tests that talk to the daemon over Zenoh (built with `--features zenoh`).

use std::time::{Duration, Instant};

use slam_node::daemon::{run_daemon, DaemonOptions, DaemonReport};
use zenoh::Wait;

/// Starts the daemon on a runtime of its own, waits (at most 30 s) until its subscriber
/// matches `publisher`, lets `publish` run, and returns the daemon's report (at most 2 min
/// later).
pub fn run_with(
    opts: DaemonOptions,
    publisher: &zenoh::pubsub::Publisher<'_>,
    publish: impl FnOnce(),
) -> DaemonReport {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let daemon = runtime.spawn(run_daemon(opts, None));
    let deadline = Instant::now() + Duration::from_secs(30);
    while !publisher.matching_status().wait().unwrap().matching() {
        assert!(Instant::now() < deadline, "the daemon never subscribed");
        assert!(!daemon.is_finished(), "the daemon ended before subscribing");
        std::thread::sleep(Duration::from_millis(5));
    }
    publish();
    runtime
        .block_on(async { tokio::time::timeout(Duration::from_secs(120), daemon).await })
        .expect("the daemon finishes within 2 min")
        .expect("the daemon's task")
        .expect("the daemon runs")
}
