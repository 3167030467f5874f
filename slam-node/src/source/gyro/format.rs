//! The gyro line format of `docs/contracts.md`, parsed without IO: the odometry stream's
//! rules with two fields, checked by the odometry's own
//! [`radar_driver::odometry::split_line`] and [`radar_driver::odometry::decimal`].
//!
//! ```text
//! # gyro v1 timestamp_s yaw_rate_rad_s
//! 1700000000.250000000 0.0312
//! ```
//!
//! ASCII, one sample a line, `\n`-terminated (a trailing `\r` is tolerated). The header may
//! appear again (a reconnected stream starts with it); blank lines are skipped. Lines over
//! [`MAX_LINE_BYTES`] (cut by the odometry's [`radar_driver::odometry::LineSplitter`],
//! which never holds more than one line) or that do not parse are errors that cost that
//! line only. The yaw rate is counter-clockwise positive (the vehicle turning left), rad/s.

use radar_driver::odometry::{decimal, split_line, Fields, LineError};
pub use radar_driver::odometry::{MAX_LINE_BYTES, MAX_TIMESTAMP_DECIMALS};

/// The header line, without its newline.
pub const GYRO_HEADER: &str = "# gyro v1 timestamp_s yaw_rate_rad_s";

/// One gyro sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSample {
    /// Unix seconds.
    pub timestamp_s: f64,
    /// Yaw rate, rad/s, counter-clockwise positive.
    pub yaw_rate_rad_s: f64,
}

impl GyroSample {
    /// The sample as one line of the format (no newline), timestamp to 9 decimals.
    pub fn to_line(&self) -> String {
        format!("{:.9} {}", self.timestamp_s, self.yaw_rate_rad_s)
    }
}

/// What is wrong with one line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GyroLineError {
    /// Longer than [`MAX_LINE_BYTES`]; the rest of it up to the newline was discarded.
    #[error("line longer than {MAX_LINE_BYTES} bytes ({len} bytes or more)")]
    TooLong {
        /// Bytes seen before giving up on the line.
        len: usize,
    },
    /// Not ASCII.
    #[error("line is not ASCII")]
    NotAscii,
    /// A sample before the header line.
    #[error("sample before the header line `{GYRO_HEADER}`")]
    MissingHeader,
    /// A `#` line that is not the header.
    #[error("unexpected comment or header: {0:?}")]
    BadHeader(String),
    /// Not two fields separated by a single space.
    #[error("expected 2 fields separated by a single space, found {found}")]
    FieldCount {
        /// Fields found.
        found: usize,
    },
    /// A field that is not a finite plain decimal number.
    #[error("field {field} is not a finite number: {text:?}")]
    BadNumber {
        /// Field name.
        field: &'static str,
        /// The text (at most a line's worth).
        text: String,
    },
    /// A timestamp with more than nine decimals.
    #[error("timestamp has more than {MAX_TIMESTAMP_DECIMALS} decimals: {0:?}")]
    TooManyDecimals(String),
}

impl From<LineError> for GyroLineError {
    /// The odometry's shared line checks' errors, as the gyro's (whose messages name the
    /// gyro's header and field count).
    fn from(e: LineError) -> Self {
        match e {
            LineError::TooLong { len } => GyroLineError::TooLong { len },
            LineError::NotAscii => GyroLineError::NotAscii,
            LineError::MissingHeader => GyroLineError::MissingHeader,
            LineError::BadHeader(text) => GyroLineError::BadHeader(text),
            LineError::FieldCount { found } => GyroLineError::FieldCount { found },
            LineError::BadNumber { field, text } => GyroLineError::BadNumber { field, text },
            LineError::TooManyDecimals(text) => GyroLineError::TooManyDecimals(text),
        }
    }
}

/// What one line holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GyroLine {
    /// The header.
    Header,
    /// A blank line (skipped).
    Blank,
    /// A sample.
    Sample(GyroSample),
}

/// Parses one line (without its `\n`).
pub fn parse_gyro_line(line: &[u8]) -> Result<GyroLine, GyroLineError> {
    Ok(match split_line(line, GYRO_HEADER)? {
        Fields::Header => GyroLine::Header,
        Fields::Blank => GyroLine::Blank,
        Fields::Record([t, w]) => GyroLine::Sample(GyroSample {
            timestamp_s: decimal("timestamp_s", t)?,
            yaw_rate_rad_s: decimal("yaw_rate_rad_s", w)?,
        }),
    })
}

/// Turns lines into samples, enforcing the header rule.
#[derive(Debug, Default)]
pub struct GyroParser {
    seen_header: bool,
}

impl GyroParser {
    /// A parser expecting a header first.
    pub fn new() -> Self {
        Self::default()
    }

    /// Expects a header again (a new connection).
    pub fn reset(&mut self) {
        self.seen_header = false;
    }

    /// `Ok(Some(sample))` for a sample, `Ok(None)` for a header or blank line.
    pub fn parse(&mut self, line: &[u8]) -> Result<Option<GyroSample>, GyroLineError> {
        match parse_gyro_line(line)? {
            GyroLine::Header => {
                self.seen_header = true;
                Ok(None)
            }
            GyroLine::Blank => Ok(None),
            GyroLine::Sample(_) if !self.seen_header => Err(GyroLineError::MissingHeader),
            GyroLine::Sample(s) => Ok(Some(s)),
        }
    }
}

impl radar_driver::odometry::LineParser for GyroParser {
    type Record = GyroSample;
    type Error = GyroLineError;
    const NAME: &'static str = "gyro";

    fn parse(&mut self, line: &[u8]) -> Result<Option<GyroSample>, GyroLineError> {
        GyroParser::parse(self, line)
    }

    fn reset(&mut self) {
        GyroParser::reset(self);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use radar_driver::odometry::LineSplitter;

    #[test]
    fn a_sample_line_parses_to_its_two_values_and_round_trips() {
        assert_eq!(
            parse_gyro_line(b"1700000000.123456789 -0.0312\r").unwrap(),
            GyroLine::Sample(GyroSample {
                timestamp_s: "1700000000.123456789".parse().unwrap(),
                yaw_rate_rad_s: -0.0312
            })
        );
        assert_eq!(
            parse_gyro_line(GYRO_HEADER.as_bytes()).unwrap(),
            GyroLine::Header
        );
        assert_eq!(parse_gyro_line(b"").unwrap(), GyroLine::Blank);
        let s = GyroSample {
            timestamp_s: 1_700_000_000.25,
            yaw_rate_rad_s: 0.125,
        };
        assert_eq!(
            parse_gyro_line(s.to_line().as_bytes()).unwrap(),
            GyroLine::Sample(s)
        );
    }

    #[test]
    fn hostile_lines_are_named_errors() {
        type Check = fn(&GyroLineError) -> bool;
        let cases: &[(&[u8], Check)] = &[
            (b"1", |e| {
                matches!(e, GyroLineError::FieldCount { found: 1 })
            }),
            (b"1 2 3", |e| {
                matches!(e, GyroLineError::FieldCount { found: 3 })
            }),
            (b"1  2", |e| {
                matches!(e, GyroLineError::FieldCount { found: 3 })
            }),
            (b"1\t2", |e| {
                matches!(e, GyroLineError::FieldCount { found: 1 })
            }),
            (b"1 NaN", |e| {
                matches!(
                    e,
                    GyroLineError::BadNumber {
                        field: "yaw_rate_rad_s",
                        ..
                    }
                )
            }),
            (b"1 inf", |e| matches!(e, GyroLineError::BadNumber { .. })),
            (b"1 1e3", |e| matches!(e, GyroLineError::BadNumber { .. })),
            (b"1 --1", |e| matches!(e, GyroLineError::BadNumber { .. })),
            (b"x 0.1", |e| {
                matches!(
                    e,
                    GyroLineError::BadNumber {
                        field: "timestamp_s",
                        ..
                    }
                )
            }),
            (b"1.0123456789 0.1", |e| {
                matches!(e, GyroLineError::TooManyDecimals(_))
            }),
            (b"# odometry v1 timestamp_s speed_mps steer_rad", |e| {
                matches!(e, GyroLineError::BadHeader(_))
            }),
            ("1 0.\u{e9}".as_bytes(), |e| {
                matches!(e, GyroLineError::NotAscii)
            }),
        ];
        for (line, ok) in cases {
            let err = parse_gyro_line(line).unwrap_err();
            assert!(ok(&err), "{:?} gave {err:?}", String::from_utf8_lossy(line));
        }
        let long = vec![b'1'; MAX_LINE_BYTES + 1];
        assert!(matches!(
            parse_gyro_line(&long),
            Err(GyroLineError::TooLong { .. })
        ));
    }

    #[test]
    fn samples_before_the_header_cost_their_line_and_later_ones_parse() {
        let mut p = GyroParser::new();
        assert_eq!(p.parse(b"1 0.1"), Err(GyroLineError::MissingHeader));
        assert_eq!(p.parse(GYRO_HEADER.as_bytes()), Ok(None));
        assert!(matches!(p.parse(b"1 0.1"), Ok(Some(_))));
        assert!(p.parse(b"garbage").is_err());
        assert!(matches!(p.parse(b"2 0.2"), Ok(Some(_))));
        p.reset();
        assert_eq!(p.parse(b"3 0.1"), Err(GyroLineError::MissingHeader));
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_never_panic_and_never_buffer_more_than_a_line(
            chunks in proptest::collection::vec(proptest::collection::vec(proptest::num::u8::ANY, 0..400), 0..20)
        ) {
            let mut s = LineSplitter::new();
            let mut p = GyroParser::new();
            for c in &chunks {
                s.push(c);
                proptest::prop_assert!(s.pending_bytes() <= MAX_LINE_BYTES);
                while let Some(line) = s.next_line() {
                    if let Ok(line) = line {
                        let _ = p.parse(&line);
                    }
                }
            }
        }
    }
}
