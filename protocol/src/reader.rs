//! A bounds-checked big/little-endian reader over a byte slice: every read checks what
//! remains and returns [`PayloadError::Truncated`] instead of panicking.

use crate::error::PayloadError;

/// Cursor over a payload. Reads never panic.
#[derive(Debug)]
pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    /// Bytes consumed so far.
    pub(crate) fn position(&self) -> usize {
        self.pos
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], PayloadError> {
        let end = self.pos.checked_add(N).ok_or(PayloadError::Truncated {
            needed: usize::MAX,
            got: self.buf.len(),
        })?;
        let bytes = self.buf.get(self.pos..end).ok_or(PayloadError::Truncated {
            needed: end,
            got: self.buf.len(),
        })?;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        self.pos = end;
        Ok(out)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, PayloadError> {
        Ok(self.take::<1>()?[0])
    }

    pub(crate) fn u16_be(&mut self) -> Result<u16, PayloadError> {
        self.take::<2>().map(u16::from_be_bytes)
    }

    pub(crate) fn u32_be(&mut self) -> Result<u32, PayloadError> {
        self.take::<4>().map(u32::from_be_bytes)
    }

    pub(crate) fn u32_le(&mut self) -> Result<u32, PayloadError> {
        self.take::<4>().map(u32::from_le_bytes)
    }

    pub(crate) fn f32_be(&mut self) -> Result<f32, PayloadError> {
        self.take::<4>().map(f32::from_be_bytes)
    }
}
