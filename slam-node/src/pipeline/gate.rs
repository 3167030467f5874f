//! The odometry gate: odometry reaches the filter only up to the time of the beam being
//! processed (so the filter never runs ahead of the radar), and a beam reaches the filter
//! only when odometry covers it. Without odometry, or with odometry older than
//! `stale_after_s` behind the beam, the beam is refused and counted: no motion is
//! fabricated. The odometry the filter holds is the filter's ([`slam_filter::Ekf::held_odometry`]);
//! the gate keeps only what is not yet applied.

use slam_filter::{Ekf, OdometrySample, ProcessModel};
use tracing::warn;

use super::odometry::OdometryQueue;
use super::summary::RefusalCounts;
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

/// Odometry waiting for the radar, and the refusal rule.
#[derive(Debug)]
pub struct OdometryGate {
    queue: OdometryQueue,
    stale_after_s: f64,
    last_warning_s: f64,
}

/// Warnings about refused beams at most this often (stream seconds).
const WARN_EVERY_S: f64 = 5.0;

impl OdometryGate {
    /// A gate holding at most `capacity` pending samples, refusing beams whose odometry is
    /// older than `stale_after_s`.
    pub fn new(capacity: usize, stale_after_s: f64) -> Self {
        Self {
            queue: OdometryQueue::new(capacity),
            stale_after_s,
            last_warning_s: f64::NEG_INFINITY,
        }
    }

    /// Queues a sample; returns one that must be applied now (the queue is full).
    pub fn push(&mut self, sample: OdometrySample) -> Option<OdometrySample> {
        self.queue.push(sample)
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
