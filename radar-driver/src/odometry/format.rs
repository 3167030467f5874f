//! The odometry stream format of `docs/contracts.md`, parsed without IO.
//!
//! ```text
//! # odometry v1 timestamp_s speed_mps steer_rad
//! 1700000000.250000000 4.5 0.02
//! ```
//!
//! ASCII, one record a line, `\n`-terminated (a trailing `\r` is tolerated). The header may
//! appear again (a reconnected stream starts with it); blank lines are skipped. Lines over
//! [`MAX_LINE_BYTES`] or that do not parse are errors that cost that line only.

/// The header line, without its newline.
pub const ODOMETRY_HEADER: &str = "# odometry v1 timestamp_s speed_mps steer_rad";
/// Longest accepted line, in bytes, excluding the newline.
pub const MAX_LINE_BYTES: usize = 256;
/// Most decimals accepted in a timestamp (nanoseconds).
pub const MAX_TIMESTAMP_DECIMALS: usize = 9;

/// One odometry sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryRecord {
    /// Unix seconds.
    pub timestamp_s: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// Steering input, radians (interpreted by the configured motion model).
    pub steer_rad: f64,
}

impl OdometryRecord {
    /// The record as one line of the stream format (no newline), timestamp to 9 decimals.
    pub fn to_line(&self) -> String {
        format!(
            "{:.9} {} {}",
            self.timestamp_s, self.speed_mps, self.steer_rad
        )
    }
}

/// What is wrong with one line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    /// Longer than [`MAX_LINE_BYTES`]; the rest of it up to the newline was discarded.
    #[error("line longer than {MAX_LINE_BYTES} bytes ({len} bytes or more)")]
    TooLong {
        /// Bytes seen before giving up on the line.
        len: usize,
    },
    /// Not ASCII.
    #[error("line is not ASCII")]
    NotAscii,
    /// A record before the header line.
    #[error("record before the header line `{ODOMETRY_HEADER}`")]
    MissingHeader,
    /// A `#` line that is not the header.
    #[error("unexpected comment or header: {0:?}")]
    BadHeader(String),
    /// Not three fields separated by single spaces.
    #[error("expected 3 fields separated by single spaces, found {found}")]
    FieldCount {
        /// Fields found.
        found: usize,
    },
    /// A field that is not a finite decimal number.
    #[error("field {field} is not a finite number: {text:?}")]
    BadNumber {
        /// Field name.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// A timestamp with more than nine decimals.
    #[error("timestamp has more than {MAX_TIMESTAMP_DECIMALS} decimals: {0:?}")]
    TooManyDecimals(String),
}

/// What one line holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Line {
    /// The header.
    Header,
    /// A blank line (skipped).
    Blank,
    /// A record.
    Record(OdometryRecord),
}

/// What one line of a line format of `docs/contracts.md` holds before its fields are read
/// as numbers: the shared checks of [`split_line`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fields<'a, const N: usize> {
    /// The format's header.
    Header,
    /// A blank line (skipped).
    Blank,
    /// A record's `N` fields, the first a timestamp with at most nine decimals.
    Record([&'a str; N]),
}

/// The checks every line format of `docs/contracts.md` (odometry, gyro) shares: at most
/// [`MAX_LINE_BYTES`], ASCII, a trailing `\r` tolerated, blank lines, `#` lines that must be
/// `header`, exactly `N` fields separated by single spaces, a timestamp first with at most
/// [`MAX_TIMESTAMP_DECIMALS`] decimals.
pub fn split_line<'a, const N: usize>(
    line: &'a [u8],
    header: &str,
) -> Result<Fields<'a, N>, LineError> {
    if line.len() > MAX_LINE_BYTES {
        return Err(LineError::TooLong { len: line.len() });
    }
    if !line.is_ascii() {
        return Err(LineError::NotAscii);
    }
    let text = std::str::from_utf8(line).map_err(|_| LineError::NotAscii)?;
    let text = text.strip_suffix('\r').unwrap_or(text);
    if text.is_empty() {
        return Ok(Fields::Blank);
    }
    if text.starts_with('#') {
        return if text == header {
            Ok(Fields::Header)
        } else {
            Err(LineError::BadHeader(text.to_owned()))
        };
    }
    let mut fields = [""; N];
    let mut found = 0;
    for field in text.split(' ') {
        if let Some(slot) = fields.get_mut(found) {
            *slot = field;
        }
        found += 1;
    }
    if found != N {
        return Err(LineError::FieldCount { found });
    }
    if let Some(t) = fields.first() {
        if t.split_once('.')
            .is_some_and(|(_, decimals)| decimals.len() > MAX_TIMESTAMP_DECIMALS)
        {
            return Err(LineError::TooManyDecimals((*t).to_owned()));
        }
    }
    Ok(Fields::Record(fields))
}

/// Parses one line (without its `\n`).
pub fn parse_line(line: &[u8]) -> Result<Line, LineError> {
    Ok(match split_line(line, ODOMETRY_HEADER)? {
        Fields::Header => Line::Header,
        Fields::Blank => Line::Blank,
        Fields::Record([t, v, s]) => Line::Record(OdometryRecord {
            timestamp_s: decimal("timestamp_s", t)?,
            speed_mps: decimal("speed_mps", v)?,
            steer_rad: decimal("steer_rad", s)?,
        }),
    })
}

/// A field that must be a finite plain decimal number (`field` names it in the error).
pub fn decimal(field: &'static str, text: &str) -> Result<f64, LineError> {
    // Plain decimals only: Rust's parser would also take "inf", "NaN" and "1e5".
    let plain = !text.is_empty()
        && text
            .bytes()
            .all(|b| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'+');
    match text.parse::<f64>() {
        Ok(x) if plain && x.is_finite() => Ok(x),
        _ => Err(LineError::BadNumber {
            field,
            text: text.to_owned(),
        }),
    }
}

/// Cuts a byte stream into lines of at most [`MAX_LINE_BYTES`], holding at most that many
/// bytes of an unfinished line: an over-long line is reported once and skipped to its
/// newline without being stored.
#[derive(Debug, Default)]
pub struct LineSplitter {
    partial: Vec<u8>,
    /// Bytes of an over-long line seen so far, while discarding it.
    discarding: Option<usize>,
    ready: std::collections::VecDeque<Result<Vec<u8>, LineError>>,
}

impl LineSplitter {
    /// An empty splitter.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds bytes; complete lines become available from [`LineSplitter::next_line`].
    pub fn push(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let newline = bytes.iter().position(|&b| b == b'\n');
            let (chunk, rest, complete) = match newline {
                Some(i) => {
                    let (line, rest) = bytes.split_at(i);
                    // `rest` starts with the newline.
                    (line, rest.get(1..).unwrap_or_default(), true)
                }
                None => (bytes, &[][..], false),
            };
            bytes = rest;
            if let Some(seen) = self.discarding.as_mut() {
                *seen = seen.saturating_add(chunk.len());
                if complete {
                    let len = *seen;
                    self.discarding = None;
                    self.ready.push_back(Err(LineError::TooLong { len }));
                }
                continue;
            }
            if self.partial.len() + chunk.len() > MAX_LINE_BYTES {
                let len = self.partial.len() + chunk.len();
                self.partial.clear();
                if complete {
                    self.ready.push_back(Err(LineError::TooLong { len }));
                } else {
                    self.discarding = Some(len);
                }
                continue;
            }
            self.partial.extend_from_slice(chunk);
            if complete {
                self.ready.push_back(Ok(std::mem::take(&mut self.partial)));
            }
        }
    }

    /// The next complete line (without its newline), or an over-long line's error.
    pub fn next_line(&mut self) -> Option<Result<Vec<u8>, LineError>> {
        self.ready.pop_front()
    }

    /// Forgets any unfinished line (after a reconnect).
    pub fn reset(&mut self) {
        self.partial.clear();
        self.discarding = None;
    }

    /// Bytes held for an unfinished line.
    pub fn pending_bytes(&self) -> usize {
        self.partial.len()
    }
}

/// Turns lines into odometry records, enforcing the header rule.
#[derive(Debug, Default)]
pub struct RecordParser {
    seen_header: bool,
}

impl RecordParser {
    /// A parser expecting a header first.
    pub fn new() -> Self {
        Self::default()
    }

    /// Expects a header again (a new connection).
    pub fn reset(&mut self) {
        self.seen_header = false;
    }

    /// `Ok(Some(record))` for a record, `Ok(None)` for a header or blank line.
    pub fn parse(&mut self, line: &[u8]) -> Result<Option<OdometryRecord>, LineError> {
        match parse_line(line)? {
            Line::Header => {
                self.seen_header = true;
                Ok(None)
            }
            Line::Blank => Ok(None),
            Line::Record(_) if !self.seen_header => Err(LineError::MissingHeader),
            Line::Record(r) => Ok(Some(r)),
        }
    }
}

impl super::LineParser for RecordParser {
    type Record = OdometryRecord;
    type Error = LineError;
    const NAME: &'static str = "odometry";

    fn parse(&mut self, line: &[u8]) -> Result<Option<OdometryRecord>, LineError> {
        RecordParser::parse(self, line)
    }

    fn reset(&mut self) {
        RecordParser::reset(self);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_line_parses_to_its_three_values() {
        let l = parse_line(b"1700000000.123456789 4.5 -0.02").unwrap();
        assert_eq!(
            l,
            Line::Record(OdometryRecord {
                timestamp_s: "1700000000.123456789".parse().unwrap(),
                speed_mps: 4.5,
                steer_rad: -0.02
            })
        );
        assert_eq!(
            parse_line(ODOMETRY_HEADER.as_bytes()).unwrap(),
            Line::Header
        );
        assert_eq!(
            parse_line(b"1 2 3\r").unwrap(),
            Line::Record(OdometryRecord {
                timestamp_s: 1.0,
                speed_mps: 2.0,
                steer_rad: 3.0
            })
        );
    }

    #[test]
    fn malformed_lines_are_named_errors() {
        type Check = fn(&LineError) -> bool;
        let cases: &[(&[u8], Check)] = &[
            (b"1 2", |e| matches!(e, LineError::FieldCount { found: 2 })),
            (b"1  2 3", |e| {
                matches!(e, LineError::FieldCount { found: 4 })
            }),
            (b"1 2 3 4", |e| {
                matches!(e, LineError::FieldCount { found: 4 })
            }),
            (b"1 NaN 3", |e| {
                matches!(
                    e,
                    LineError::BadNumber {
                        field: "speed_mps",
                        ..
                    }
                )
            }),
            (b"1 2 inf", |e| {
                matches!(
                    e,
                    LineError::BadNumber {
                        field: "steer_rad",
                        ..
                    }
                )
            }),
            (b"x 2 3", |e| {
                matches!(
                    e,
                    LineError::BadNumber {
                        field: "timestamp_s",
                        ..
                    }
                )
            }),
            (b"1.0123456789 2 3", |e| {
                matches!(e, LineError::TooManyDecimals(_))
            }),
            (b"# odometry v2", |e| matches!(e, LineError::BadHeader(_))),
            ("1 2 \u{e9}".as_bytes(), |e| {
                matches!(e, LineError::NotAscii)
            }),
        ];
        for (line, ok) in cases {
            let err = parse_line(line).unwrap_err();
            assert!(ok(&err), "{:?} gave {err:?}", String::from_utf8_lossy(line));
        }
    }

    #[test]
    fn the_splitter_reassembles_lines_across_chunks_and_skips_overlong_ones() {
        let mut s = LineSplitter::new();
        s.push(b"ab");
        s.push(b"c\nde");
        assert_eq!(s.next_line(), Some(Ok(b"abc".to_vec())));
        assert_eq!(s.next_line(), None);
        let long = vec![b'x'; 300];
        s.push(b"f\n");
        s.push(&long[..200]);
        assert!(s.pending_bytes() <= MAX_LINE_BYTES);
        s.push(&long[200..]);
        assert!(s.pending_bytes() <= MAX_LINE_BYTES);
        s.push(b"\nok\n");
        assert_eq!(s.next_line(), Some(Ok(b"def".to_vec())));
        assert_eq!(s.next_line(), Some(Err(LineError::TooLong { len: 300 })));
        assert_eq!(s.next_line(), Some(Ok(b"ok".to_vec())));
    }

    #[test]
    fn a_line_of_exactly_256_bytes_is_accepted_and_257_is_not() {
        let mut s = LineSplitter::new();
        let mut line = vec![b'1'; 256];
        line.push(b'\n');
        s.push(&line);
        assert!(matches!(s.next_line(), Some(Ok(l)) if l.len() == 256));
        let mut line = vec![b'1'; 257];
        line.push(b'\n');
        s.push(&line);
        assert_eq!(s.next_line(), Some(Err(LineError::TooLong { len: 257 })));
    }

    #[test]
    fn records_before_the_header_are_rejected_and_later_ones_accepted() {
        let mut p = RecordParser::new();
        assert_eq!(p.parse(b"1 2 3"), Err(LineError::MissingHeader));
        assert_eq!(p.parse(ODOMETRY_HEADER.as_bytes()), Ok(None));
        assert!(matches!(p.parse(b"1 2 3"), Ok(Some(_))));
        assert_eq!(p.parse(b""), Ok(None));
    }

    #[test]
    fn a_record_survives_a_round_trip_through_its_line() {
        let r = OdometryRecord {
            timestamp_s: 1_700_000_000.25,
            speed_mps: -1.5,
            steer_rad: 0.125,
        };
        let Line::Record(back) = parse_line(r.to_line().as_bytes()).unwrap() else {
            panic!("not a record")
        };
        assert_eq!(back, r);
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_never_panic_and_never_buffer_more_than_a_line(
            chunks in proptest::collection::vec(proptest::collection::vec(proptest::num::u8::ANY, 0..400), 0..20)
        ) {
            let mut s = LineSplitter::new();
            let mut p = RecordParser::new();
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
