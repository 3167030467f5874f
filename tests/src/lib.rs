//! End-to-end tests across crates over loopback live in `tests/`.
