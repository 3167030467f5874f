//! The `Clock` seam: wall-clock and monotonic time for the driver, mockable in tests.
//!
//! The driver reads time in two places only: the monotonic clock stamps each socket read so
//! the latency from the read to the channel send can be measured, and the wall clock stamps
//! odometry and log lines. Everything else takes its time from the radar's own timestamps.

use std::fmt::Debug;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// A source of time. Implementations must be cheap: the driver calls `monotonic_ns` twice per
/// azimuth.
pub trait Clock: Send + Sync + Debug {
    /// Seconds since the Unix epoch (wall clock; may jump).
    fn unix_now_s(&self) -> f64;
    /// Nanoseconds on a monotonic clock with an arbitrary origin (never goes backwards).
    fn monotonic_ns(&self) -> u64;
}

/// The operating system's clocks.
#[derive(Debug, Clone, Copy)]
pub struct SystemClock {
    origin: Instant,
}

impl SystemClock {
    /// A clock whose monotonic origin is now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
        }
    }
}

impl Default for SystemClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for SystemClock {
    fn unix_now_s(&self) -> f64 {
        match SystemTime::now().duration_since(UNIX_EPOCH) {
            Ok(d) => d.as_secs_f64(),
            // A wall clock set before 1970 is reported as negative seconds, not a panic.
            Err(e) => -e.duration().as_secs_f64(),
        }
    }

    fn monotonic_ns(&self) -> u64 {
        // u64 nanoseconds cover 584 years of uptime; saturate rather than wrap beyond that.
        u64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_monotonic_clock_never_goes_backwards() {
        let clock = SystemClock::new();
        let mut last = clock.monotonic_ns();
        for _ in 0..1000 {
            let now = clock.monotonic_ns();
            assert!(now >= last);
            last = now;
        }
    }

    #[test]
    fn the_wall_clock_reads_a_date_after_2020() {
        assert!(SystemClock::new().unix_now_s() > 1.577e9);
    }
}
