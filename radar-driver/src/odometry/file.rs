//! Odometry from a file in the stream format.

use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::time::Duration;

use super::{LineReader, OdometryError, OdometryPoll, OdometrySource, RecordParser};

/// Reads a file incrementally: memory stays at one read chunk plus one line.
#[derive(Debug)]
pub struct FileOdometry<R = File> {
    lines: LineReader<R>,
    parser: RecordParser,
}

impl FileOdometry<File> {
    /// Opens `path`, a regular file (a FIFO or a device is refused without blocking).
    pub fn open(path: &Path) -> Result<Self, OdometryError> {
        let file = super::open_regular(path).map_err(|source| OdometryError::Open {
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
            lines: LineReader::new(reader),
            parser: RecordParser::new(),
        }
    }

    /// Lines read so far.
    pub fn lines_read(&self) -> u64 {
        self.lines.lines_read()
    }

    fn next(&mut self) -> Result<OdometryPoll, OdometryError> {
        loop {
            let Some((line_no, line)) = self.lines.next_line().map_err(OdometryError::Read)? else {
                return Ok(OdometryPoll::Ended);
            };
            match line.and_then(|l| self.parser.parse(&l)) {
                Ok(Some(record)) => return Ok(OdometryPoll::Record(record)),
                Ok(None) => {}
                Err(source) => {
                    return Err(OdometryError::Line {
                        line: line_no,
                        source,
                    })
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
