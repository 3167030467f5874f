//! Value types that cannot hold an invalid setting.
//!
//! Each type has a fallible constructor that names what is wrong with a value; the section
//! validators attach the dotted field path. Once built, a value is valid for its whole life.

use std::fmt;
use std::num::NonZeroUsize;
use std::time::Duration;

/// What is wrong with one value, without saying where it came from.
///
/// The section validators wrap it with the field's dotted path (see [`crate::FieldError`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValueError {
    /// NaN or an infinity where a real number is needed.
    #[error("must be a finite number, got {0}")]
    NotFinite(f64),
    /// Zero or negative where a strictly positive value is needed.
    #[error("must be > 0, got {0}")]
    NotPositive(String),
    /// Negative where zero or more is needed.
    #[error("must be >= 0, got {0}")]
    Negative(String),
    /// Outside a closed or half-open interval; the text says which.
    #[error("must be in {range}, got {got}")]
    OutOfRange {
        /// The allowed interval, written as in mathematics, e.g. `[0, 1]` or `(0, 1)`.
        range: String,
        /// The rejected value, as written.
        got: String,
    },
    /// A socket address that does not parse as `ip:port`.
    #[error("must be an address `ip:port` such as `127.0.0.1:6317`, got {0:?}")]
    BadSocketAddr(String),
    /// A string that must not be empty.
    #[error("must not be empty")]
    Empty,
    /// Any other rule, stated in words.
    #[error("{0}")]
    Rule(String),
}

/// Writes a number for a message: plainly in the usual range, in exponent form when very
/// small or very large (`1e-308`, not three hundred zeros).
pub fn number(value: f64) -> String {
    let magnitude = value.abs();
    if value == 0.0 || !value.is_finite() || (1e-4..1e16).contains(&magnitude) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

fn finite(value: f64) -> Result<f64, ValueError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ValueError::NotFinite(value))
    }
}

/// A finite `f64` (no NaN, no infinity).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct FiniteF64(f64);

impl FiniteF64 {
    /// Zero.
    pub const ZERO: Self = Self(0.0);
    /// Accepts any finite value.
    pub fn new(value: f64) -> Result<Self, ValueError> {
        finite(value).map(Self)
    }
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A finite `f64` strictly greater than zero.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct PositiveF64(f64);

impl PositiveF64 {
    /// One.
    pub const ONE: Self = Self(1.0);
    /// Accepts finite values `> 0`.
    pub fn new(value: f64) -> Result<Self, ValueError> {
        let value = finite(value)?;
        if value > 0.0 {
            Ok(Self(value))
        } else {
            Err(ValueError::NotPositive(number(value)))
        }
    }
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A finite `f64` greater than or equal to zero.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct NonNegativeF64(f64);

impl NonNegativeF64 {
    /// Accepts finite values `>= 0` (negative zero is stored as zero).
    pub fn new(value: f64) -> Result<Self, ValueError> {
        let value = finite(value)?;
        if value >= 0.0 {
            Ok(Self(value + 0.0))
        } else {
            Err(ValueError::Negative(number(value)))
        }
    }
    /// Zero.
    pub const ZERO: Self = Self(0.0);
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A probability in the closed interval `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct Probability(f64);

impl Probability {
    /// One half.
    pub const HALF: Self = Self(0.5);
    /// Accepts finite values in `[0, 1]`.
    pub fn new(value: f64) -> Result<Self, ValueError> {
        let value = finite(value)?;
        if (0.0..=1.0).contains(&value) {
            Ok(Self(value + 0.0))
        } else {
            Err(ValueError::OutOfRange {
                range: "[0, 1]".into(),
                got: number(value),
            })
        }
    }
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A share of a radar registration's covariance that is its clouds' placement, in
/// `[0, 0.45]` (at 0.5 chained registrations would not drift at all).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct PlacementShare(f64);

impl PlacementShare {
    /// The largest share.
    pub const MAX: f64 = 0.45;
    /// No share: every registration independent.
    pub const ZERO: Self = Self(0.0);
    /// Accepts finite values in `[0, 0.45]`.
    pub fn new(value: f64) -> Result<Self, ValueError> {
        let value = finite(value)?;
        if (0.0..=Self::MAX).contains(&value) {
            Ok(Self(value + 0.0))
        } else {
            Err(ValueError::OutOfRange {
                range: "[0, 0.45]".into(),
                got: number(value),
            })
        }
    }
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A probability in the open interval `(0, 1)`: neither impossible nor certain.
///
/// Used where 0 or 1 would make a threshold infinite (false-alarm rates, gate probabilities).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct OpenProbability(f64);

impl OpenProbability {
    /// One half.
    pub const HALF: Self = Self(0.5);
    /// Accepts finite values strictly between 0 and 1.
    pub fn new(value: f64) -> Result<Self, ValueError> {
        let value = finite(value)?;
        if value > 0.0 && value < 1.0 {
            Ok(Self(value))
        } else {
            Err(ValueError::OutOfRange {
                range: "(0, 1)".into(),
                got: number(value),
            })
        }
    }
    /// The value.
    pub const fn get(self) -> f64 {
        self.0
    }
}

/// A count of slots (channel capacity, buffer size, table length): at least 1 and at most a
/// stated bound, so that a setting can never ask for an unbounded allocation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Capacity(NonZeroUsize);

impl Capacity {
    /// One slot.
    pub const ONE: Self = Self(NonZeroUsize::MIN);
    /// Accepts `1..=max`. The raw value is an `i64` because that is what TOML holds.
    pub fn new(value: i64, max: usize) -> Result<Self, ValueError> {
        let as_usize = usize::try_from(value).ok().filter(|v| *v <= max);
        match as_usize.and_then(NonZeroUsize::new) {
            Some(n) => Ok(Self(n)),
            None => Err(ValueError::OutOfRange {
                range: format!("[1, {max}]"),
                got: value.to_string(),
            }),
        }
    }
    /// The count.
    pub const fn get(self) -> usize {
        self.0.get()
    }
    /// The count as a `NonZeroUsize`.
    pub const fn non_zero(self) -> NonZeroUsize {
        self.0
    }
}

/// Checks an integer count `0..=max` (the raw value is an `i64` because TOML holds `i64`).
pub fn count(value: i64, max: u64) -> Result<u64, ValueError> {
    match u64::try_from(value) {
        Ok(v) if v <= max => Ok(v),
        _ => Err(ValueError::OutOfRange {
            range: format!("[0, {max}]"),
            got: value.to_string(),
        }),
    }
}

/// The longest duration any setting accepts: one day. Longer is a typo, and bounding it keeps
/// every `Instant + Duration` in range.
pub const MAX_DURATION: Duration = Duration::from_secs(86_400);

/// A duration from a strictly positive number of milliseconds, at most [`MAX_DURATION`].
pub fn duration_from_ms(ms: i64) -> Result<Duration, ValueError> {
    let max_ms = MAX_DURATION.as_millis();
    match u64::try_from(ms) {
        Ok(0) | Err(_) => Err(ValueError::NotPositive(ms.to_string())),
        Ok(v) if u128::from(v) > max_ms => Err(ValueError::OutOfRange {
            range: format!("[1, {max_ms}] ms"),
            got: ms.to_string(),
        }),
        Ok(v) => Ok(Duration::from_millis(v)),
    }
}

/// A duration from a strictly positive, finite number of seconds, at most [`MAX_DURATION`].
pub fn duration_from_s(s: f64) -> Result<Duration, ValueError> {
    let s = PositiveF64::new(s)?.get();
    if s > MAX_DURATION.as_secs_f64() {
        return Err(ValueError::OutOfRange {
            range: format!("(0, {}] s", MAX_DURATION.as_secs()),
            got: number(s),
        });
    }
    Duration::try_from_secs_f64(s).map_err(|e| ValueError::Rule(e.to_string()))
}

/// Parses `ip:port` (IPv4 or bracketed IPv6). Host names are not resolved here: resolution is
/// IO and belongs to the caller.
pub fn socket_addr(text: &str) -> Result<std::net::SocketAddr, ValueError> {
    text.trim()
        .parse()
        .map_err(|_| ValueError::BadSocketAddr(text.to_owned()))
}

impl fmt::Display for PositiveF64 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&number(self.0))
    }
}

impl fmt::Display for NonNegativeF64 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&number(self.0))
    }
}

impl fmt::Display for Probability {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&number(self.0))
    }
}

/// A file path that is not empty.
pub fn non_empty_path(path: &std::path::Path) -> Result<std::path::PathBuf, ValueError> {
    if path.as_os_str().is_empty() {
        Err(ValueError::Empty)
    } else {
        Ok(path.to_path_buf())
    }
}

impl fmt::Display for FiniteF64 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&number(self.0))
    }
}

impl fmt::Display for OpenProbability {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&number(self.0))
    }
}

/// Whole milliseconds of a duration, rounded up so that a positive duration stays positive,
/// saturating at `i64::MAX` (for writing settings back out).
pub fn whole_ms(d: Duration) -> i64 {
    let ms = d.as_nanos().div_ceil(1_000_000);
    i64::try_from(ms).unwrap_or(i64::MAX)
}

/// A count as TOML's `i64`, saturating at `i64::MAX` (for writing settings back out).
pub fn as_i64<T: TryInto<i64>>(n: T) -> i64 {
    n.try_into().unwrap_or(i64::MAX)
}
