//! The wire's timestamp: u32 seconds since the Unix epoch plus u32 nanoseconds.

use crate::error::ConversionError;

const NANOS_PER_SECOND: u32 = 1_000_000_000;

/// A validated wire timestamp: `seconds` since the Unix epoch and `nanos < 1e9`.
///
/// The protocol crate keeps the wire's integer pair (no rounding); everything above it
/// uses [`Timestamp::as_secs_f64`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp {
    seconds: u32,
    nanos: u32,
}

impl Timestamp {
    /// The Unix epoch.
    pub const EPOCH: Timestamp = Timestamp {
        seconds: 0,
        nanos: 0,
    };

    /// A timestamp from its wire fields; `nanos` must be below 10^9.
    pub fn new(seconds: u32, nanos: u32) -> Result<Self, ConversionError> {
        if nanos >= NANOS_PER_SECOND {
            return Err(ConversionError::BadNanos { nanos });
        }
        Ok(Self { seconds, nanos })
    }

    /// The nearest timestamp to `seconds` since the epoch (nanosecond resolution).
    /// Errors for NaN, negative times and times past 2106 (u32 seconds).
    pub fn from_secs_f64(seconds: f64) -> Result<Self, ConversionError> {
        if !seconds.is_finite() || seconds < 0.0 {
            return Err(ConversionError::TimeOutOfRange { seconds });
        }
        let whole = seconds.floor();
        let mut nanos = ((seconds - whole) * f64::from(NANOS_PER_SECOND)).round();
        let mut whole_s = whole;
        if nanos >= f64::from(NANOS_PER_SECOND) {
            nanos = 0.0;
            whole_s += 1.0;
        }
        if whole_s > f64::from(u32::MAX) {
            return Err(ConversionError::TimeOutOfRange { seconds });
        }
        // Both values were range-checked above, so these casts are exact.
        Ok(Self {
            seconds: whole_s as u32,
            nanos: nanos as u32,
        })
    }

    /// Whole seconds since the Unix epoch.
    pub fn seconds(&self) -> u32 {
        self.seconds
    }

    /// Nanoseconds within the second, below 10^9.
    pub fn nanos(&self) -> u32 {
        self.nanos
    }

    /// Seconds since the Unix epoch as f64 (about 0.2 microsecond resolution today).
    pub fn as_secs_f64(&self) -> f64 {
        f64::from(self.seconds) + f64::from(self.nanos) * 1e-9
    }

    /// As a `std::time::Duration` since the Unix epoch (exact).
    pub fn as_duration_since_epoch(&self) -> std::time::Duration {
        std::time::Duration::new(u64::from(self.seconds), self.nanos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nanos_of_one_billion_are_rejected() {
        assert_eq!(
            Timestamp::new(5, 1_000_000_000),
            Err(ConversionError::BadNanos {
                nanos: 1_000_000_000
            })
        );
        assert!(Timestamp::new(5, 999_999_999).is_ok());
    }

    #[test]
    fn seconds_convert_both_ways() {
        let t = Timestamp::new(1_547_131_046, 353_776_000).unwrap();
        assert!((t.as_secs_f64() - 1_547_131_046.353_776).abs() < 1e-6);
        let back = Timestamp::from_secs_f64(t.as_secs_f64()).unwrap();
        assert_eq!(back.seconds(), t.seconds());
        assert!(back.nanos().abs_diff(t.nanos()) < 1_000);
    }

    #[test]
    fn a_fraction_that_rounds_up_carries_into_the_seconds() {
        let t = Timestamp::from_secs_f64(9.999_999_999_9).unwrap();
        assert_eq!((t.seconds(), t.nanos()), (10, 0));
    }

    #[test]
    fn negative_nan_and_post_2106_times_are_errors() {
        assert!(Timestamp::from_secs_f64(-1.0).is_err());
        assert!(Timestamp::from_secs_f64(f64::NAN).is_err());
        assert!(Timestamp::from_secs_f64(4_294_967_296.0).is_err());
    }
}
