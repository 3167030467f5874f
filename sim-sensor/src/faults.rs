//! Fault injection: what the server does wrong on purpose, one connection at a time.
//!
//! The settings are config's [`FaultSettings`] (re-exported), so a fault can be set in
//! `[sim.faults]` or built in code. Semantics, as `config::faults` documents them: message
//! counts are per connection and count **every** message sent (the configuration, keep-alives
//! and FFT data), 1-based; a skipped azimuth is not sent and so not counted.
//!
//! | fault | on the wire |
//! |---|---|
//! | `drop_after_messages = N` | the socket is closed right after message N |
//! | `cut_frame_at_message = N` | only the first half of message N's bytes is sent, then the socket is closed |
//! | `corrupt_every_n = N` | in every N-th message one signature byte is inverted, so the frame fails its signature check and a decoder must resynchronise |
//! | `skip_azimuth_every_n = N` | every N-th azimuth is not sent (the sweep counter and encoder still advance, so the gap is visible) |
//! | `stall = (N, d)` | after message N nothing at all (no keep-alive either) is sent for `d`, once per connection |
//! | `no_keepalive` | keep-alives are never sent |
//! | `oversized_at_message = N` | message N's header announces a payload of [`OVERSIZED_PAYLOAD`] bytes (the real payload follows), so a decoder must reject the length before reserving memory and resynchronise |
//! | `noise_burst = (a, d)` | from `a` into the stream for `d` (on the azimuths' own timestamps, from the connection's first azimuth), every bin of every azimuth is random: a swamped receiver. Frames stay valid |
//!
//! [`FaultScope`] limits the faults to the first connections, so a client that reconnects
//! after a dropped connection then sees a clean stream.

use std::num::NonZeroU64;
use std::time::Duration;

use protocol::{message_id, HEADER_LEN, SIGNATURE};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A stall: after `after_messages` messages, send nothing for `duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Stall {
    /// Messages sent before the stall.
    pub after_messages: NonZeroU64,
    /// How long nothing is sent.
    pub duration: Duration,
}

/// A noise burst: `after` into the stream, for `duration`, every bin random.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NoiseBurst {
    /// Stream time before the burst, from the connection's first azimuth.
    pub after: Duration,
    /// How long it lasts, in stream time.
    pub duration: Duration,
}

/// The faults to inject (the table above); `None` means the fault is off.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct FaultSettings {
    /// Close after this many messages.
    pub drop_after_messages: Option<NonZeroU64>,
    /// Cut this message (1-based) in half, then close.
    pub cut_frame_at_message: Option<NonZeroU64>,
    /// Corrupt every N-th message.
    pub corrupt_every_n: Option<NonZeroU64>,
    /// Skip every N-th azimuth.
    pub skip_azimuth_every_n: Option<NonZeroU64>,
    /// Stall.
    pub stall: Option<Stall>,
    /// Send no keep-alives.
    pub no_keepalive: bool,
    /// Announce an oversized payload in this message (1-based).
    pub oversized_at_message: Option<NonZeroU64>,
    /// Every bin random for a while.
    pub noise_burst: Option<NoiseBurst>,
}

impl FaultSettings {
    /// Whether any fault is on.
    pub fn any(&self) -> bool {
        *self != FaultSettings::default()
    }
}

#[cfg(feature = "config")]
impl From<&config::FaultSettings> for FaultSettings {
    /// The `[sim.faults]` section, as validated by the configuration crate.
    fn from(c: &config::FaultSettings) -> Self {
        Self {
            drop_after_messages: c.drop_after_messages,
            cut_frame_at_message: c.cut_frame_at_message,
            corrupt_every_n: c.corrupt_every_n,
            skip_azimuth_every_n: c.skip_azimuth_every_n,
            stall: c.stall.map(|s| Stall {
                after_messages: s.after_messages,
                duration: s.duration,
            }),
            no_keepalive: c.no_keepalive,
            oversized_at_message: c.oversized_at_message,
            noise_burst: c.noise_burst.map(|b| NoiseBurst {
                after: b.after,
                duration: b.duration,
            }),
        }
    }
}

/// The payload length announced by the oversized-payload fault (far above the protocol's
/// 1,000,000-byte limit).
pub const OVERSIZED_PAYLOAD: u32 = 0x7FFF_FFF0;

/// Which connections the faults apply to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FaultScope {
    /// Every connection.
    #[default]
    EveryConnection,
    /// Only the first `n` connections accepted (counting from 1).
    FirstConnections(u64),
}

impl FaultScope {
    /// Whether connection number `connection` (1-based) gets the faults.
    pub fn applies_to(self, connection: u64) -> bool {
        match self {
            FaultScope::EveryConnection => true,
            FaultScope::FirstConnections(n) => connection <= n,
        }
    }
}

/// What to do with a frame that is about to be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Send {
    /// Write all of it.
    Whole,
    /// Write only this many leading bytes, then close the connection.
    CutThenClose(usize),
}

/// What to do after a frame has been written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum After {
    /// Carry on.
    Continue,
    /// Send nothing for this long, then carry on.
    Stall(Duration),
    /// Close the connection.
    Close,
}

/// One connection's fault state.
#[derive(Debug, Clone)]
pub struct FaultInjector {
    settings: FaultSettings,
    active: bool,
    messages_sent: u64,
    azimuths_seen: u64,
    stalled: bool,
    /// The stream time of the connection's first azimuth, seconds.
    first_azimuth_s: Option<f64>,
    /// Azimuths whose bins the noise burst replaced.
    noised: u64,
    rng: ChaCha8Rng,
}

impl FaultInjector {
    /// Faults for one connection; `active = false` gives a clean connection.
    pub fn new(settings: &FaultSettings, active: bool) -> Self {
        Self {
            settings: settings.clone(),
            active,
            messages_sent: 0,
            azimuths_seen: 0,
            stalled: false,
            first_azimuth_s: None,
            noised: 0,
            rng: ChaCha8Rng::seed_from_u64(0x5eed),
        }
    }

    /// A connection with no faults.
    pub fn clean() -> Self {
        Self::new(&FaultSettings::default(), false)
    }

    /// Messages counted so far on this connection.
    pub fn messages_sent(&self) -> u64 {
        self.messages_sent
    }

    /// Whether keep-alives are sent.
    pub fn keepalives_enabled(&self) -> bool {
        !(self.active && self.settings.no_keepalive)
    }

    /// Called once per azimuth before it is rendered: `true` means leave it out.
    pub fn skip_azimuth(&mut self) -> bool {
        self.azimuths_seen += 1;
        match self.settings.skip_azimuth_every_n {
            Some(n) if self.active => self.azimuths_seen.is_multiple_of(n.get()),
            _ => false,
        }
    }

    /// Azimuths whose bins the noise burst replaced on this connection.
    pub fn noised_azimuths(&self) -> u64 {
        self.noised
    }

    /// Called with each whole FFT frame before the client's shaping (a contour cuts the
    /// noise as it would the signal): during the noise burst its bins are replaced by
    /// random bytes. Other frames, and every frame outside the burst, are left as they are.
    pub fn noise_burst(&mut self, frame: &mut [u8]) {
        let Some(burst) = self.settings.noise_burst.filter(|_| self.active) else {
            return;
        };
        let fft = matches!(
            frame.get(17),
            Some(&message_id::FFT_DATA | &message_id::HIGH_PRECISION_FFT_DATA)
        );
        let field = |at: usize| -> Option<[u8; 4]> { frame.get(at..at + 4)?.try_into().ok() };
        let (Some(seconds), Some(nanos), Some(offset)) = (
            field(HEADER_LEN + 6),
            field(HEADER_LEN + 10),
            frame.get(HEADER_LEN..HEADER_LEN + 2),
        ) else {
            return;
        };
        if !fft {
            return;
        }
        let offset = usize::from(u16::from_be_bytes([offset[0], offset[1]]));
        let t =
            f64::from(u32::from_le_bytes(seconds)) + f64::from(u32::from_le_bytes(nanos)) * 1e-9;
        let into = t - *self.first_azimuth_s.get_or_insert(t);
        let start = burst.after.as_secs_f64();
        if into < start || into >= start + burst.duration.as_secs_f64() {
            return;
        }
        if let Some(bins) = frame.get_mut(HEADER_LEN + offset..) {
            if self.noised == 0 {
                tracing::info!(
                    after_s = start,
                    lasts_s = burst.duration.as_secs_f64(),
                    "fault: noise burst, every bin random"
                );
            }
            self.rng.fill_bytes(bins);
            self.noised += 1;
        }
    }

    /// Called with each whole encoded frame just before it is written; may alter its bytes
    /// (corruption, oversized length) and says how much of it to write.
    pub fn before_send(&mut self, frame: &mut [u8]) -> Send {
        self.messages_sent += 1;
        if !self.active {
            return Send::Whole;
        }
        let m = self.messages_sent;
        if let Some(n) = self.settings.corrupt_every_n {
            if m.is_multiple_of(n.get()) {
                // Deterministic choice of the signature byte, varying between messages.
                let position = usize::try_from(m.wrapping_mul(7) % 16).unwrap_or(0);
                if let (Some(byte), Some(good)) = (frame.get_mut(position), SIGNATURE.get(position))
                {
                    *byte = !*good;
                }
            }
        }
        if self.settings.oversized_at_message.map(|n| n.get()) == Some(m)
            && frame.len() >= HEADER_LEN
        {
            if let Some(size) = frame.get_mut(18..22) {
                size.copy_from_slice(&OVERSIZED_PAYLOAD.to_be_bytes());
            }
        }
        if self.settings.cut_frame_at_message.map(|n| n.get()) == Some(m) {
            return Send::CutThenClose(frame.len() / 2);
        }
        Send::Whole
    }

    /// Called after each frame was written.
    pub fn after_send(&mut self) -> After {
        if !self.active {
            return After::Continue;
        }
        let m = self.messages_sent;
        if self.settings.drop_after_messages.map(|n| n.get()) == Some(m) {
            return After::Close;
        }
        if let Some(stall) = self.settings.stall {
            if !self.stalled && stall.after_messages.get() == m {
                self.stalled = true;
                return After::Stall(stall.duration);
            }
        }
        After::Continue
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::num::NonZeroU64;

    fn nz(n: u64) -> Option<NonZeroU64> {
        NonZeroU64::new(n)
    }

    fn frame() -> Vec<u8> {
        let mut f = SIGNATURE.to_vec();
        f.extend_from_slice(&[1, 30, 0, 0, 0, 4, 9, 9, 9, 9]);
        f
    }

    #[test]
    fn a_clean_injector_changes_nothing() {
        let mut inj = FaultInjector::clean();
        for _ in 0..100 {
            let mut f = frame();
            assert_eq!(inj.before_send(&mut f), Send::Whole);
            assert_eq!(f, frame());
            assert_eq!(inj.after_send(), After::Continue);
            assert!(!inj.skip_azimuth());
        }
        assert!(inj.keepalives_enabled());
    }

    #[test]
    fn corruption_breaks_exactly_one_signature_byte_of_every_nth_message() {
        let settings = FaultSettings {
            corrupt_every_n: nz(3),
            ..FaultSettings::default()
        };
        let mut inj = FaultInjector::new(&settings, true);
        for m in 1..=9u64 {
            let mut f = frame();
            inj.before_send(&mut f);
            let changed = f.iter().zip(frame()).filter(|(a, b)| **a != *b).count();
            assert_eq!(changed, usize::from(m % 3 == 0), "message {m}");
        }
    }

    #[test]
    fn the_oversized_fault_rewrites_the_length_field_only() {
        let settings = FaultSettings {
            oversized_at_message: nz(2),
            ..FaultSettings::default()
        };
        let mut inj = FaultInjector::new(&settings, true);
        let mut first = frame();
        inj.before_send(&mut first);
        assert_eq!(first, frame());
        let mut second = frame();
        inj.before_send(&mut second);
        assert_eq!(&second[18..22], &OVERSIZED_PAYLOAD.to_be_bytes());
        assert_eq!(&second[..18], &frame()[..18]);
        assert_eq!(&second[22..], &frame()[22..]);
    }

    #[test]
    fn drop_cut_and_stall_fire_at_their_message_and_the_stall_only_once() {
        let settings = FaultSettings {
            drop_after_messages: nz(5),
            cut_frame_at_message: nz(7),
            stall: Some(Stall {
                after_messages: NonZeroU64::MIN.saturating_add(1),
                duration: Duration::from_millis(30),
            }),
            ..FaultSettings::default()
        };
        let mut inj = FaultInjector::new(&settings, true);
        let mut actions = Vec::new();
        for _ in 0..7 {
            let mut f = frame();
            let send = inj.before_send(&mut f);
            actions.push((send, inj.after_send()));
        }
        assert_eq!(actions[1].1, After::Stall(Duration::from_millis(30)));
        assert_eq!(actions[4].1, After::Close);
        assert_eq!(actions[6].0, Send::CutThenClose(frame().len() / 2));
        assert_eq!(
            actions
                .iter()
                .filter(|a| matches!(a.1, After::Stall(_)))
                .count(),
            1
        );
    }

    #[test]
    fn the_noise_burst_replaces_the_bins_of_the_azimuths_inside_it_only() {
        let settings = FaultSettings {
            noise_burst: Some(NoiseBurst {
                after: Duration::from_millis(1000),
                duration: Duration::from_millis(500),
            }),
            ..FaultSettings::default()
        };
        let mut inj = FaultInjector::new(&settings, true);
        let bins = [3u8; 200];
        let t0_ns = 1_700_000_000_900_000_000u64;
        let mut noised = Vec::new();
        // Azimuths every 100 ms from t0.
        for k in 0..30u64 {
            let ns = t0_ns + k * 100_000_000;
            let stamp =
                protocol::Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
                    .expect("stamp");
            let mut f = bytes::BytesMut::new();
            protocol::encode_fft_frame(
                &mut f,
                protocol::BinWidth::Eight,
                k as u16,
                0,
                stamp,
                &bins,
            )
            .expect("frame");
            let header = f[..HEADER_LEN + 14].to_vec();
            inj.noise_burst(&mut f);
            assert_eq!(
                f[..HEADER_LEN + 14],
                header[..],
                "azimuth {k}: the header is kept"
            );
            if f[HEADER_LEN + 14..] != bins[..] {
                noised.push(k);
            }
        }
        // 1.0 s to 1.5 s after the first azimuth: azimuths 10 to 14.
        assert_eq!(noised, vec![10, 11, 12, 13, 14]);
        assert_eq!(inj.noised_azimuths(), 5);
        // A clean connection, and a frame that is not FFT data, are left alone.
        let mut clean = FaultInjector::new(&settings, false);
        let mut keepalive = frame();
        clean.noise_burst(&mut keepalive);
        inj.noise_burst(&mut keepalive);
        assert_eq!(keepalive, frame());
    }

    #[test]
    fn skipping_counts_azimuths_and_scope_limits_connections() {
        let settings = FaultSettings {
            skip_azimuth_every_n: nz(4),
            no_keepalive: true,
            ..FaultSettings::default()
        };
        let mut inj = FaultInjector::new(&settings, true);
        let skipped: Vec<bool> = (0..8).map(|_| inj.skip_azimuth()).collect();
        assert_eq!(
            skipped,
            vec![false, false, false, true, false, false, false, true]
        );
        assert!(!inj.keepalives_enabled());
        assert!(FaultScope::FirstConnections(1).applies_to(1));
        assert!(!FaultScope::FirstConnections(1).applies_to(2));
        assert!(FaultScope::EveryConnection.applies_to(99));
    }
}
