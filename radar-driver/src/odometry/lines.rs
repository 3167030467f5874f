//! A file of lines in the stream format, read incrementally: the file reader of the odometry
//! ([`super::FileOdometry`]) and of any other line stream (slam-node's gyro file) share it.
//! Memory stays at one read chunk plus one line ([`super::MAX_LINE_BYTES`]) whatever the
//! file's size.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::{LineError, LineSplitter};

const READ_CHUNK: usize = 8192;

/// Opens `path` for reading line by line, refusing anything that is not a regular file (a
/// FIFO, a device, a directory) before opening it: opening a FIFO would block until a
/// writer comes, deaf to Ctrl-C.
///
/// # Errors
/// The OS's error, or `InvalidInput` naming what the path is.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    let not_regular = |what: &str| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("not a regular file ({what}); a stream of lines is read from a file"),
        )
    };
    // `metadata` follows symlinks and opens nothing.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(not_regular(if meta.is_dir() {
            "a directory"
        } else {
            "a FIFO, socket or device"
        }));
    }
    let file = File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular("replaced while opening"));
    }
    Ok(file)
}

/// A line's number (from 1) and its bytes, or why the splitter refused it.
pub type NumberedLine = (u64, Result<Vec<u8>, LineError>);

/// Numbered lines of a byte source.
#[derive(Debug)]
pub struct LineReader<R = File> {
    reader: R,
    splitter: LineSplitter,
    line_no: u64,
    eof: bool,
    failed: bool,
}

impl<R: Read> LineReader<R> {
    /// Lines of `reader`.
    pub fn new(reader: R) -> Self {
        Self {
            reader,
            splitter: LineSplitter::new(),
            line_no: 0,
            eof: false,
            failed: false,
        }
    }

    /// Lines read so far.
    pub fn lines_read(&self) -> u64 {
        self.line_no
    }

    /// The next line with its number (from 1), or the splitter's error for a line too long
    /// or not text; `Ok(None)` at the end (a last line without a newline still counts);
    /// a read error once, then the end.
    ///
    /// # Errors
    /// The source's read error.
    pub fn next_line(&mut self) -> std::io::Result<Option<NumberedLine>> {
        loop {
            if let Some(line) = self.splitter.next_line() {
                self.line_no += 1;
                return Ok(Some((self.line_no, line)));
            }
            if self.eof || self.failed {
                return Ok(None);
            }
            let mut chunk = [0u8; READ_CHUNK];
            match self.reader.read(&mut chunk) {
                Ok(0) => {
                    self.eof = true;
                    if self.splitter.pending_bytes() > 0 {
                        self.splitter.push(b"\n");
                    }
                }
                Ok(n) => self.splitter.push(chunk.get(..n).unwrap_or_default()),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.failed = true;
                    return Err(e);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_or_a_directory_is_refused_without_blocking() {
        let dir = std::env::temp_dir().join(format!("lines-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = open_regular(&dir).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let fifo = dir.join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let e = open_regular(&fifo).unwrap_err();
            assert!(e.to_string().contains("FIFO"), "{e}");
        }
        let file = dir.join("lines.txt");
        std::fs::write(&file, "a\nb").unwrap();
        let mut lines = LineReader::new(open_regular(&file).unwrap());
        assert_eq!(lines.next_line().unwrap().unwrap().1.unwrap(), b"a");
        let (n, last) = lines.next_line().unwrap().unwrap();
        assert_eq!((n, last.unwrap()), (2, b"b".to_vec()));
        assert!(lines.next_line().unwrap().is_none());
        std::fs::remove_dir_all(&dir).ok();
    }
}
