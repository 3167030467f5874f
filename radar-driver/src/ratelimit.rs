//! A small rate limiter for log lines caused by what arrives on the wire: a misbehaving
//! radar must not be able to flood the log. The first event logs at once; later ones log
//! at most once per interval and say how many were suppressed in between.
//!
//! Time comes in as an argument (tokio's [`Instant`], so tests run on the paused clock).
//!
//! ```
//! use std::time::Duration;
//! use radar_driver::RateLimiter;
//! use tokio::time::Instant;
//!
//! let mut limit = RateLimiter::new(Duration::from_secs(10));
//! let t0 = Instant::now();
//! assert_eq!(limit.check(t0), Some(0)); // the first one logs
//! assert_eq!(limit.check(t0 + Duration::from_secs(1)), None); // suppressed
//! assert_eq!(limit.check(t0 + Duration::from_secs(10)), Some(1)); // logs: 1 suppressed
//! ```

use std::time::Duration;

use tokio::time::Instant;

/// Allows one event per interval; counts the rest.
#[derive(Debug, Clone)]
pub struct RateLimiter {
    interval: Duration,
    last: Option<Instant>,
    suppressed: u64,
}

impl RateLimiter {
    /// At most one event per `interval`.
    pub fn new(interval: Duration) -> Self {
        Self {
            interval,
            last: None,
            suppressed: 0,
        }
    }

    /// Records an event at `now`. `Some(n)`: log it, `n` events were suppressed since the
    /// last one logged. `None`: suppress it (counted).
    pub fn check(&mut self, now: Instant) -> Option<u64> {
        let due = match self.last {
            None => true,
            Some(last) => now.saturating_duration_since(last) >= self.interval,
        };
        if due {
            self.last = Some(now);
            Some(std::mem::take(&mut self.suppressed))
        } else {
            self.suppressed = self.suppressed.saturating_add(1);
            None
        }
    }

    /// Events suppressed since the last one allowed.
    pub fn suppressed(&self) -> u64 {
        self.suppressed
    }
}

/// Logs a WARN through a [`RateLimiter`], adding a `suppressed` field (events not logged
/// since the last line).
#[macro_export]
#[doc(hidden)]
macro_rules! warn_limited {
    ($limiter:expr, $($arg:tt)+) => {
        if let Some(suppressed) = $limiter.check(::tokio::time::Instant::now()) {
            ::tracing::warn!(suppressed, $($arg)+);
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_event_per_interval_is_allowed_and_the_rest_are_counted() {
        let mut limit = RateLimiter::new(Duration::from_secs(5));
        let t0 = Instant::now();
        let allowed: Vec<Option<u64>> = (0..12)
            .map(|s| limit.check(t0 + Duration::from_secs(s)))
            .collect();
        assert_eq!(
            allowed,
            vec![
                Some(0),
                None,
                None,
                None,
                None,
                Some(4),
                None,
                None,
                None,
                None,
                Some(4),
                None
            ]
        );
        assert_eq!(limit.suppressed(), 1);
    }

    #[test]
    fn a_burst_at_one_instant_logs_once() {
        let mut limit = RateLimiter::new(Duration::from_secs(1));
        let t0 = Instant::now();
        let logged = (0..1000).filter(|_| limit.check(t0).is_some()).count();
        assert_eq!(logged, 1);
        assert_eq!(limit.suppressed(), 999);
    }
}
