//! The gyro of radar-only driving: its yaw rate in the gyro line format of
//! `docs/contracts.md` ([`format`]), read over TCP ([`TcpGyro`]) or from a file
//! ([`FileGyro`]), or made from a recording's ground truth with a MEMS part's bias and noise
//! ([`TruthGyro`], `--gyro-from-truth`), behind the [`GyroSource`] seam. The pipeline
//! integrates the samples into the filter's prediction (`crate::pipeline::gyro`).
//!
//! IO: [`TcpGyro`] connects (on the caller's tokio runtime), [`FileGyro`] reads a file;
//! [`format`] and [`TruthGyro`] do none.

pub mod format;
mod tcp;
#[cfg(feature = "sim")]
mod truth;

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Duration;

use radar_driver::odometry::{open_regular, LineReader};

pub use format::{GyroLineError, GyroParser, GyroSample, GYRO_HEADER};
pub use tcp::{tcp_gyro_settings, TcpGyro, TcpGyroSettings, GYRO_CAPACITY};
#[cfg(feature = "sim")]
pub use truth::TruthGyro;

/// The result of asking a source for its next sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GyroPoll {
    /// A sample.
    Sample(GyroSample),
    /// Nothing yet (a live source within the timeout).
    Pending,
    /// No more samples (end of file, or the source was shut down).
    Ended,
}

/// Why a source could not give a sample.
#[derive(Debug, thiserror::Error)]
pub enum GyroError {
    /// One line was bad; the source carries on with the next one.
    #[error("gyro line {line} is malformed")]
    Line {
        /// 1-based line number within the file or connection.
        line: u64,
        /// What was wrong.
        #[source]
        source: GyroLineError,
    },
    /// The gyro file cannot be opened.
    #[error("cannot open gyro file {path}")]
    Open {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Reading the file failed; the source has ended.
    #[error("reading the gyro failed")]
    Read(#[source] std::io::Error),
}

impl GyroError {
    /// True when the source can carry on after this error (it cost one line only).
    pub fn is_recoverable(&self) -> bool {
        matches!(self, GyroError::Line { .. })
    }
}

/// A source of gyro samples in time order.
pub trait GyroSource: Send {
    /// The next sample, waiting at most `timeout` for a live source (a file answers at
    /// once). A recoverable error costs one line: call again for the next.
    fn poll_next(&mut self, timeout: Duration) -> Result<GyroPoll, GyroError>;
}

/// Opens the source `[gyro]` names: a [`TcpGyro`] (spawned on `runtime`, stopped by
/// `shutdown`), a [`FileGyro`], or `None`.
pub fn open_configured(
    settings: &config::GyroSettings,
    runtime: &tokio::runtime::Handle,
    shutdown: radar_driver::Shutdown,
) -> Result<Option<Box<dyn GyroSource>>, GyroError> {
    Ok(match &settings.source {
        config::gyro::GyroSource::None => None,
        config::gyro::GyroSource::Tcp { address } => Some(Box::new(TcpGyro::spawn(
            runtime,
            tcp_gyro_settings(*address),
            shutdown,
        ))),
        config::gyro::GyroSource::File { path } => Some(Box::new(FileGyro::open(path)?)),
    })
}

/// Reads a gyro file incrementally: memory stays at one read chunk plus one line.
#[derive(Debug)]
pub struct FileGyro<R = File> {
    lines: LineReader<R>,
    parser: GyroParser,
}

impl FileGyro<File> {
    /// Opens `path`, a regular file (a FIFO or a device is refused without blocking).
    pub fn open(path: &Path) -> Result<Self, GyroError> {
        let file = open_regular(path).map_err(|source| GyroError::Open {
            path: path.to_owned(),
            source,
        })?;
        Ok(Self::from_reader(file))
    }
}

impl<R: Read> FileGyro<R> {
    /// Reads from any byte source (a file, a test buffer).
    pub fn from_reader(reader: R) -> Self {
        Self {
            lines: LineReader::new(reader),
            parser: GyroParser::new(),
        }
    }

    fn next(&mut self) -> Result<GyroPoll, GyroError> {
        loop {
            let Some((line_no, line)) = self.lines.next_line().map_err(GyroError::Read)? else {
                return Ok(GyroPoll::Ended);
            };
            match line
                .map_err(GyroLineError::from)
                .and_then(|l| self.parser.parse(&l))
            {
                Ok(Some(sample)) => return Ok(GyroPoll::Sample(sample)),
                Ok(None) => {}
                Err(source) => {
                    return Err(GyroError::Line {
                        line: line_no,
                        source,
                    })
                }
            }
        }
    }
}

impl<R: Read + Send> GyroSource for FileGyro<R> {
    fn poll_next(&mut self, _timeout: Duration) -> Result<GyroPoll, GyroError> {
        self.next()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(src: &mut dyn GyroSource) -> (Vec<GyroSample>, Vec<GyroError>) {
        let (mut samples, mut errors) = (Vec::new(), Vec::new());
        for _ in 0..1000 {
            match src.poll_next(Duration::ZERO) {
                Ok(GyroPoll::Sample(s)) => samples.push(s),
                Ok(GyroPoll::Pending) => {}
                Ok(GyroPoll::Ended) => break,
                Err(e) => {
                    assert!(e.is_recoverable(), "{e}");
                    errors.push(e);
                }
            }
        }
        (samples, errors)
    }

    #[test]
    fn a_file_of_samples_reads_back_and_a_bad_line_costs_that_line() {
        let mut text = format!("{GYRO_HEADER}\n1.0 0.1\n1.01 nope\n");
        text.push_str(&"9".repeat(5000));
        text.push_str("\n1.02 -0.2\n\n1.03 0.3");
        let mut src = FileGyro::from_reader(text.as_bytes());
        let (samples, errors) = drain(&mut src);
        assert_eq!(
            samples.iter().map(|s| s.yaw_rate_rad_s).collect::<Vec<_>>(),
            vec![0.1, -0.2, 0.3]
        );
        assert_eq!(errors.len(), 2);
        assert!(matches!(
            errors[0],
            GyroError::Line {
                line: 3,
                source: GyroLineError::BadNumber { .. }
            }
        ));
        assert!(matches!(
            errors[1],
            GyroError::Line {
                line: 4,
                source: GyroLineError::TooLong { .. }
            }
        ));
    }

    #[test]
    fn a_missing_file_is_a_typed_error() {
        let e = FileGyro::open(Path::new("/nonexistent/gyro.txt")).unwrap_err();
        assert!(matches!(e, GyroError::Open { .. }));
        assert!(!e.is_recoverable());
    }
}
