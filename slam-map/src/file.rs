//! The map on disk: [`Map::save`] writes atomically, [`Map::load`] reads with every length
//! checked against the file before it is trusted.
//!
//! Saving writes the whole file to a temporary file in the target's folder (named
//! `.<name>.<random>.tmp`), flushes it to the disk (`fsync`), renames it over the target and
//! flushes the folder, so a crash or a failed write at any moment leaves either the previous
//! file whole or the new one whole; a failed save removes its temporary file.

use std::fs::File;
use std::io::{self, BufReader, Write};
use std::path::Path;

use crate::codec::{read_header, read_payload, Limits, HEADER_LEN};
use crate::error::{FormatError, LoadError, SaveError, WriteError};
use crate::model::Map;

impl Map {
    /// Writes the map to `path` atomically; returns the file's size in bytes.
    pub fn save(&self, path: &Path) -> Result<u64, SaveError> {
        let fail = |reason| SaveError {
            path: path.to_owned(),
            reason,
        };
        let bytes = self.to_bytes().map_err(fail)?;
        write_atomically(path, &bytes, |f, b| f.write_all(b))
            .map_err(|e| fail(WriteError::Io(e)))?;
        Ok(bytes.len() as u64)
    }

    /// Reads the map at `path` with the default [`Limits`].
    pub fn load(path: &Path) -> Result<Map, LoadError> {
        Self::load_with(path, &Limits::default())
    }

    /// Reads the map at `path`: refuses a path that is not a regular file before opening it
    /// (a FIFO would block), then checks the header, the declared length against `limits`
    /// and the file's size, the CRC, the payload and the format's rules.
    pub fn load_with(path: &Path, limits: &Limits) -> Result<Map, LoadError> {
        load_inner(path, limits).map_err(|reason| LoadError {
            path: path.to_owned(),
            reason,
        })
    }
}

fn load_inner(path: &Path, limits: &Limits) -> Result<Map, FormatError> {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Err(FormatError::Missing),
        Err(e) => return Err(FormatError::Io(e)),
    };
    if !meta.is_file() {
        return Err(FormatError::NotAFile);
    }
    let file = File::open(path).map_err(|e| match e.kind() {
        io::ErrorKind::NotFound => FormatError::Missing,
        _ => FormatError::Io(e),
    })?;
    let size = file.metadata()?.len();
    let mut r = BufReader::new(file);
    let header = read_header(&mut r, limits)?;
    let whole = HEADER_LEN as u64 + header.payload_len;
    if size < whole {
        return Err(FormatError::Truncated {
            expected: whole,
            found: size,
        });
    }
    if size > whole {
        return Err(FormatError::TrailingBytes(size - whole));
    }
    read_payload(&mut r, &header, true)
}

/// Writes `bytes` to `path` through a temporary file in the same folder, renamed over the
/// target once it is whole and on the disk. `write` does the writing (tests make it fail).
fn write_atomically(
    path: &Path,
    bytes: &[u8],
    write: impl FnOnce(&mut File, &[u8]) -> io::Result<()>,
) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))?;
    let prefix = format!(".{}.", name.to_string_lossy());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    write(tmp.as_file_mut(), bytes)?;
    tmp.as_file_mut().flush()?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    // The rename is durable once the folder is on the disk too.
    #[cfg(unix)]
    File::open(dir)?.sync_all()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files_in(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_write_that_fails_half_way_leaves_the_previous_file_byte_identical() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.slmap");
        let old: Vec<u8> = (0..=255u8).cycle().take(10_000).collect();
        write_atomically(&path, &old, |f, b| f.write_all(b)).unwrap();
        let new = vec![7u8; 50_000];
        let err = write_atomically(&path, &new, |f, b| {
            f.write_all(&b[..b.len() / 2])?;
            Err(io::Error::other("the disk is full"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "the disk is full");
        assert_eq!(std::fs::read(&path).unwrap(), old);
        // The temporary file is gone.
        assert_eq!(files_in(dir.path()), vec!["map.slmap".to_owned()]);
    }

    #[test]
    fn a_write_that_panics_half_way_leaves_the_previous_file_byte_identical() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.slmap");
        write_atomically(&path, b"previous", |f, b| f.write_all(b)).unwrap();
        let p = path.clone();
        let joined = std::thread::spawn(move || {
            write_atomically(&p, b"the new map", |f, b| {
                f.write_all(&b[..4]).unwrap();
                panic!("killed mid-write");
            })
        })
        .join();
        assert!(joined.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"previous");
        assert_eq!(files_in(dir.path()), vec!["map.slmap".to_owned()]);
    }

    #[test]
    fn a_whole_write_replaces_the_file_and_leaves_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.slmap");
        write_atomically(&path, b"first", |f, b| f.write_all(b)).unwrap();
        write_atomically(&path, b"second", |f, b| f.write_all(b)).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(files_in(dir.path()), vec!["map.slmap".to_owned()]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode & 0o644, 0o644, "readable by others: {mode:o}");
        }
    }
}
