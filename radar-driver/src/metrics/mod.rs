//! Driver metrics: lock-free counters updated by the socket task, read as a
//! [`MetricsSnapshot`] by anyone holding the shared [`Metrics`].

mod latency;

pub use latency::{LatencyHistogram, LatencySummary};

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crate::budget::ByteBudget;

/// What kind of malformed input the frame decoder rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DecodeErrorKind {
    /// Bytes that did not start with the 16-byte signature (skipped while resynchronising).
    Signature,
    /// A header whose version is not 1.
    Version,
    /// A payload size of 1,000,000 bytes or more.
    Oversized,
    /// A payload shorter than its message type needs, or a frame cut short by the next
    /// frame's signature (the protocol decoder's `PayloadError::CutShort`).
    Truncated,
    /// An FFT payload whose layout is impossible (data offset beyond the payload, odd 16-bit bins).
    FftLayout,
    /// A timestamp whose nanoseconds are 10^9 or more.
    Timestamp,
    /// A protobuf tail that does not decode.
    Protobuf,
    /// Any other malformed payload.
    Other,
}

impl DecodeErrorKind {
    /// Every kind, in the order of [`DecodeErrorCounts`]' fields.
    pub const ALL: [DecodeErrorKind; 8] = [
        DecodeErrorKind::Signature,
        DecodeErrorKind::Version,
        DecodeErrorKind::Oversized,
        DecodeErrorKind::Truncated,
        DecodeErrorKind::FftLayout,
        DecodeErrorKind::Timestamp,
        DecodeErrorKind::Protobuf,
        DecodeErrorKind::Other,
    ];

    fn index(self) -> usize {
        self as usize
    }
}

/// Decode errors by kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecodeErrorCounts {
    /// See [`DecodeErrorKind::Signature`].
    pub signature: u64,
    /// See [`DecodeErrorKind::Version`].
    pub version: u64,
    /// See [`DecodeErrorKind::Oversized`].
    pub oversized: u64,
    /// See [`DecodeErrorKind::Truncated`].
    pub truncated: u64,
    /// See [`DecodeErrorKind::FftLayout`].
    pub fft_layout: u64,
    /// See [`DecodeErrorKind::Timestamp`].
    pub timestamp: u64,
    /// See [`DecodeErrorKind::Protobuf`].
    pub protobuf: u64,
    /// See [`DecodeErrorKind::Other`].
    pub other: u64,
}

impl DecodeErrorCounts {
    /// The sum over all kinds.
    pub fn total(&self) -> u64 {
        self.signature
            + self.version
            + self.oversized
            + self.truncated
            + self.fft_layout
            + self.timestamp
            + self.protobuf
            + self.other
    }
}

/// The live counters. Shared as `Arc<Metrics>`; every update is one relaxed atomic add.
#[derive(Debug, Default)]
pub struct Metrics {
    frames: AtomicU64,
    bytes: AtomicU64,
    keep_alives: AtomicU64,
    configurations: AtomicU64,
    configurations_repeated: AtomicU64,
    configurations_refused: AtomicU64,
    fft_frames: AtomicU64,
    other_messages: AtomicU64,
    fft_before_configuration: AtomicU64,
    encoder_out_of_range: AtomicU64,
    decode_errors: [AtomicU64; 8],
    azimuths_sent: AtomicU64,
    azimuths_delivered: AtomicU64,
    azimuth_drops: AtomicU64,
    rotations_sent: AtomicU64,
    rotations_delivered: AtomicU64,
    rotation_drops: AtomicU64,
    skipped_azimuths: AtomicU64,
    sweep_gaps: AtomicU64,
    sweep_missing: AtomicU64,
    connect_attempts: AtomicU64,
    connections: AtomicU64,
    reconnects: AtomicU64,
    watchdog_timeouts: AtomicU64,
    record_bytes: AtomicU64,
    budget_drops: AtomicU64,
    record_budget_drops: AtomicU64,
    latency: LatencyHistogram,
    budget: Arc<ByteBudget>,
}

/// A point-in-time copy of every counter.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MetricsSnapshot {
    /// Whole frames decoded (any message type).
    pub frames: u64,
    /// Bytes read from the socket.
    pub bytes: u64,
    /// Keep-alive messages (id 1).
    pub keep_alives: u64,
    /// Configuration messages (id 10).
    pub configurations: u64,
    /// Configuration messages identical to the one in force (re-sent by the radar).
    pub configurations_repeated: u64,
    /// Configuration messages refused as unusable (each ended its connection).
    pub configurations_refused: u64,
    /// FFT data messages (id 30 or 31).
    pub fft_frames: u64,
    /// Messages of any other type (including unknown ids), skipped.
    pub other_messages: u64,
    /// FFT frames that arrived before any configuration and could not be interpreted.
    pub fft_before_configuration: u64,
    /// FFT frames whose azimuth was not below the encoder size (dropped).
    pub encoder_out_of_range: u64,
    /// Frames or bytes the decoder rejected, by kind.
    pub decode_errors: DecodeErrorCounts,
    /// Azimuths offered to the per-azimuth channel.
    pub azimuths_sent: u64,
    /// Azimuths that entered the per-azimuth channel.
    pub azimuths_delivered: u64,
    /// Azimuths dropped (channel full under the drop policy, or consumer gone).
    pub azimuth_drops: u64,
    /// Rotations offered to the rotation channel.
    pub rotations_sent: u64,
    /// Rotations that entered the rotation channel.
    pub rotations_delivered: u64,
    /// Rotations dropped.
    pub rotation_drops: u64,
    /// Azimuth slots missing inside rotations (from encoder values).
    pub skipped_azimuths: u64,
    /// Sweep-counter discontinuities.
    pub sweep_gaps: u64,
    /// Azimuth messages missing according to the sweep counter.
    pub sweep_missing: u64,
    /// TCP connection attempts.
    pub connect_attempts: u64,
    /// Connections established.
    pub connections: u64,
    /// Connections re-established after a failure (connections after the first).
    pub reconnects: u64,
    /// Links declared dead by the keep-alive watchdog.
    pub watchdog_timeouts: u64,
    /// Bytes written to the recording.
    pub record_bytes: u64,
    /// Azimuths dropped because the byte budget was full (before any channel: not in
    /// `azimuths_sent`).
    pub budget_drops: u64,
    /// Recording chunks dropped because the byte budget was full.
    pub record_budget_drops: u64,
    /// Bytes of radar data held now (see [`crate::budget`]).
    pub held_bytes: usize,
    /// The most bytes of radar data ever held at once.
    pub held_bytes_peak: usize,
    /// The byte budget (`max_held_bytes`).
    pub max_held_bytes: usize,
    /// Latency from the socket read that completed a frame to its channel send.
    pub latency: LatencySummary,
}

macro_rules! bump {
    ($($name:ident => $field:ident),* $(,)?) => {
        $(
            #[doc = concat!("Adds `n` to `", stringify!($field), "`.")]
            pub fn $name(&self, n: u64) {
                self.$field.fetch_add(n, Ordering::Relaxed);
            }
        )*
    };
}

impl Metrics {
    /// All counters at zero, with no byte limit.
    pub fn new() -> Self {
        Self::default()
    }

    /// All counters at zero, with a byte budget of `max_held_bytes`.
    pub fn with_budget(max_held_bytes: usize) -> Self {
        Self {
            budget: ByteBudget::new(max_held_bytes),
            ..Self::default()
        }
    }

    /// The byte budget every azimuth is charged to.
    pub fn budget(&self) -> &Arc<ByteBudget> {
        &self.budget
    }

    bump! {
        add_frames => frames,
        add_bytes => bytes,
        add_keep_alives => keep_alives,
        add_configurations => configurations,
        add_configurations_repeated => configurations_repeated,
        add_configurations_refused => configurations_refused,
        add_fft_frames => fft_frames,
        add_other_messages => other_messages,
        add_fft_before_configuration => fft_before_configuration,
        add_encoder_out_of_range => encoder_out_of_range,
        add_azimuths_sent => azimuths_sent,
        add_azimuths_delivered => azimuths_delivered,
        add_azimuth_drops => azimuth_drops,
        add_rotations_sent => rotations_sent,
        add_rotations_delivered => rotations_delivered,
        add_rotation_drops => rotation_drops,
        add_skipped_azimuths => skipped_azimuths,
        add_sweep_gaps => sweep_gaps,
        add_sweep_missing => sweep_missing,
        add_connect_attempts => connect_attempts,
        add_connections => connections,
        add_reconnects => reconnects,
        add_watchdog_timeouts => watchdog_timeouts,
        add_record_bytes => record_bytes,
        add_budget_drops => budget_drops,
        add_record_budget_drops => record_budget_drops,
    }

    /// Counts one decode error of `kind`.
    pub fn add_decode_error(&self, kind: DecodeErrorKind) {
        if let Some(c) = self.decode_errors.get(kind.index()) {
            c.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Records one read-to-send latency.
    pub fn record_latency_ns(&self, ns: u64) {
        self.latency.record(ns);
    }

    /// The latency histogram itself.
    pub fn latency(&self) -> &LatencyHistogram {
        &self.latency
    }

    /// Copies every counter. Counters are read one by one, so a snapshot taken while the
    /// driver runs may be off by the few messages processed during the copy.
    pub fn snapshot(&self) -> MetricsSnapshot {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let d = |k: DecodeErrorKind| self.decode_errors.get(k.index()).map_or(0, get);
        MetricsSnapshot {
            frames: get(&self.frames),
            bytes: get(&self.bytes),
            keep_alives: get(&self.keep_alives),
            configurations: get(&self.configurations),
            configurations_repeated: get(&self.configurations_repeated),
            configurations_refused: get(&self.configurations_refused),
            fft_frames: get(&self.fft_frames),
            other_messages: get(&self.other_messages),
            fft_before_configuration: get(&self.fft_before_configuration),
            encoder_out_of_range: get(&self.encoder_out_of_range),
            decode_errors: DecodeErrorCounts {
                signature: d(DecodeErrorKind::Signature),
                version: d(DecodeErrorKind::Version),
                oversized: d(DecodeErrorKind::Oversized),
                truncated: d(DecodeErrorKind::Truncated),
                fft_layout: d(DecodeErrorKind::FftLayout),
                timestamp: d(DecodeErrorKind::Timestamp),
                protobuf: d(DecodeErrorKind::Protobuf),
                other: d(DecodeErrorKind::Other),
            },
            azimuths_sent: get(&self.azimuths_sent),
            azimuths_delivered: get(&self.azimuths_delivered),
            azimuth_drops: get(&self.azimuth_drops),
            rotations_sent: get(&self.rotations_sent),
            rotations_delivered: get(&self.rotations_delivered),
            rotation_drops: get(&self.rotation_drops),
            skipped_azimuths: get(&self.skipped_azimuths),
            sweep_gaps: get(&self.sweep_gaps),
            sweep_missing: get(&self.sweep_missing),
            connect_attempts: get(&self.connect_attempts),
            connections: get(&self.connections),
            reconnects: get(&self.reconnects),
            watchdog_timeouts: get(&self.watchdog_timeouts),
            record_bytes: get(&self.record_bytes),
            budget_drops: get(&self.budget_drops),
            record_budget_drops: get(&self.record_budget_drops),
            held_bytes: self.budget.held(),
            held_bytes_peak: self.budget.peak(),
            max_held_bytes: self.budget.limit(),
            latency: self.latency.summary(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_decode_error_kind_is_counted_in_its_own_field() {
        let m = Metrics::new();
        for (i, kind) in DecodeErrorKind::ALL.iter().enumerate() {
            for _ in 0..=i {
                m.add_decode_error(*kind);
            }
        }
        let d = m.snapshot().decode_errors;
        assert_eq!(
            [
                d.signature,
                d.version,
                d.oversized,
                d.truncated,
                d.fft_layout,
                d.timestamp,
                d.protobuf,
                d.other
            ],
            [1, 2, 3, 4, 5, 6, 7, 8]
        );
        assert_eq!(d.total(), 36);
    }
}
