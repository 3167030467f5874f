//! Why the live output or the Zenoh odometry could not start: the one error of the live
//! output, its key conventions and the Zenoh session.

/// Why the live output (or the Zenoh odometry) could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `[output.zenoh] enabled = true` or `[odometry] source = "zenoh"` in a build without the
    /// `zenoh` feature.
    #[error("[output.zenoh] is enabled or [odometry] source is \"zenoh\" but this slam-node was built without its `zenoh` feature (cargo build --release -p slam-node --features zenoh)")]
    NotBuilt,
    /// The Zenoh session could not be opened (bad endpoint, port in use, no router).
    #[error("opening the Zenoh session: {0}")]
    Open(String),
    /// A key, a publisher or a subscriber could not be declared.
    #[error("declaring the Zenoh publisher or subscriber for {key}: {message}")]
    Declare {
        /// The key.
        key: String,
        /// Zenoh's message.
        message: String,
    },
    /// rmw_zenoh's keys need the type's hash, and this type's is not tabulated.
    #[error("no RIHS01 type hash is known for {0}: the rmw_zenoh convention cannot key it")]
    UnknownTypeHash(String),
    /// The publisher thread could not be started or stopped answering.
    #[error("the Zenoh publisher thread: {0}")]
    Thread(String),
}
