//! The odometry gate: odometry reaches the filter only up to the time of the beam being
//! processed (so the filter never runs ahead of the radar), and a beam reaches the filter
//! only when odometry covers it. Without odometry, or with odometry older than
//! `stale_after_s` behind the beam, the beam is refused and counted: no motion is
//! fabricated. The odometry the filter holds is the filter's ([`slam_filter::Ekf::held_odometry`]);
//! the gate keeps only what is not yet applied.
//!
//! A source that reconnects may send again what it sent last (a bridge replaying its last
//! half second): a record equal to one taken (same time, speed and steer) at most
//! [`ODOMETRY_REPLAY_WINDOW_S`] before the newest is dropped as a duplicate (counted, logged
//! at most once per 5 s of stream) without touching the stream's clock or the odometry held;
//! the gate remembers the records it took over that window (at most [`TAKEN_CAPACITY`], 24
//! bytes each). Any other step back, within the window or beyond it, is a clock that jumped: refused until confirmed, then resynchronised
//! with the pending records dropped (they lie ahead of the new clock). A step forward past
//! the clock's limit (records missing) is confirmed the same way, and the pending records,
//! earlier than the new clock, are kept.

use std::collections::VecDeque;

use slam_filter::{Ekf, OdometrySample, ProcessModel};
use tracing::{info, warn};

use super::clock::{Verdict, WireClock};
use super::counts::RefusalCounts;
use super::odometry::OdometryQueue;
use slam_filter::BeamObservationModel;

/// Why a beam was not given to the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refusal {
    /// No odometry has reached the filter yet.
    NoOdometry,
    /// The held odometry is older than the staleness limit behind the beam.
    Stale {
        /// How old (s).
        age_s: f64,
    },
}

/// Physical limits on what odometry may report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryLimits {
    /// Largest |speed| (m/s).
    pub max_speed_mps: f64,
    /// Largest |steer| (rad).
    pub max_steer_rad: f64,
    /// Largest |change of speed| per second over intervals up to 1 s (m/s^2).
    pub max_accel_mps2: f64,
}

impl Default for OdometryLimits {
    fn default() -> Self {
        Self {
            max_speed_mps: 60.0,
            max_steer_rad: 1.2,
            max_accel_mps2: 20.0,
        }
    }
}

/// Why an odometry record was not taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OdometryRejection {
    /// Its timestamp is far from the stream's clock (and not yet confirmed as a jump).
    WildTime,
    /// Speed, steer or acceleration past the physical limits.
    Implausible,
    /// Equal to a record taken within the replay window: sent again (a source that
    /// reconnected replays what it sent last). Dropped, not an error.
    Duplicate,
}

/// Odometry waiting for the radar, and the refusal rule.
#[derive(Debug)]
pub struct OdometryGate {
    queue: OdometryQueue,
    clock: WireClock,
    limits: OdometryLimits,
    last_accepted: Option<OdometrySample>,
    /// The records taken over the last [`ODOMETRY_REPLAY_WINDOW_S`], oldest first (what a
    /// replay can repeat).
    taken: VecDeque<OdometrySample>,
    stale_after_s: f64,
    last_warning_s: f64,
    rejected: u64,
    duplicates: u64,
    last_duplicate_log_s: f64,
    clock_jumps: u64,
}

/// Odometry timestamps may step forward by at most this between records (s); a wilder one
/// must be confirmed by this many records before the clock follows it.
const ODOMETRY_MAX_STEP_S: f64 = 2.0;
const ODOMETRY_JUMP_CONFIRM: u32 = 8;
/// A record equal to one taken up to this long (s) before the newest is a re-sent one (a
/// reconnecting source replays what it sent last), dropped as a duplicate; a new record
/// stamped back in time, or a step back further than this, is the sender's clock jumping.
pub const ODOMETRY_REPLAY_WINDOW_S: f64 = 5.0;
/// Records the gate remembers for recognising replays, at most (100 Hz over the replay
/// window, twice over): 96 kB.
pub const TAKEN_CAPACITY: usize = 1000;
/// The acceleration limit is checked over intervals up to this (s): after a longer silence
/// any speed is believable.
const ACCEL_WINDOW_S: f64 = 1.0;

/// Logs the 1st, 2nd, 4th, 8th... occurrence of something (bounded, deterministic).
pub fn worth_logging(count: u64) -> bool {
    count.is_power_of_two()
}

/// Warnings about refused beams at most this often (stream seconds).
const WARN_EVERY_S: f64 = 5.0;

impl OdometryGate {
    /// A gate holding at most `capacity` pending samples, refusing beams whose odometry is
    /// older than `stale_after_s`.
    pub fn new(capacity: usize, stale_after_s: f64, limits: OdometryLimits) -> Self {
        Self {
            queue: OdometryQueue::new(capacity),
            clock: WireClock::new(ODOMETRY_MAX_STEP_S, ODOMETRY_JUMP_CONFIRM),
            limits,
            last_accepted: None,
            taken: VecDeque::new(),
            stale_after_s,
            last_warning_s: f64::NEG_INFINITY,
            rejected: 0,
            duplicates: 0,
            last_duplicate_log_s: f64::NEG_INFINITY,
            clock_jumps: 0,
        }
    }

    /// Checks a record against the physical limits and the stream's clock, then queues it;
    /// returns a sample that must be applied now (the queue is full). A refused record is
    /// counted and logged (the 1st, 2nd, 4th... time); a duplicate is counted apart and
    /// logged at most once per 5 s of stream.
    pub fn push(
        &mut self,
        sample: OdometrySample,
    ) -> Result<Option<OdometrySample>, OdometryRejection> {
        if let Err(why) = self.check(&sample) {
            if why == OdometryRejection::Duplicate {
                self.duplicates += 1;
                let newest_s = self.clock.now_s().unwrap_or(sample.timestamp_s);
                if newest_s - self.last_duplicate_log_s > WARN_EVERY_S {
                    self.last_duplicate_log_s = newest_s;
                    info!(
                        time_s = sample.timestamp_s,
                        newest_s,
                        duplicates = self.duplicates,
                        "odometry records sent again (a reconnected source replaying?): dropped as duplicates"
                    );
                }
                return Err(why);
            }
            self.rejected += 1;
            if worth_logging(self.rejected) {
                warn!(
                    time_s = sample.timestamp_s,
                    speed_mps = sample.speed_mps,
                    steer_rad = sample.steer_rad,
                    ?why,
                    refused = self.rejected,
                    "odometry record refused"
                );
            }
            return Err(why);
        }
        self.last_accepted = Some(sample);
        self.remember(sample);
        Ok(self.queue.push(sample))
    }

    fn check(&mut self, s: &OdometrySample) -> Result<(), OdometryRejection> {
        let l = &self.limits;
        let plausible = s.speed_mps.is_finite()
            && s.steer_rad.is_finite()
            && s.speed_mps.abs() <= l.max_speed_mps
            && s.steer_rad.abs() <= l.max_steer_rad;
        if !plausible {
            return Err(OdometryRejection::Implausible);
        }
        if self.is_duplicate(s) {
            return Err(OdometryRejection::Duplicate);
        }
        if let Some(last) = self.last_accepted {
            let dt = s.timestamp_s - last.timestamp_s;
            if dt > 0.0
                && dt <= ACCEL_WINDOW_S
                && (s.speed_mps - last.speed_mps).abs() > l.max_accel_mps2 * dt.max(0.05)
            {
                return Err(OdometryRejection::Implausible);
            }
        }
        match self.clock.observe(s.timestamp_s) {
            Verdict::Accept => Ok(()),
            Verdict::Outlier => Err(OdometryRejection::WildTime),
            Verdict::Jump { from_s, to_s } if to_s < from_s => {
                // Back: the pending records lie ahead of the new clock.
                warn!(
                    from_s,
                    to_s,
                    "odometry clock jumped back: pending records dropped, clock resynchronised"
                );
                self.queue.reset();
                self.last_accepted = None;
                self.taken.clear();
                self.clock_jumps += 1;
                Ok(())
            }
            Verdict::Jump { from_s, to_s } => {
                // Forward (records missing, or the sender's clock set ahead): the pending
                // records were taken on the old clock and come before the new ones in time,
                // so they stay; dropping them refused every beam up to the new clock.
                warn!(
                    from_s,
                    to_s,
                    "odometry clock jumped forward: clock resynchronised, pending records kept"
                );
                self.last_accepted = None;
                self.clock_jumps += 1;
                Ok(())
            }
        }
    }

    /// A record taken before (equal in time, speed and steer), stamped at most the replay
    /// window before the newest record taken.
    fn is_duplicate(&self, s: &OdometrySample) -> bool {
        let Some(newest_s) = self.clock.now_s() else {
            return false;
        };
        let back_s = newest_s - s.timestamp_s;
        (0.0..=ODOMETRY_REPLAY_WINDOW_S).contains(&back_s) && self.taken.contains(s)
    }

    /// Keeps `sample` among the records a replay can repeat, forgetting those older than
    /// the window (or past the capacity).
    fn remember(&mut self, sample: OdometrySample) {
        self.taken.push_back(sample);
        let newest_s = self.clock.now_s().unwrap_or(sample.timestamp_s);
        while self.taken.len() > TAKEN_CAPACITY
            || self
                .taken
                .front()
                .is_some_and(|t| newest_s - t.timestamp_s > ODOMETRY_REPLAY_WINDOW_S)
        {
            self.taken.pop_front();
        }
    }

    /// Records dropped as sent again (at or before the newest record taken, within the
    /// replay window).
    pub fn duplicates(&self) -> u64 {
        self.duplicates
    }

    /// Jumps of the odometry's clock resynchronised to (pending records dropped on a jump
    /// back, kept on a jump forward).
    pub fn clock_jumps(&self) -> u64 {
        self.clock_jumps
    }

    /// Records refused (wild time or past the physical limits).
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// Newest sample time received (not necessarily applied).
    pub fn latest_s(&self) -> Option<f64> {
        self.queue.latest_s()
    }

    /// Samples dropped for being out of order or non-finite.
    pub fn out_of_order(&self) -> u64 {
        self.queue.out_of_order()
    }

    /// The next pending sample at or before `time_s`, to be applied before a beam then.
    pub fn next_until(&mut self, time_s: f64) -> Option<OdometrySample> {
        self.queue.pop_until(time_s)
    }

    /// Whether the filter may process a beam at `time_s`, given the odometry it holds;
    /// a refusal is counted in `refused` and warned about (rate-limited).
    pub fn admit<M: ProcessModel, O: BeamObservationModel>(
        &mut self,
        ekf: &Ekf<M, O>,
        time_s: f64,
        refused: &mut RefusalCounts,
    ) -> Result<(), Refusal> {
        let refusal = match ekf.held_odometry() {
            None => Refusal::NoOdometry,
            Some(held) if time_s - held.timestamp_s > self.stale_after_s => Refusal::Stale {
                age_s: time_s - held.timestamp_s,
            },
            Some(_) => return Ok(()),
        };
        match refusal {
            Refusal::NoOdometry => refused.no_odometry += 1,
            Refusal::Stale { .. } => refused.stale_odometry += 1,
        }
        if time_s - self.last_warning_s > WARN_EVERY_S {
            self.last_warning_s = time_s;
            match refusal {
                Refusal::NoOdometry => warn!(
                    time_s,
                    "no odometry yet: refusing to update the map (no dead reckoning is fabricated)"
                ),
                Refusal::Stale { age_s } => warn!(
                    time_s,
                    odometry_age_s = age_s,
                    "odometry is stale: refusing to update the map until it returns"
                ),
            }
        }
        Err(refusal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(t: f64) -> OdometrySample {
        OdometrySample {
            timestamp_s: t,
            speed_mps: 1.0,
            steer_rad: 0.01,
        }
    }

    fn gate() -> OdometryGate {
        OdometryGate::new(1 << 10, 0.5, OdometryLimits::default())
    }

    #[test]
    fn records_sent_again_after_a_reconnect_are_duplicates_and_the_clock_holds() {
        let mut g = gate();
        for k in 0..100 {
            assert!(g.push(rec(100.0 + 0.02 * f64::from(k))).is_ok());
        }
        // The source reconnects and replays its last half second (25 records), the newest
        // one included, then carries on.
        for k in 75..100 {
            assert_eq!(
                g.push(rec(100.0 + 0.02 * f64::from(k))),
                Err(OdometryRejection::Duplicate)
            );
        }
        for k in 100..110 {
            assert!(g.push(rec(100.0 + 0.02 * f64::from(k))).is_ok());
        }
        assert_eq!((g.duplicates(), g.rejected(), g.clock_jumps()), (25, 0, 0));
        assert_eq!(g.latest_s(), Some(100.0 + 0.02 * 109.0));
        // Everything taken is still pending, in order: nothing was dropped.
        let mut pending = 0;
        while g.next_until(f64::INFINITY).is_some() {
            pending += 1;
        }
        assert_eq!(pending, 110);
    }

    #[test]
    fn a_step_back_beyond_the_replay_window_is_still_a_clock_jump_to_confirm() {
        let mut g = gate();
        for k in 0..10 {
            assert!(g.push(rec(5000.0 + 0.05 * f64::from(k))).is_ok());
        }
        // The sender's clock was set back an hour: refused until confirmed, then followed.
        let back = 5000.0 - 3600.0;
        for k in 0..ODOMETRY_JUMP_CONFIRM - 1 {
            assert_eq!(
                g.push(rec(back + 0.05 * f64::from(k))),
                Err(OdometryRejection::WildTime)
            );
        }
        assert!(g
            .push(rec(back + 0.05 * f64::from(ODOMETRY_JUMP_CONFIRM - 1)))
            .is_ok());
        assert_eq!((g.clock_jumps(), g.duplicates()), (1, 0));
        assert_eq!(g.rejected(), u64::from(ODOMETRY_JUMP_CONFIRM - 1));
        // Just beyond the window, too.
        let mut g = gate();
        assert!(g.push(rec(100.0)).is_ok());
        assert_eq!(
            g.push(rec(100.0 - ODOMETRY_REPLAY_WINDOW_S - 0.1)),
            Err(OdometryRejection::WildTime)
        );
    }

    #[test]
    fn a_new_record_stamped_as_the_newest_is_taken_and_the_same_record_again_is_not() {
        let mut g = gate();
        assert!(g.push(rec(100.0)).is_ok());
        assert_eq!(g.push(rec(100.0)), Err(OdometryRejection::Duplicate));
        let changed = OdometrySample {
            speed_mps: 1.5,
            ..rec(100.0)
        };
        assert!(g.push(changed).is_ok());
        assert_eq!(g.duplicates(), 1);
    }

    /// The sender's clock steps back 2 s (inside the replay window) and goes on with new
    /// records: not duplicates (they were never taken) but a jump back, confirmed and
    /// followed, and the records after it are taken again at once.
    #[test]
    fn a_genuine_step_back_inside_the_replay_window_is_a_clock_jump_not_duplicates() {
        let mut g = gate();
        for k in 0..100 {
            assert!(g.push(rec(100.0 + 0.02 * f64::from(k))).is_ok());
        }
        let newer = |k: u32| OdometrySample {
            speed_mps: 1.2,
            ..rec(99.98 - 2.0 + 0.02 * f64::from(k))
        };
        for k in 0..ODOMETRY_JUMP_CONFIRM - 1 {
            assert_eq!(g.push(newer(k)), Err(OdometryRejection::WildTime));
        }
        assert!(g.push(newer(ODOMETRY_JUMP_CONFIRM - 1)).is_ok());
        for k in ODOMETRY_JUMP_CONFIRM..ODOMETRY_JUMP_CONFIRM + 20 {
            assert!(g.push(newer(k)).is_ok(), "record {k} after the jump");
        }
        assert_eq!((g.clock_jumps(), g.duplicates()), (1, 0));
        // A replay of what was taken after the jump is still recognised.
        assert_eq!(
            g.push(newer(ODOMETRY_JUMP_CONFIRM + 19)),
            Err(OdometryRejection::Duplicate)
        );
    }

    /// The records remembered for recognising replays stay within the window and the
    /// capacity, however fast the source sends.
    #[test]
    fn the_replay_memory_is_bounded_by_the_window_and_the_capacity() {
        let mut g = gate();
        for k in 0..20_000 {
            let _ = g.push(rec(100.0 + 0.001 * f64::from(k)));
        }
        assert!(g.taken.len() <= TAKEN_CAPACITY);
        let mut g = gate();
        for k in 0..2_000 {
            assert!(g.push(rec(100.0 + 0.05 * f64::from(k))).is_ok());
        }
        let newest = g.latest_s().expect("records taken");
        assert!(g
            .taken
            .iter()
            .all(|t| newest - t.timestamp_s <= ODOMETRY_REPLAY_WINDOW_S));
    }
}
