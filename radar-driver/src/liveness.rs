//! Judging a silent link: by what can be read, not by the clock alone.
//!
//! A silence deadline (the radar's watchdog, the odometry link's idle timeout) that passes
//! proves nothing by itself when this process was not running through it: stopped
//! (`kill -STOP`), descheduled on a loaded machine, or its runtime stalled. On expiry, then:
//! bytes already in the socket are read first ([`bytes_waiting`]); and a deadline noticed
//! well after it passed gives the peer a moment more ([`resume_grace`]), since a peer frozen
//! with this process (the simulator in the daemon's process) resumes with it and has had
//! no time to send. A deadline noticed on time, with nothing waiting, is a dead link.

use std::time::Duration;

use tokio::net::TcpStream;
use tokio::time::Instant;

/// A deadline noticed this long after it passed was not watched: this process (or its
/// runtime) was not running. Timers on a loaded machine are late by milliseconds.
pub const LATE_NOTICE: Duration = Duration::from_millis(250);

/// How long a peer is given, after a deadline noticed late, to be heard from (at most the
/// timeout itself).
pub const RESUME_GRACE: Duration = Duration::from_secs(1);

/// Whether the socket's receive buffer holds bytes (or the peer's close) now, asked of the
/// kernel without waiting and without tokio's cached readiness, which may not yet have seen
/// what arrived while this process was not running.
pub fn bytes_waiting(stream: &TcpStream) -> bool {
    let mut probe = [std::mem::MaybeUninit::<u8>::uninit(); 1];
    match socket2::SockRef::from(stream).peek(&mut probe) {
        Ok(_) => true, // a byte, or 0 for the peer's close: the read reports it
        Err(e) => e.kind() != std::io::ErrorKind::WouldBlock, // an error: the read reports it
    }
}

/// For a silence deadline `deadline` (of a `timeout`) found passed now: `Some(grace)` when
/// it was noticed at least [`LATE_NOTICE`] late, the time to wait longer before judging
/// the link; `None` when it was noticed on time.
pub fn resume_grace(deadline: Instant, timeout: Duration) -> Option<Duration> {
    let late = Instant::now().saturating_duration_since(deadline);
    (late >= LATE_NOTICE).then(|| RESUME_GRACE.min(timeout))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn a_deadline_noticed_late_gets_a_grace_and_one_noticed_on_time_does_not() {
        let deadline = Instant::now();
        assert_eq!(resume_grace(deadline, Duration::from_secs(7)), None);
        tokio::time::advance(Duration::from_millis(100)).await;
        assert_eq!(resume_grace(deadline, Duration::from_secs(7)), None);
        tokio::time::advance(Duration::from_secs(2)).await;
        assert_eq!(
            resume_grace(deadline, Duration::from_secs(7)),
            Some(RESUME_GRACE)
        );
        assert_eq!(
            resume_grace(deadline, Duration::from_millis(300)),
            Some(Duration::from_millis(300))
        );
    }
}
