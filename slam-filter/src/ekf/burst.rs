//! The burst guard (see [`FilterSettings::burst_factor`]): a beam whose targets arrive far
//! faster than the learned rate starts no features.

use crate::settings::FilterSettings;

/// The short and learned rates of targets per second (see
/// [`FilterSettings::burst_factor`]): exponentially decayed target counts and elapsed times.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TargetRate {
    short_count: f64,
    long_count: f64,
    long_time_s: f64,
    last_s: Option<f64>,
}

impl TargetRate {
    /// Counts a beam's `targets` at `time_s`; returns whether the rate is now a burst.
    pub(super) fn is_burst(&mut self, s: &FilterSettings, time_s: f64, targets: usize) -> bool {
        let dt = match self.last_s {
            Some(last) if time_s >= last => time_s - last,
            // A step back in time (a resynchronised clock): count from here.
            _ => 0.0,
        };
        self.last_s = Some(time_s);
        let n = targets as f64;
        self.short_count = self.short_count * (-dt / s.burst_window_s).exp() + n;
        let decay = (-dt / s.burst_norm_s).exp();
        let before = self.long_count * decay;
        self.long_count = before + n;
        self.long_time_s = self.long_time_s * decay + dt;
        if !s.burst_factor.is_finite() || self.long_time_s < s.burst_norm_s.min(2.0) {
            return false;
        }
        let short = self.short_count / s.burst_window_s;
        let norm = self.long_count / self.long_time_s;
        let burst = short > s.burst_factor * norm + s.burst_floor_per_s;
        if burst {
            // The burst's own targets do not teach the norm what is normal: over this beam's
            // interval it learns at most the threshold's rate. Learning all of them made a
            // burst its own norm within about a third of the time the norm had seen (3 s of
            // noise 10 s into a run), and the map flooded from then on; now the norm grows
            // at most geometrically, e^(3 t / burst_norm_s) at the shipped factor, so a
            // lasting change of scene is still accepted within about a norm time constant.
            let threshold = s.burst_factor * before / self.long_time_s + s.burst_floor_per_s;
            self.long_count = before + n.min(threshold * dt);
        }
        burst
    }
}
