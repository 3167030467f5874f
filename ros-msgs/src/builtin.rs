//! `builtin_interfaces`: Time and Duration.

use serde::{Deserialize, Serialize};

use crate::schema::{MsgDef, RosMessage};

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0..1e9.
    pub nanosec: u32,
}

/// Definition of [`Time`].
pub static TIME: MsgDef = MsgDef {
    name: "builtin_interfaces/Time",
    text: "int32 sec\nuint32 nanosec\n",
    uses: &[],
};

impl RosMessage for Time {
    const DEF: &'static MsgDef = &TIME;
}

impl Time {
    /// From nanoseconds since the epoch (seconds saturate at `i32::MAX`, 2038).
    pub fn from_nanos(ns: u64) -> Self {
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the epoch (negative seconds give 0).
    pub fn as_nanos(&self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }

    /// From Unix seconds, to the nearest nanosecond the f64 resolves (not finite or
    /// negative: 0).
    pub fn from_secs_f64(t: f64) -> Self {
        Self::from_nanos(secs_to_nanos(t))
    }

    /// Unix seconds, computed as `std::time::Duration::as_secs_f64` does.
    pub fn as_secs_f64(&self) -> f64 {
        std::time::Duration::from_nanos(self.as_nanos()).as_secs_f64()
    }
}

/// Nanoseconds for Unix seconds `t`, chosen so that converting them back with
/// `Duration::as_secs_f64` gives `t` exactly whenever some nanosecond count does (a time
/// that came from the wire's seconds + nanoseconds always round-trips). Not finite or
/// negative: 0.
pub fn secs_to_nanos(t: f64) -> u64 {
    if !(t.is_finite() && t >= 0.0) {
        return 0;
    }
    let secs = t.floor();
    if secs >= u64::MAX as f64 / 1e9 {
        return u64::MAX;
    }
    let whole = secs as u64;
    let frac_ns = ((t - secs) * 1e9).round() as i64;
    let back = |n: i64| -> Option<u64> {
        let total = i128::from(whole) * 1_000_000_000 + i128::from(n);
        u64::try_from(total).ok()
    };
    // The f64 near 1.7e9 s resolves about 240 ns: search that neighbourhood for the count
    // that reproduces `t` bit for bit.
    for d in 0..=512i64 {
        for n in [frac_ns + d, frac_ns - d] {
            if let Some(ns) = back(n) {
                if std::time::Duration::from_nanos(ns).as_secs_f64() == t {
                    return ns;
                }
            }
        }
    }
    back(frac_ns).unwrap_or(0)
}

/// `builtin_interfaces/Duration`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0..1e9.
    pub nanosec: u32,
}

/// Definition of [`Duration`].
pub static DURATION: MsgDef = MsgDef {
    name: "builtin_interfaces/Duration",
    text: "int32 sec\nuint32 nanosec\n",
    uses: &[],
};

impl RosMessage for Duration {
    const DEF: &'static MsgDef = &DURATION;
}
