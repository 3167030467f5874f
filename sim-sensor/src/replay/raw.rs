//! Raw Colossus byte streams (what `radar-driver --record` writes: the radar's bytes as
//! sent, no framing of our own): the first configuration is announced, the FFT frames are
//! re-served with their recorded encoder values, sweep counters and timestamps.
//!
//! Garbage inside the recording costs what the decoder skips (it resynchronises), never
//! the replay. The file is read in bounded chunks, so memory does not grow with its size.

use std::path::{Path, PathBuf};

use bytes::BytesMut;
use protocol::{Configuration, FftData, FrameDecoder, Message};
use tokio::io::AsyncReadExt;

use crate::error::ReplayError;

/// Bytes read from the file at a time.
pub const READ_CHUNK: usize = 64 * 1024;
/// How far into a recording its configuration must appear.
pub const MAX_CONFIGURATION_SEARCH: u64 = 16 << 20;

/// A recorded stream, opened and checked.
#[derive(Debug, Clone)]
pub struct RawRecording {
    /// The file.
    pub path: PathBuf,
    /// Its first configuration message.
    pub configuration: Configuration,
}

impl RawRecording {
    /// Reads up to [`MAX_CONFIGURATION_SEARCH`] bytes to find the first configuration, which
    /// must come before the first FFT frame (a radar sends it first).
    pub async fn open(path: &Path) -> Result<RawRecording, ReplayError> {
        let mut reader = RawReader::open(path).await?;
        let fail = |reason: &str| ReplayError::RawStream {
            path: path.to_path_buf(),
            reason: reason.to_string(),
        };
        loop {
            if reader.bytes_read > MAX_CONFIGURATION_SEARCH {
                return Err(fail("no configuration message in the first 16 MiB"));
            }
            match reader.next_message().await? {
                None => return Err(fail("no configuration message before the end")),
                Some(Message::Configuration(configuration)) => {
                    return Ok(RawRecording {
                        path: path.to_path_buf(),
                        configuration: *configuration,
                    })
                }
                Some(Message::FftData(_)) => {
                    return Err(fail("FFT data before any configuration message"))
                }
                Some(_) => {}
            }
        }
    }
}

/// Reads one recording's frames in order.
#[derive(Debug)]
pub struct RawReader {
    path: PathBuf,
    file: tokio::fs::File,
    buf: BytesMut,
    decoder: FrameDecoder,
    eof: bool,
    bytes_read: u64,
    /// Frames the decoder rejected (garbage in the recording).
    pub decode_errors: u64,
}

impl RawReader {
    /// Opens the file.
    pub async fn open(path: &Path) -> Result<RawReader, ReplayError> {
        let file = tokio::fs::File::open(path)
            .await
            .map_err(|source| ReplayError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(RawReader {
            path: path.to_path_buf(),
            file,
            buf: BytesMut::with_capacity(READ_CHUNK),
            decoder: FrameDecoder::new(),
            eof: false,
            bytes_read: 0,
            decode_errors: 0,
        })
    }

    /// The next decodable message, `None` at the end of the file. A stretch of more than
    /// [`MAX_CONFIGURATION_SEARCH`] bytes without one (`/dev/zero`, a file that is not a
    /// recording) is an error, so a replay never reads without end.
    pub async fn next_message(&mut self) -> Result<Option<Message>, ReplayError> {
        let start = self.bytes_read;
        loop {
            if self.bytes_read - start > MAX_CONFIGURATION_SEARCH {
                return Err(ReplayError::RawStream {
                    path: self.path.clone(),
                    reason: format!("no decodable frame in {} bytes", self.bytes_read - start),
                });
            }
            // At the end of the file the decoder must give up any frame it holds back while
            // waiting to see whether a signature follows it.
            let decoded = if self.eof {
                self.decoder.decode_eof(&mut self.buf)
            } else {
                self.decoder.decode(&mut self.buf)
            };
            match decoded {
                Ok(Some(message)) => return Ok(Some(message)),
                Ok(None) if self.eof => return Ok(None),
                Ok(None) => self.fill().await?,
                Err(error) => {
                    self.decode_errors += 1;
                    tracing::debug!(path = %self.path.display(), %error, "skipping a bad frame in the recording");
                }
            }
        }
    }

    /// The next FFT frame (other messages are skipped), `None` at the end.
    pub async fn next_fft(&mut self) -> Result<Option<FftData>, ReplayError> {
        loop {
            match self.next_message().await? {
                None => return Ok(None),
                Some(Message::FftData(fft)) => return Ok(Some(fft)),
                Some(_) => {}
            }
        }
    }

    async fn fill(&mut self) -> Result<(), ReplayError> {
        self.buf.reserve(READ_CHUNK);
        let n = (&mut self.file)
            .take(READ_CHUNK as u64)
            .read_buf(&mut self.buf)
            .await
            .map_err(|source| ReplayError::Io {
                path: self.path.clone(),
                source,
            })?;
        if n == 0 {
            self.eof = true;
        }
        self.bytes_read += n as u64;
        Ok(())
    }
}
