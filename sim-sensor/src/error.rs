//! The simulator's error types.

use std::path::PathBuf;

/// A scene file (or a preset override) that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A scene file larger than [`crate::scene::MAX_SCENE_BYTES`].
    #[error("scene file {path} is larger than {limit} bytes")]
    TooLarge {
        /// The file.
        path: std::path::PathBuf,
        /// The limit.
        limit: u64,
    },
    /// The TOML did not parse or had an unknown key; toml's message names the key, line and
    /// column.
    #[error("scene {name}: {source}")]
    Parse {
        /// The scene's file path or shipped name.
        name: String,
        /// toml's error.
        #[source]
        source: toml::de::Error,
    },
    /// A value outside its allowed range; `field` is the dotted path in the scene file.
    #[error("scene field {field}: {reason}")]
    Invalid {
        /// Dotted path, e.g. `features[3].rho`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// No shipped scene of that name.
    #[error("no shipped scene named {name:?} (shipped: {shipped})")]
    UnknownShipped {
        /// The name asked for.
        name: String,
        /// The shipped scenes' names, comma-separated.
        shipped: String,
    },
    /// A scene file that could not be read.
    #[error("reading scene {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}

/// A recording that cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// Reading a file or directory failed.
    #[error("reading {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A PNG that does not decode.
    #[error("decoding PNG {path}: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: png::DecodingError,
    },
    /// A PNG that is not a polar scan of the expected layout (Oxford/Boreas rows with
    /// metadata columns, or RADIATE's range rows by azimuth columns).
    #[error("PNG {path} is not a polar scan of the expected layout: {reason}")]
    Layout {
        /// The file.
        path: PathBuf,
        /// What differs.
        reason: String,
    },
    /// A directory with no scans in it.
    #[error("no .png scans in {0}")]
    Empty(PathBuf),
    /// A folder whose layout is none of the known data sets'.
    #[error("{dir}: not a recording of a known layout ({looked_for}); name it with --replay-format oxford|boreas|radiate")]
    UnknownFormat {
        /// The folder.
        dir: PathBuf,
        /// What was looked for.
        looked_for: String,
    },
    /// A folder that looks like more than one data set's layout.
    #[error(
        "{dir}: ambiguous layout, it looks like {candidates}; choose one with --replay-format"
    )]
    AmbiguousFormat {
        /// The folder.
        dir: PathBuf,
        /// The layouts it matches.
        candidates: String,
    },
    /// A scan whose file name is not its timestamp (Oxford, Boreas: microseconds).
    #[error("{path}: a scan's file name must be its timestamp in microseconds")]
    BadName {
        /// The file.
        path: PathBuf,
    },
    /// A row of a scan index (RADIATE's `Navtech_Polar.txt`) that does not parse, or names
    /// a scan that is not there.
    #[error("{path}, row {row}: {reason}")]
    IndexRow {
        /// The index file.
        path: PathBuf,
        /// 1-based line number.
        row: usize,
        /// What is wrong.
        reason: String,
    },
    /// Scan times that do not increase (two scans named by the same time, `100.png` and
    /// `0100.png`, or index rows out of order).
    #[error("{path}{}: scan time {later_us} us comes after {earlier_us} us{} but is not later", row.map(|r| format!(", row {r}")).unwrap_or_default(), earlier_path.as_ref().map(|p| format!(" ({})", p.display())).unwrap_or_default())]
    OutOfOrder {
        /// The scan (Oxford, Boreas) or index file (RADIATE).
        path: PathBuf,
        /// The index's 1-based line number, where there is one.
        row: Option<usize>,
        /// The earlier scan's file, where the times are files' names (Oxford, Boreas).
        earlier_path: Option<PathBuf>,
        /// The earlier time (µs since the epoch).
        earlier_us: i64,
        /// The later time (µs since the epoch).
        later_us: i64,
    },
    /// Azimuth rows whose encoder value is at or past the recording's encoder size: no radar
    /// sends such a row and a radar driver drops it, so the scan is skipped.
    #[error(
        "{path}: {rows} of {of} azimuths carry encoder values from {min} to {max} (the first \
         is row {first_row}), at or past the encoder size {encoder_size}"
    )]
    EncoderPastSize {
        /// The scan.
        path: PathBuf,
        /// Rows past the encoder size.
        rows: usize,
        /// Rows in the scan.
        of: usize,
        /// The first such row (0-based, image order).
        first_row: usize,
        /// The smallest such encoder value.
        min: u16,
        /// The largest.
        max: u16,
        /// The recording's encoder size.
        encoder_size: u16,
    },
    /// A file too large to be an index of scans.
    #[error("{path}: {bytes} bytes is larger than the {limit} read")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A raw Colossus stream without a configuration message before its first FFT frame.
    #[error("raw stream {path}: {reason}")]
    RawStream {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// Why the simulator could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A scene problem.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A replay problem.
    #[error(transparent)]
    Replay(#[from] ReplayError),
    /// Binding a listening socket failed.
    #[error("binding {what} on {addr}: {source}")]
    Bind {
        /// "radar" or "odometry".
        what: &'static str,
        /// The requested address.
        addr: std::net::SocketAddr,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Creating or writing the ground-truth file failed.
    #[error("ground truth file {path}: {source}")]
    GroundTruth {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A setting that cannot be used.
    #[error("setting {field}: {reason}")]
    Setting {
        /// Which setting.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The radar model rejected a scene value.
    #[error("radar model: {0}")]
    Model(String),
    /// A server task panicked or was cancelled abnormally.
    #[error("server task failed: {0}")]
    Task(String),
}

/// Why one client's session ended (logged; never stops the server).
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The socket failed.
    #[error("socket: {0}")]
    Io(#[from] std::io::Error),
    /// The client sent bytes that do not decode.
    #[error("client sent garbage: {0}")]
    Garbage(String),
    /// The client closed its end.
    #[error("client closed the connection")]
    Closed,
    /// The client's socket took no data within the write timeout (it is not reading).
    #[error("client took no data for {0:?}")]
    NotReading(std::time::Duration),
    /// The client did not ask for data within the idle timeout.
    #[error("client asked for no data within {0:?}")]
    Idle(std::time::Duration),
    /// A fault injection closed the connection on purpose.
    #[error("fault injection: {0}")]
    Fault(&'static str),
    /// Rendering or re-encoding failed on the server's side.
    #[error("server-side failure: {0}")]
    Internal(String),
    /// Replay data failed while serving.
    #[error(transparent)]
    Replay(#[from] ReplayError),
}
