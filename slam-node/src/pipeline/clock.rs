//! Time from the wire is a measurement, not a fact. A timestamp that jumps away from the
//! stream's clock (a frame stamped in 2100, a mutated seconds field, a record from a
//! misconfigured bridge) costs that sample only; a jump that the following samples confirm
//! (the sender's clock really was set) resynchronises the clock. No IO, no clock of its own.

/// What to make of one timestamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// It follows the stream's clock.
    Accept,
    /// It does not, and not enough samples agree with it yet: drop this sample.
    Outlier,
    /// Enough consecutive samples agree on a new clock: accept this one from it.
    Jump {
        /// The stream's clock before (s).
        from_s: f64,
        /// The new clock (s).
        to_s: f64,
    },
}

/// A stream's clock as seen through its timestamps.
#[derive(Debug, Clone)]
pub struct WireClock {
    last_s: Option<f64>,
    max_step_s: f64,
    confirm: u32,
    candidate: Option<(f64, u32)>,
    outliers: u64,
    jumps: u64,
}

impl WireClock {
    /// A clock that accepts steps forward of at most `max_step_s` between samples, and takes
    /// `confirm` consecutive samples that agree with each other (each within `max_step_s` of
    /// the one before) as a jump.
    pub fn new(max_step_s: f64, confirm: u32) -> Self {
        Self {
            last_s: None,
            max_step_s,
            confirm: confirm.max(1),
            candidate: None,
            outliers: 0,
            jumps: 0,
        }
    }

    /// Judges the timestamp `t_s` (and moves the clock when it is accepted).
    pub fn observe(&mut self, t_s: f64) -> Verdict {
        if !t_s.is_finite() {
            self.outliers += 1;
            return Verdict::Outlier;
        }
        let Some(last) = self.last_s else {
            self.last_s = Some(t_s);
            return Verdict::Accept;
        };
        let step = t_s - last;
        if (0.0..=self.max_step_s).contains(&step) {
            self.last_s = Some(t_s);
            self.candidate = None;
            return Verdict::Accept;
        }
        let count = match self.candidate {
            Some((c, n)) if (0.0..=self.max_step_s).contains(&(t_s - c)) => n + 1,
            _ => 1,
        };
        if count >= self.confirm {
            self.last_s = Some(t_s);
            self.candidate = None;
            self.jumps += 1;
            return Verdict::Jump {
                from_s: last,
                to_s: t_s,
            };
        }
        self.candidate = Some((t_s, count));
        self.outliers += 1;
        Verdict::Outlier
    }

    /// As [`WireClock::observe`], except that a forward step longer than `max_step_s` but
    /// at most `max_silence_s` is accepted at once when `vouch_s` (another stream's clock,
    /// guarded by its own `WireClock`: the odometry's) is within `max_step_s` of it. The
    /// sender was silent (a link down and back up) while time went on; its clock did not
    /// jump, and nothing needs resynchronising. Longer silences are confirmed as jumps.
    pub fn observe_vouched(
        &mut self,
        t_s: f64,
        vouch_s: Option<f64>,
        max_silence_s: f64,
    ) -> Verdict {
        if let (Some(last), Some(vouch)) = (self.last_s, vouch_s) {
            if t_s.is_finite()
                && t_s > last
                && t_s - last <= max_silence_s
                && (t_s - vouch).abs() <= self.max_step_s
            {
                self.last_s = Some(t_s);
                self.candidate = None;
                return Verdict::Accept;
            }
        }
        self.observe(t_s)
    }

    /// The stream's clock: the last accepted timestamp.
    pub fn now_s(&self) -> Option<f64> {
        self.last_s
    }

    /// Samples dropped as outliers.
    pub fn outliers(&self) -> u64 {
        self.outliers
    }

    /// Jumps resynchronised.
    pub fn jumps(&self) -> u64 {
        self.jumps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_far_future_stamp_costs_that_sample_only() {
        let mut c = WireClock::new(1.0, 8);
        for k in 0..10 {
            assert_eq!(c.observe(100.0 + 0.01 * f64::from(k)), Verdict::Accept);
        }
        assert_eq!(c.observe(4.1e9), Verdict::Outlier);
        assert_eq!(c.observe(100.11), Verdict::Accept);
        assert_eq!(c.now_s(), Some(100.11));
        assert_eq!(c.outliers(), 1);
    }

    #[test]
    fn a_stamp_in_the_past_is_an_outlier_and_nan_too() {
        let mut c = WireClock::new(1.0, 8);
        assert_eq!(c.observe(100.0), Verdict::Accept);
        assert_eq!(c.observe(99.0), Verdict::Outlier);
        assert_eq!(c.observe(f64::NAN), Verdict::Outlier);
        assert_eq!(c.observe(100.5), Verdict::Accept);
    }

    #[test]
    fn a_silence_the_other_clock_vouches_for_is_accepted_and_a_wild_stamp_is_not() {
        let mut c = WireClock::new(2.0, 16);
        assert_eq!(c.observe(100.0), Verdict::Accept);
        // The link was down for 3 s; the odometry went on to 103.1.
        assert_eq!(c.observe_vouched(103.0, Some(103.1), 60.0), Verdict::Accept);
        assert_eq!(c.jumps(), 0);
        // 2100 is vouched for by nothing; nor is a step back.
        assert_eq!(
            c.observe_vouched(4.1e9, Some(103.2), 60.0),
            Verdict::Outlier
        );
        assert_eq!(c.observe_vouched(90.0, Some(90.0), 60.0), Verdict::Outlier);
        // Without a vouching clock, a silence is a jump to confirm, as before; so is one
        // longer than the longest silence.
        assert_eq!(c.observe_vouched(110.0, None, 60.0), Verdict::Outlier);
        assert_eq!(
            c.observe_vouched(3703.0, Some(3703.0), 60.0),
            Verdict::Outlier
        );
    }

    #[test]
    fn a_jump_the_following_samples_confirm_resynchronises() {
        let mut c = WireClock::new(1.0, 4);
        assert_eq!(c.observe(100.0), Verdict::Accept);
        for k in 0..3 {
            assert_eq!(c.observe(5000.0 + 0.1 * f64::from(k)), Verdict::Outlier);
        }
        assert_eq!(
            c.observe(5000.3),
            Verdict::Jump {
                from_s: 100.0,
                to_s: 5000.3
            }
        );
        assert_eq!(c.observe(5000.4), Verdict::Accept);
        assert_eq!(c.jumps(), 1);
        // Backwards too (a clock set back).
        for k in 0..3 {
            assert_eq!(c.observe(50.0 + 0.1 * f64::from(k)), Verdict::Outlier);
        }
        assert!(matches!(c.observe(50.3), Verdict::Jump { .. }));
    }
}
