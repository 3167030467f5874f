//! Odometry from a file in the stream format.

use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::time::Duration;

use super::{LineSplitter, OdometryError, OdometryPoll, OdometrySource, RecordParser};

const READ_CHUNK: usize = 8192;

/// Reads a file incrementally: memory stays at one read chunk plus one line.
#[derive(Debug)]
pub struct FileOdometry<R = File> {
    reader: R,
    splitter: LineSplitter,
    parser: RecordParser,
    line_no: u64,
    eof: bool,
    failed: bool,
}

impl FileOdometry<File> {
    /// Opens `path`.
    pub fn open(path: &Path) -> Result<Self, OdometryError> {
        let file = File::open(path).map_err(|source| OdometryError::Open {
            path: path.to_owned(),
            source,
        })?;
        Ok(Self::from_reader(file))
    }
}

impl<R: Read> FileOdometry<R> {
    /// Reads from any byte source (a file, a test buffer).
    pub fn from_reader(reader: R) -> Self {
        Self {
            reader,
            splitter: LineSplitter::new(),
            parser: RecordParser::new(),
            line_no: 0,
            eof: false,
            failed: false,
        }
    }

    /// Lines read so far.
    pub fn lines_read(&self) -> u64 {
        self.line_no
    }

    fn next(&mut self) -> Result<OdometryPoll, OdometryError> {
        loop {
            if let Some(line) = self.splitter.next_line() {
                self.line_no += 1;
                let parsed = line.and_then(|l| self.parser.parse(&l));
                match parsed {
                    Ok(Some(record)) => return Ok(OdometryPoll::Record(record)),
                    Ok(None) => continue,
                    Err(source) => {
                        return Err(OdometryError::Line {
                            line: self.line_no,
                            source,
                        })
                    }
                }
            }
            if self.eof || self.failed {
                return Ok(OdometryPoll::Ended);
            }
            let mut chunk = [0u8; READ_CHUNK];
            match self.reader.read(&mut chunk) {
                Ok(0) => {
                    self.eof = true;
                    // A last line without a newline still counts.
                    if self.splitter.pending_bytes() > 0 {
                        self.splitter.push(b"\n");
                    }
                }
                Ok(n) => self.splitter.push(chunk.get(..n).unwrap_or_default()),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.failed = true;
                    return Err(OdometryError::Read(e));
                }
            }
        }
    }
}

impl<R: Read + Send> OdometrySource for FileOdometry<R> {
    fn poll_next(&mut self, _timeout: Duration) -> Result<OdometryPoll, OdometryError> {
        self.next()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{LineError, OdometryRecord, ODOMETRY_HEADER};
    use super::*;

    #[test]
    fn a_file_yields_its_records_and_a_bad_line_costs_only_that_line() {
        let text = format!(
            "{ODOMETRY_HEADER}\n100.0 1 0.1\nnot a record\n100.05 2 0.2\n{}\n100.1 3 0.3",
            "9".repeat(300)
        );
        let mut src = FileOdometry::from_reader(std::io::Cursor::new(text.into_bytes()));
        let t = Duration::ZERO;
        let rec = |t, v, s| OdometryRecord {
            timestamp_s: t,
            speed_mps: v,
            steer_rad: s,
        };
        assert_eq!(
            src.poll_next(t).unwrap(),
            OdometryPoll::Record(rec(100.0, 1.0, 0.1))
        );
        let e = src.poll_next(t).unwrap_err();
        assert!(e.is_recoverable());
        assert!(
            matches!(
                e,
                OdometryError::Line {
                    line: 3,
                    source: LineError::BadNumber {
                        field: "timestamp_s",
                        ..
                    }
                }
            ),
            "{e}"
        );
        assert_eq!(
            src.poll_next(t).unwrap(),
            OdometryPoll::Record(rec(100.05, 2.0, 0.2))
        );
        assert!(matches!(
            src.poll_next(t).unwrap_err(),
            OdometryError::Line {
                line: 5,
                source: LineError::TooLong { len: 300 }
            }
        ));
        assert_eq!(
            src.poll_next(t).unwrap(),
            OdometryPoll::Record(rec(100.1, 3.0, 0.3))
        );
        assert_eq!(src.poll_next(t).unwrap(), OdometryPoll::Ended);
        assert_eq!(src.poll_next(t).unwrap(), OdometryPoll::Ended);
    }

    #[test]
    fn a_missing_file_is_a_typed_error() {
        let e = FileOdometry::open(Path::new("/nonexistent/odometry.txt")).unwrap_err();
        assert!(matches!(e, OdometryError::Open { .. }));
        assert!(!e.is_recoverable());
    }
}
