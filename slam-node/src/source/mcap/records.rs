//! An MCAP file's records, streamed through the `mcap` crate's sans-IO linear reader with
//! the file's own size as a bound on every read it asks for. Does file IO (reads the file
//! it is given, nothing else).
//!
//! The linear reader asks for a record's whole body once it has read the record's length
//! field, and allocates what it asks for before a byte arrives: a length field, or a chunk's
//! compression-string length, that claims more than the file holds would cost that much
//! memory (issue 38, item 8: a 191 KB file took 1.6 GB). Here a request for more bytes than
//! are left in the file is refused with [`McapFileError::ClaimBeyondFile`] before anything
//! is allocated, so what the reader buffers from the file is at most the file's size.
//! Chunks come out of the reader whole and are opened by [`super::chunk`], which bounds a
//! compressed chunk's claimed uncompressed size by what its bytes can expand to and by an
//! absolute cap before decompressing.
//!
//! A stop request (the daemon's Ctrl-C flag) is honoured between records, between
//! reads of the file (at most [`READ_BYTES`] each, so a 256 MiB record on slow storage does
//! not hold it up) and between blocks of a chunk's decompression.

use std::fs::File;
use std::io::Read;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};

use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::chunk::{read_chunk, ChunkLimits};

/// The most read from the file at once, between checks of the stop request.
pub const READ_BYTES: usize = 4 << 20;

/// Why reading the file's records stopped before its end.
#[derive(Debug, thiserror::Error)]
pub enum McapFileError {
    /// The file could not be read.
    #[error("reading the file")]
    Io(#[source] std::io::Error),
    /// A record (or a chunk's header, or a record in an uncompressed chunk) claims more bytes
    /// than the file holds after it: a corrupt length field, or a file cut short.
    #[error(
        "a record at byte {offset} needs {need} more bytes but the file has {left} left \
         (a length field is corrupt, or the file is cut short)"
    )]
    ClaimBeyondFile {
        /// Bytes of the file read so far.
        offset: u64,
        /// Bytes the reader asked for.
        need: u64,
        /// Bytes left in the file.
        left: u64,
    },
    /// The `mcap` crate refused what it read (bad magic, a chunk whose sizes disagree, a
    /// record over the length limit, a decompression failure).
    #[error(transparent)]
    Mcap(#[from] mcap::McapError),
    /// A chunk was refused: its claimed size is more than its bytes can expand to or over
    /// the cap, or its data disagrees with its header.
    #[error("the chunk record at byte {offset}: {source}")]
    Chunk {
        /// The chunk record's offset in the file (its opcode).
        offset: u64,
        /// Why.
        #[source]
        source: super::chunk::ChunkError,
    },
    /// The file ended, between records, before its footer.
    #[error("the file ends before its footer (cut short)")]
    NoFooter,
}

/// How reading ended without an error in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordsEnd {
    /// Every record was read, up to the file's end magic.
    Complete,
    /// The caller asked to stop (`on_record` broke, or the stop flag was set).
    Stopped,
}

/// Streams `file`'s records (opcode and body) to `on_record` in file order, records inside
/// chunks included (not the chunk records themselves), until the end of the file, an error
/// in it, `on_record` breaks or `stop` is set. `limits.max_record` bounds any one record,
/// compressed chunks' decompressed records too; `limits.max_uncompressed` a chunk's
/// uncompressed size.
pub fn read_records(
    mut file: File,
    limits: ChunkLimits,
    stop: &AtomicBool,
    mut on_record: impl FnMut(u8, &[u8]) -> ControlFlow<()>,
) -> Result<RecordsEnd, McapFileError> {
    let mut on_record = |opcode, data: &[u8]| {
        if stop.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            on_record(opcode, data)
        }
    };
    let record_length_limit = usize::try_from(limits.max_record).unwrap_or(usize::MAX);
    let size = file.metadata().map_err(McapFileError::Io)?.len();
    let mut offset = 0u64;
    let mut seen_footer = false;
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(record_length_limit)
            .with_emit_chunks(true),
    );
    while let Some(event) = reader.next_event() {
        if stop.load(Ordering::Relaxed) {
            return Ok(RecordsEnd::Stopped);
        }
        match event? {
            LinearReadEvent::ReadRequest(need) => {
                let left = size.saturating_sub(offset);
                if left == 0 {
                    break; // the end of the file
                }
                if need as u64 > left {
                    return Err(McapFileError::ClaimBeyondFile {
                        offset,
                        need: need as u64,
                        left,
                    });
                }
                // A short read is asked for again (the reader asks for what is still missing).
                let read = file
                    .read(reader.insert(need.min(READ_BYTES)))
                    .map_err(McapFileError::Io)?;
                if read == 0 {
                    break; // the file shrank while being read: its end
                }
                offset += read as u64;
                reader.notify_read(read);
            }
            LinearReadEvent::Record { opcode, data } if opcode == mcap::records::op::CHUNK => {
                // The reader asks for exactly what a record needs: the chunk record ends at
                // `offset`.
                let start = offset.saturating_sub(9 + data.len() as u64);
                let flow =
                    read_chunk(data, limits, stop, &mut on_record).map_err(|e| e.at(start))?;
                if flow.is_break() {
                    return Ok(RecordsEnd::Stopped);
                }
            }
            LinearReadEvent::Record { opcode, data } => {
                seen_footer |= opcode == mcap::records::op::FOOTER;
                if on_record(opcode, data).is_break() {
                    return Ok(RecordsEnd::Stopped);
                }
            }
        }
    }
    if seen_footer {
        Ok(RecordsEnd::Complete)
    } else {
        Err(McapFileError::NoFooter)
    }
}
