//! The header constants of the map file, shared by the codec and its errors. No IO.

/// The first eight bytes of every map file. The first byte is not ASCII (a text file is
/// not taken for a map) and the CR LF pair catches a transfer that rewrote line endings.
pub const MAGIC: [u8; 8] = [0x89, b'S', b'L', b'M', b'A', b'P', b'\r', b'\n'];

/// The format version this build writes (it reads every version up to it).
pub const FORMAT_VERSION: u32 = 4;

/// Bytes before the payload.
pub const HEADER_LEN: usize = 24;

/// Points a submap's scan holds at most (format version 3): 8 bytes each.
pub const MAX_SCAN_POINTS: usize = 1 << 16;

/// Positions a submap's path holds at most (format version 4): 8 bytes each.
pub const MAX_PATH_POINTS: usize = 1 << 12;

/// A path records the vehicle's position each time it moved this far from the last (m).
pub const PATH_SPACING_M: f64 = 2.0;
