//! Odometry waiting to be applied: samples are held in time order and handed to the filter
//! only up to the time of the beam being processed, so the filter never runs ahead of the
//! radar. Bounded: past `capacity` the oldest sample is applied at once (it is the earliest
//! anyway) and counted.

use std::collections::VecDeque;

use slam_filter::OdometrySample;

/// Samples not yet applied, in time order.
#[derive(Debug)]
pub struct OdometryQueue {
    queue: VecDeque<OdometrySample>,
    capacity: usize,
    latest_s: Option<f64>,
    applied_s: Option<f64>,
    out_of_order: u64,
    forced: u64,
}

impl OdometryQueue {
    /// An empty queue holding at most `capacity` samples.
    pub fn new(capacity: usize) -> Self {
        Self {
            queue: VecDeque::new(),
            capacity: capacity.max(1),
            latest_s: None,
            applied_s: None,
            out_of_order: 0,
            forced: 0,
        }
    }

    /// Adds a sample. A sample older than the newest one already queued is dropped and
    /// counted (the stream must be in time order). Returns a sample that must be applied
    /// now because the queue is full.
    pub fn push(&mut self, s: OdometrySample) -> Option<OdometrySample> {
        if !(s.timestamp_s.is_finite() && s.speed_mps.is_finite() && s.steer_rad.is_finite()) {
            self.out_of_order += 1;
            return None;
        }
        if self.latest_s.is_some_and(|t| s.timestamp_s < t) {
            self.out_of_order += 1;
            return None;
        }
        self.latest_s = Some(s.timestamp_s);
        self.queue.push_back(s);
        if self.queue.len() > self.capacity {
            self.forced += 1;
            let oldest = self.queue.pop_front();
            if let Some(o) = oldest {
                self.applied_s = Some(o.timestamp_s);
            }
            return oldest;
        }
        None
    }

    /// Removes and returns the next sample at or before `time_s`.
    pub fn pop_until(&mut self, time_s: f64) -> Option<OdometrySample> {
        if self.queue.front().is_some_and(|s| s.timestamp_s <= time_s) {
            let s = self.queue.pop_front();
            if let Some(s) = s {
                self.applied_s = Some(s.timestamp_s);
            }
            return s;
        }
        None
    }

    /// Newest sample time received.
    pub fn latest_s(&self) -> Option<f64> {
        self.latest_s
    }

    /// Newest sample time handed to the filter.
    pub fn applied_s(&self) -> Option<f64> {
        self.applied_s
    }

    /// Forgets every pending sample and the newest time (the sender's clock jumped).
    pub fn reset(&mut self) {
        self.queue.clear();
        self.latest_s = None;
    }

    /// Samples dropped for being out of order or not finite.
    pub fn out_of_order(&self) -> u64 {
        self.out_of_order
    }

    /// Samples applied early because the queue was full.
    pub fn forced(&self) -> u64 {
        self.forced
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: f64) -> OdometrySample {
        OdometrySample {
            timestamp_s: t,
            speed_mps: 1.0,
            steer_rad: 0.0,
        }
    }

    #[test]
    fn samples_come_out_only_up_to_the_asked_time() {
        let mut q = OdometryQueue::new(10);
        for t in [1.0, 1.05, 1.1] {
            assert!(q.push(s(t)).is_none());
        }
        assert_eq!(q.pop_until(1.07).map(|x| x.timestamp_s), Some(1.0));
        assert_eq!(q.pop_until(1.07).map(|x| x.timestamp_s), Some(1.05));
        assert!(q.pop_until(1.07).is_none());
        assert_eq!(q.applied_s(), Some(1.05));
        assert_eq!(q.latest_s(), Some(1.1));
    }

    #[test]
    fn out_of_order_and_non_finite_samples_are_dropped_and_counted() {
        let mut q = OdometryQueue::new(10);
        q.push(s(2.0));
        q.push(s(1.0));
        q.push(s(f64::NAN));
        assert_eq!(q.out_of_order(), 2);
    }

    #[test]
    fn a_full_queue_hands_back_its_oldest_sample() {
        let mut q = OdometryQueue::new(2);
        q.push(s(1.0));
        q.push(s(2.0));
        assert_eq!(q.push(s(3.0)).map(|x| x.timestamp_s), Some(1.0));
        assert_eq!(q.forced(), 1);
    }
}
