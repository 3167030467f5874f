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
//!
//! [`FaultScope`] limits the faults to the first connections, so a client that reconnects
//! after a dropped connection then sees a clean stream.

use std::num::NonZeroU64;
use std::time::Duration;

use protocol::{HEADER_LEN, SIGNATURE};

/// A stall: after `after_messages` messages, send nothing for `duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Stall {
    /// Messages sent before the stall.
    pub after_messages: NonZeroU64,
    /// How long nothing is sent.
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
