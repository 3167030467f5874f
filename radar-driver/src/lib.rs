//! Async tokio client for a Navtech radar: handshake, watchdog, reconnection, rotation assembly, hand-off.
