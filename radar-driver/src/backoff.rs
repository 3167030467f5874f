//! Exponential reconnection backoff with jitter.
//!
//! Attempt k (0-based) waits `min(max, initial * 2^k) * (1 + jitter * (2u - 1))` with u
//! uniform in [0, 1), then clamped to `max`. Jitter spreads the reconnections of several
//! clients of one radar so they do not arrive in lock step.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::time::Duration;

/// Backoff parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackoffPolicy {
    /// Delay before the first retry.
    pub initial: Duration,
    /// Largest delay.
    pub max: Duration,
    /// Relative jitter in [0, 1].
    pub jitter: f64,
}

impl Default for BackoffPolicy {
    fn default() -> Self {
        Self {
            initial: Duration::from_millis(100),
            max: Duration::from_millis(5000),
            jitter: 0.2,
        }
    }
}

/// The state of one backoff sequence.
#[derive(Debug)]
pub struct Backoff {
    policy: BackoffPolicy,
    attempt: u32,
    rng: StdRng,
}

impl Backoff {
    /// A new sequence seeded from the operating system.
    pub fn new(policy: BackoffPolicy) -> Self {
        Self::with_rng(policy, StdRng::from_entropy())
    }

    /// A reproducible sequence.
    pub fn seeded(policy: BackoffPolicy, seed: u64) -> Self {
        Self::with_rng(policy, StdRng::seed_from_u64(seed))
    }

    fn with_rng(policy: BackoffPolicy, rng: StdRng) -> Self {
        Self {
            policy,
            attempt: 0,
            rng,
        }
    }

    /// Retries taken since the last reset.
    pub fn attempt(&self) -> u32 {
        self.attempt
    }

    /// Starts again from `initial` (after a connection that worked).
    pub fn reset(&mut self) {
        self.attempt = 0;
    }

    /// The delay before the next attempt; advances the sequence.
    pub fn next_delay(&mut self) -> Duration {
        let u: f64 = self.rng.gen();
        let d = delay_for(&self.policy, self.attempt, u);
        self.attempt = self.attempt.saturating_add(1);
        d
    }
}

/// The delay of attempt `attempt` for a uniform draw `u` in [0, 1).
pub fn delay_for(policy: &BackoffPolicy, attempt: u32, u: f64) -> Duration {
    let max_s = policy.max.as_secs_f64();
    // 2^attempt overflows nothing as f64 up to 2^1023; cap the exponent well before that.
    let base_s = (policy.initial.as_secs_f64() * 2f64.powi(attempt.min(60) as i32)).min(max_s);
    let jitter = if policy.jitter.is_finite() {
        policy.jitter.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let u = if u.is_finite() {
        u.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let s = (base_s * (1.0 + jitter * (2.0 * u - 1.0))).clamp(0.0, max_s);
    Duration::from_secs_f64(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_jitter_the_delay_doubles_until_the_cap() {
        let p = BackoffPolicy {
            initial: Duration::from_millis(100),
            max: Duration::from_millis(1000),
            jitter: 0.0,
        };
        let got: Vec<u128> = (0..6).map(|k| delay_for(&p, k, 0.3).as_millis()).collect();
        assert_eq!(got, vec![100, 200, 400, 800, 1000, 1000]);
    }

    #[test]
    fn jitter_stays_within_its_fraction_and_below_the_cap() {
        let p = BackoffPolicy {
            initial: Duration::from_millis(100),
            max: Duration::from_millis(1000),
            jitter: 0.2,
        };
        let mut b = Backoff::seeded(p, 7);
        for k in 0..50u32 {
            let d = b.next_delay().as_secs_f64();
            let base = (0.1 * 2f64.powi(k.min(60) as i32)).min(1.0);
            assert!(
                d >= base * 0.8 - 1e-9 && d <= (base * 1.2).min(1.0) + 1e-9,
                "{k}: {d}"
            );
        }
        assert_eq!(b.attempt(), 50);
        b.reset();
        assert_eq!(b.attempt(), 0);
    }

    #[test]
    fn huge_attempt_counts_do_not_overflow() {
        let p = BackoffPolicy::default();
        assert_eq!(delay_for(&p, u32::MAX, 0.5), p.max);
    }
}
