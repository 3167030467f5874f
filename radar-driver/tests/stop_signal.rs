//! `stop_signal` installs its handlers when it is called, not when it is first polled: a
//! SIGTERM that comes in between is not lost, and does not kill the process by the default
//! action. A binary of its own: the test signals its own process.

#[cfg(unix)]
#[tokio::test]
async fn a_sigterm_sent_before_the_first_poll_is_caught_and_reported() {
    use std::time::Duration;
    let request = radar_driver::stop_signal();
    let status = std::process::Command::new("kill")
        .args(["-TERM", &std::process::id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    // Still alive: the handler caught it. And the request reports it once polled.
    let why = tokio::time::timeout(Duration::from_secs(5), request)
        .await
        .expect("the SIGTERM sent before the first poll was lost");
    assert_eq!(why, radar_driver::StopSignal::Term);
    assert_eq!(why.to_string(), "SIGTERM");
}
