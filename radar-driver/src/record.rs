//! Recording the raw byte stream, on a writer thread so the socket task never waits on a
//! disk.
//!
//! # Format
//!
//! A recording is the Colossus byte stream exactly as the radar sent it (every byte the
//! decoder consumed, garbage included), concatenated over reconnections, with no header
//! and no framing of our own. At each disconnection the bytes of an unfinished trailing
//! frame are left out, so each connection's bytes end on a frame boundary and the next
//! connection's configuration (message 10) starts cleanly. Any Colossus decoder reads it:
//! `protocol::FrameDecoder`, the simulator's replay, Navtech's own tools. Timing is in the
//! FFT messages' own timestamps; a replay paces itself by those. Commands the client sent
//! (21, 22, ...) are not recorded.
//!
//! If the writer falls behind by more than [`RECORD_QUEUE_CHUNKS`] chunks, or the queued
//! chunks (each charged to the driver's byte budget) would exceed that budget, chunks are
//! dropped and counted (the decoder resynchronises over such a hole on replay); the
//! socket task is never slowed.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use bytes::Bytes;
use crossbeam_channel::{bounded, Sender, TrySendError};

/// Chunks queued for the writer thread before chunks are dropped.
pub const RECORD_QUEUE_CHUNKS: usize = 1024;

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordSummary {
    /// The file.
    pub path: PathBuf,
    /// Bytes written.
    pub bytes_written: u64,
    /// Chunks dropped because the writer was behind.
    pub chunks_dropped: u64,
    /// The first write error, if one stopped the recording early.
    pub error: Option<String>,
}

#[derive(Debug, Default)]
struct Counters {
    written: AtomicU64,
    dropped: AtomicU64,
}

/// Records raw bytes to a file.
#[derive(Debug)]
pub struct Recorder {
    path: PathBuf,
    tx: Option<Sender<Bytes>>,
    counters: Arc<Counters>,
    thread: Option<JoinHandle<Option<std::io::Error>>>,
}

impl Recorder {
    /// Creates (truncates) `path`, and the folders it names that do not exist yet (a
    /// configuration's `out/vehicle/radar.colossus` on a fresh machine), and starts the
    /// writer thread.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        let file = File::create(path)?;
        let (tx, rx) = bounded::<Bytes>(RECORD_QUEUE_CHUNKS);
        let counters = Arc::new(Counters::default());
        let c = Arc::clone(&counters);
        let thread = std::thread::Builder::new()
            .name("radar-record".into())
            .spawn(move || {
                let mut out = BufWriter::with_capacity(1 << 20, file);
                for chunk in rx {
                    if let Err(e) = out.write_all(&chunk) {
                        return Some(e);
                    }
                    c.written.fetch_add(chunk.len() as u64, Ordering::Relaxed);
                }
                out.flush().err()
            })?;
        Ok(Self {
            path: path.to_owned(),
            tx: Some(tx),
            counters,
            thread: Some(thread),
        })
    }

    /// Queues `chunk` for writing; never blocks. Returns false if it was dropped.
    pub fn write(&self, chunk: Bytes) -> bool {
        if chunk.is_empty() {
            return true;
        }
        let Some(tx) = &self.tx else { return false };
        match tx.try_send(chunk) {
            Ok(()) => true,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.counters.dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }

    /// Counts a chunk dropped before reaching the queue (the driver's byte budget was full).
    pub fn count_dropped(&self) {
        self.counters.dropped.fetch_add(1, Ordering::Relaxed);
    }

    /// Bytes written so far.
    pub fn bytes_written(&self) -> u64 {
        self.counters.written.load(Ordering::Relaxed)
    }

    /// Flushes and closes the file (blocks until the writer thread has finished).
    pub fn finish(mut self) -> RecordSummary {
        self.tx = None;
        let error = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(None)) | None => None,
            Some(Ok(Some(e))) => Some(e.to_string()),
            Some(Err(_)) => Some("the recording thread panicked".to_owned()),
        };
        RecordSummary {
            path: self.path.clone(),
            bytes_written: self.counters.written.load(Ordering::Relaxed),
            chunks_dropped: self.counters.dropped.load(Ordering::Relaxed),
            error,
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        // Closing the channel lets the thread flush and exit on its own.
        self.tx = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_are_written_in_order_and_flushed_on_finish() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.bin");
        let r = Recorder::create(&path).unwrap();
        for i in 0..100u8 {
            assert!(r.write(Bytes::from(vec![i; 10])));
        }
        let s = r.finish();
        assert_eq!(
            (s.bytes_written, s.chunks_dropped, s.error),
            (1000, 0, None)
        );
        let data = std::fs::read(&path).unwrap();
        assert_eq!(data.len(), 1000);
        assert!(data
            .chunks(10)
            .enumerate()
            .all(|(i, c)| c.iter().all(|&b| usize::from(b) == i)));
    }

    #[test]
    fn an_unwritable_path_is_an_error_at_creation() {
        // A folder that cannot be made: its parent is a file.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a-file");
        std::fs::write(&file, b"x").unwrap();
        assert!(Recorder::create(&file.join("rec.bin")).is_err());
    }

    #[test]
    fn the_recording_s_missing_folders_are_made() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir
            .path()
            .join("out")
            .join("vehicle")
            .join("radar.colossus");
        let r = Recorder::create(&path).unwrap();
        drop(r);
        assert!(path.is_file());
    }
}
