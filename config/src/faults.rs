//! `[sim.faults]`: faults the simulator injects so tests can exercise the driver's error
//! paths. Message counts are per client connection and count every message sent, keep-alives
//! included; "at message N" is 1-based.

use std::num::NonZeroU64;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{self, ValueError};

/// `[sim.faults]` as written in the file. Every fault is off unless set.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawFaults {
    /// Close the connection after this many messages (>= 1).
    pub drop_after_messages: Option<i64>,
    /// Send only the first half of message N (>= 1), then close.
    pub cut_frame_at_message: Option<i64>,
    /// Corrupt bytes in every N-th message (>= 1).
    pub corrupt_every_n: Option<i64>,
    /// Leave out every N-th azimuth (>= 1).
    pub skip_azimuth_every_n: Option<i64>,
    /// Stall after this many messages (>= 1); needs `stall_ms`.
    pub stall_after_messages: Option<i64>,
    /// How long to stall, ms > 0; needs `stall_after_messages`.
    pub stall_ms: Option<i64>,
    /// Send no keep-alives. Default false.
    pub no_keepalive: bool,
    /// Announce an oversized payload length in message N (>= 1).
    pub oversized_at_message: Option<i64>,
    /// Start a noise burst this long into the stream (ms > 0, on the azimuths' own
    /// timestamps from the connection's first azimuth); needs `noise_burst_ms`.
    pub noise_burst_after_ms: Option<i64>,
    /// How long the noise burst lasts, ms > 0: every bin of every azimuth random; needs
    /// `noise_burst_after_ms`.
    pub noise_burst_ms: Option<i64>,
}

/// A stall: after `after_messages` messages, send nothing for `duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Stall {
    /// Messages sent before the stall.
    pub after_messages: NonZeroU64,
    /// How long nothing is sent.
    pub duration: Duration,
}

/// A noise burst: from `after` into the stream, for `duration`, every bin of every azimuth
/// is random (a swamped receiver), once per connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NoiseBurst {
    /// Stream time before the burst, from the connection's first azimuth.
    pub after: Duration,
    /// How long it lasts, in stream time.
    pub duration: Duration,
}

/// `[sim.faults]`, validated. `None` means the fault is off.
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
    /// A noise burst.
    pub noise_burst: Option<NoiseBurst>,
}

impl FaultSettings {
    /// Whether any fault is on.
    pub fn any(&self) -> bool {
        *self != FaultSettings::default()
    }
}

fn at_least_one(value: i64) -> Result<NonZeroU64, ValueError> {
    u64::try_from(value)
        .ok()
        .and_then(NonZeroU64::new)
        .ok_or_else(|| ValueError::OutOfRange {
            range: format!("[1, {}]", i64::MAX),
            got: value.to_string(),
        })
}

impl RawFaults {
    /// Validates this table alone; errors name `sim.faults.<field>`.
    pub fn validate(&self) -> Result<FaultSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> FaultSettings {
        let stall_after = c.check_opt(
            "sim.faults.stall_after_messages",
            self.stall_after_messages,
            at_least_one,
        );
        let stall_for = c.check_opt(
            "sim.faults.stall_ms",
            self.stall_ms,
            values::duration_from_ms,
        );
        let stall = match (self.stall_after_messages, self.stall_ms) {
            (Some(_), None) => {
                c.fail(
                    "sim.faults.stall_ms",
                    ValueError::Rule("is required with sim.faults.stall_after_messages".into()),
                );
                None
            }
            (None, Some(_)) => {
                c.fail(
                    "sim.faults.stall_after_messages",
                    ValueError::Rule("is required with sim.faults.stall_ms".into()),
                );
                None
            }
            _ => match (stall_after, stall_for) {
                (Some(after_messages), Some(duration)) => Some(Stall {
                    after_messages,
                    duration,
                }),
                _ => None,
            },
        };
        let noise_burst = self.check_noise_burst(c);
        FaultSettings {
            noise_burst,
            drop_after_messages: c.check_opt(
                "sim.faults.drop_after_messages",
                self.drop_after_messages,
                at_least_one,
            ),
            cut_frame_at_message: c.check_opt(
                "sim.faults.cut_frame_at_message",
                self.cut_frame_at_message,
                at_least_one,
            ),
            corrupt_every_n: c.check_opt(
                "sim.faults.corrupt_every_n",
                self.corrupt_every_n,
                at_least_one,
            ),
            skip_azimuth_every_n: c.check_opt(
                "sim.faults.skip_azimuth_every_n",
                self.skip_azimuth_every_n,
                at_least_one,
            ),
            stall,
            no_keepalive: self.no_keepalive,
            oversized_at_message: c.check_opt(
                "sim.faults.oversized_at_message",
                self.oversized_at_message,
                at_least_one,
            ),
        }
    }
}

impl RawFaults {
    fn check_noise_burst(&self, c: &mut Checker) -> Option<NoiseBurst> {
        const AFTER: &str = "sim.faults.noise_burst_after_ms";
        const LASTS: &str = "sim.faults.noise_burst_ms";
        let after = c.check_opt(AFTER, self.noise_burst_after_ms, values::duration_from_ms);
        let duration = c.check_opt(LASTS, self.noise_burst_ms, values::duration_from_ms);
        match (self.noise_burst_after_ms, self.noise_burst_ms) {
            (Some(_), None) => {
                c.fail(LASTS, ValueError::Rule(format!("is required with {AFTER}")));
                None
            }
            (None, Some(_)) => {
                c.fail(AFTER, ValueError::Rule(format!("is required with {LASTS}")));
                None
            }
            _ => Some(NoiseBurst {
                after: after?,
                duration: duration?,
            }),
        }
    }
}

impl From<&FaultSettings> for RawFaults {
    /// The settings written back out.
    fn from(s: &FaultSettings) -> Self {
        let n = |v: Option<NonZeroU64>| v.map(|v| values::as_i64(v.get()));
        Self {
            drop_after_messages: n(s.drop_after_messages),
            cut_frame_at_message: n(s.cut_frame_at_message),
            corrupt_every_n: n(s.corrupt_every_n),
            skip_azimuth_every_n: n(s.skip_azimuth_every_n),
            stall_after_messages: n(s.stall.map(|st| st.after_messages)),
            stall_ms: s.stall.map(|st| values::whole_ms(st.duration)),
            no_keepalive: s.no_keepalive,
            oversized_at_message: n(s.oversized_at_message),
            noise_burst_after_ms: s.noise_burst.map(|b| values::whole_ms(b.after)),
            noise_burst_ms: s.noise_burst.map(|b| values::whole_ms(b.duration)),
        }
    }
}
