//! Grouping detections from neighbouring azimuths into one observation per target.
//!
//! A pencil beam 1.8 degrees wide sees a point target in one to three consecutive azimuths
//! (more with a finer azimuth step). Detections in consecutive azimuths whose ranges agree
//! within `range_gate_m` are one target; the group becomes one observation with the
//! power-weighted bearing (linear power weights), the power-weighted range, the strongest
//! power, and the timestamp of the strongest azimuth.
//!
//! The grouper is streaming: azimuths go in one at a time in rotation order, and a group is
//! closed as soon as an azimuth goes by that does not extend it. Across the end of a
//! rotation the next azimuth is simply the next one, so a target straddling azimuth zero is
//! not split. Completed observations are released in timestamp order, and only once no open
//! group could still produce an earlier one, so the filter sees non-decreasing time.
//! A group wider than `max_width_rad` (a wall seen along its length) is closed and a new one
//! started, so an extended target becomes a row of observations, not one smeared point;
//! both pieces are marked [`Observation::cut`], and each observation carries its width
//! across azimuths and its longest extent in range, so that the front end can tell
//! point-like returns from extended ones.

use radar_model::geometry::wrap_angle;

/// One target as the filter sees it: `z = [R, beta, P]` at `timestamp_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Range to the target, metres.
    pub range_m: f64,
    /// Bearing, the paper's beta (clockwise from the vehicle's forward axis), radians.
    pub bearing_rad: f64,
    /// Received power with the receiver's range compensation removed, dB (the filter's P).
    pub power_db: f64,
    /// Time of the strongest azimuth in the group, Unix seconds.
    pub timestamp_s: f64,
    /// Azimuths that contributed.
    pub azimuths: u32,
    /// Range of the strongest single detection in the group (used to order targets
    /// down one beam), metres.
    pub peak_range_m: f64,
    /// Longest extent in range of any of its detections, metres.
    pub extent_m: f64,
    /// Strongest of its detections over the floor, dB.
    pub snr_db: f64,
    /// Angle between its first and last azimuth, radians.
    pub width_rad: f64,
    /// Part of a return wider than the widest group (a wall seen along its length, cut
    /// into pieces).
    pub cut: bool,
    /// Whether it may start a new feature (the front end's landmark test decides; true
    /// as grouped).
    pub may_start: bool,
}

/// One detection handed to the grouper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamDetection {
    /// Range, metres.
    pub range_m: f64,
    /// Uncompensated power, dB.
    pub power_db: f64,
    /// Extent of the return in range, metres.
    pub extent_m: f64,
    /// Peak over the floor, dB.
    pub snr_db: f64,
}

/// Grouping settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupingSettings {
    /// Largest range difference between detections in consecutive azimuths of one target.
    pub range_gate_m: f64,
    /// Largest bearing step that still counts as the neighbouring azimuth, radians
    /// (about 1.5 azimuth steps).
    pub max_step_rad: f64,
    /// Widest angular extent of one group, radians.
    pub max_width_rad: f64,
}

#[derive(Debug, Clone)]
struct OpenGroup {
    first_bearing_rad: f64,
    last_bearing_rad: f64,
    last_range_m: f64,
    first_timestamp_s: f64,
    reference_db: f64,
    weight_sum: f64,
    // Sum of weight * unit vector of the bearing: averaging on the circle.
    sin_sum: f64,
    cos_sum: f64,
    range_sum: f64,
    best_power_db: f64,
    best_timestamp_s: f64,
    best_range_m: f64,
    azimuths: u32,
    max_extent_m: f64,
    max_snr_db: f64,
    cut: bool,
}

impl OpenGroup {
    fn start(d: &BeamDetection, bearing_rad: f64, timestamp_s: f64) -> Self {
        let mut g = Self {
            first_bearing_rad: bearing_rad,
            last_bearing_rad: bearing_rad,
            last_range_m: d.range_m,
            first_timestamp_s: timestamp_s,
            reference_db: d.power_db,
            weight_sum: 0.0,
            sin_sum: 0.0,
            cos_sum: 0.0,
            range_sum: 0.0,
            best_power_db: f64::NEG_INFINITY,
            best_timestamp_s: timestamp_s,
            best_range_m: d.range_m,
            azimuths: 0,
            max_extent_m: 0.0,
            max_snr_db: f64::NEG_INFINITY,
            cut: false,
        };
        g.add(d, bearing_rad, timestamp_s);
        g
    }

    fn add(&mut self, d: &BeamDetection, bearing_rad: f64, timestamp_s: f64) {
        // Weights relative to 0 dB can overflow for huge uncompensated powers; weights
        // relative to the group's first power cannot, within any physical spread. A common
        // scale cancels in the weighted means.
        let w = 10f64.powf(((d.power_db - self.reference_db) / 10.0).clamp(-300.0, 300.0));
        self.weight_sum += w;
        self.sin_sum += w * bearing_rad.sin();
        self.cos_sum += w * bearing_rad.cos();
        self.range_sum += w * d.range_m;
        self.last_bearing_rad = bearing_rad;
        self.last_range_m = d.range_m;
        self.azimuths += 1;
        if d.extent_m > self.max_extent_m {
            self.max_extent_m = d.extent_m;
        }
        if d.snr_db > self.max_snr_db {
            self.max_snr_db = d.snr_db;
        }
        if d.power_db > self.best_power_db {
            self.best_power_db = d.power_db;
            self.best_timestamp_s = timestamp_s;
            self.best_range_m = d.range_m;
        }
    }

    fn finish(&self) -> Observation {
        Observation {
            range_m: self.range_sum / self.weight_sum,
            bearing_rad: wrap_angle(self.sin_sum.atan2(self.cos_sum)),
            power_db: self.best_power_db,
            timestamp_s: self.best_timestamp_s,
            azimuths: self.azimuths,
            peak_range_m: self.best_range_m,
            extent_m: self.max_extent_m,
            snr_db: self.max_snr_db,
            width_rad: wrap_angle(self.last_bearing_rad - self.first_bearing_rad).abs(),
            cut: self.cut,
            may_start: true,
        }
    }
}

/// [`wrap_angle`] of the difference of two bearings, without its floating-point remainder
/// on the grouper's inner loop: for `|d| < 2 pi` the remainder is `d` itself (exact), so the
/// same operations give the same bits; anything else goes to [`wrap_angle`].
fn wrap_difference(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    // NaN and the infinities fail the test too.
    if d.is_nan() || d.abs() >= TAU {
        return wrap_angle(d);
    }
    // `d.rem_euclid(TAU)` for |d| < 2 pi, then wrap_angle's two corrections.
    let mut a = if d < 0.0 { d + TAU } else { d };
    if a > PI {
        a -= TAU;
    }
    if a <= -PI {
        a += TAU;
    }
    a
}

/// Inserts `o` into `done` (in time order) after every observation not later than it: the
/// order a stable sort by time of `done` with `o` appended would give, without sorting the
/// whole list again for every azimuth.
fn insert_by_time(done: &mut Vec<Observation>, o: Observation) {
    let at = done.partition_point(|d| d.timestamp_s.total_cmp(&o.timestamp_s).is_le());
    done.insert(at, o);
}

/// True when there is no candidate yet or `dr` is closer than the current one.
fn closer_than(best: Option<(usize, f64)>, dr: f64) -> bool {
    match best {
        None => true,
        Some((_, best_dr)) => dr < best_dr,
    }
}

/// The streaming grouper.
#[derive(Debug)]
pub struct Grouper {
    settings: GroupingSettings,
    open: Vec<OpenGroup>,
    done: Vec<Observation>,
    scratch: Vec<OpenGroup>,
    extended: Vec<bool>,
    still_open: Vec<OpenGroup>,
}

impl Grouper {
    /// An empty grouper.
    pub fn new(settings: GroupingSettings) -> Self {
        Self {
            settings,
            open: Vec::new(),
            done: Vec::new(),
            scratch: Vec::new(),
            extended: Vec::new(),
            still_open: Vec::new(),
        }
    }

    /// Adds the detections of one azimuth (bearing `bearing_rad`, time `timestamp_s`) and
    /// appends to `ready` every observation that can no longer change or be preceded.
    pub fn push(
        &mut self,
        bearing_rad: f64,
        timestamp_s: f64,
        detections: &[BeamDetection],
        ready: &mut Vec<Observation>,
    ) {
        let s = self.settings;
        let mut extended = std::mem::take(&mut self.extended);
        extended.clear();
        extended.resize(self.open.len(), false);
        self.scratch.clear();
        for d in detections {
            if !(d.range_m.is_finite() && d.power_db.is_finite()) {
                continue;
            }
            // The open group from the previous azimuth nearest in range, if within the gate;
            // and whether one would have taken it but for its width.
            let mut best: Option<(usize, f64)> = None;
            let mut too_wide: Option<usize> = None;
            for (k, g) in self.open.iter().enumerate() {
                let step = wrap_difference(bearing_rad - g.last_bearing_rad).abs();
                let width = wrap_difference(bearing_rad - g.first_bearing_rad).abs();
                let dr = (d.range_m - g.last_range_m).abs();
                let free = !extended.get(k).copied().unwrap_or(true);
                if free && step <= s.max_step_rad && dr <= s.range_gate_m {
                    if width > s.max_width_rad {
                        too_wide = Some(k);
                    } else if closer_than(best, dr) {
                        best = Some((k, dr));
                    }
                }
            }
            match best.and_then(|(k, _)| self.open.get_mut(k).map(|g| (k, g))) {
                Some((k, g)) => {
                    g.add(d, bearing_rad, timestamp_s);
                    if let Some(e) = extended.get_mut(k) {
                        *e = true;
                    }
                }
                None => {
                    let mut g = OpenGroup::start(d, bearing_rad, timestamp_s);
                    // The continuation of a group cut at its widest: both are pieces of
                    // one extended return.
                    if let Some(k) = too_wide {
                        g.cut = true;
                        if let Some(o) = self.open.get_mut(k) {
                            o.cut = true;
                        }
                    }
                    self.scratch.push(g)
                }
            }
        }
        // Close every group that this azimuth did not extend.
        let mut still_open = std::mem::take(&mut self.still_open);
        still_open.clear();
        for (g, &ext) in self.open.drain(..).zip(extended.iter()) {
            if ext {
                still_open.push(g);
            } else {
                insert_by_time(&mut self.done, g.finish());
            }
        }
        still_open.append(&mut self.scratch);
        std::mem::swap(&mut self.open, &mut still_open);
        self.still_open = still_open;
        self.extended = extended;
        self.release(ready, false);
    }

    /// Closes every open group and releases everything (end of stream).
    pub fn flush(&mut self, ready: &mut Vec<Observation>) {
        for g in self.open.drain(..) {
            insert_by_time(&mut self.done, g.finish());
        }
        self.release(ready, true);
    }

    /// Observations closed but not yet released.
    pub fn pending(&self) -> usize {
        self.done.len() + self.open.len()
    }

    fn release(&mut self, ready: &mut Vec<Observation>, all: bool) {
        let horizon = if all {
            f64::INFINITY
        } else {
            self.open
                .iter()
                .map(|g| g.first_timestamp_s)
                .fold(f64::INFINITY, f64::min)
        };
        // `done` is kept in time order as it is filled (`insert_by_time`).
        let cut = self.done.partition_point(|o| o.timestamp_s <= horizon);
        ready.extend(self.done.drain(..cut));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEP: f64 = 1.8 * std::f64::consts::PI / 180.0;

    fn settings() -> GroupingSettings {
        GroupingSettings {
            range_gate_m: 0.75,
            max_step_rad: 1.5 * STEP,
            max_width_rad: 4.0 * STEP,
        }
    }

    fn det(range_m: f64, power_db: f64) -> BeamDetection {
        BeamDetection {
            range_m,
            power_db,
            extent_m: 0.1,
            snr_db: 30.0,
        }
    }

    #[test]
    fn one_target_over_three_azimuths_is_one_observation_at_the_power_weighted_bearing() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        // Equal power on the two outer azimuths: the weighted bearing is the middle one.
        g.push(10.0 * STEP, 1.0, &[det(20.0, 40.0)], &mut out);
        g.push(11.0 * STEP, 1.1, &[det(20.1, 50.0)], &mut out);
        g.push(12.0 * STEP, 1.2, &[det(20.0, 40.0)], &mut out);
        assert!(out.is_empty(), "still open");
        g.push(13.0 * STEP, 1.3, &[], &mut out);
        assert_eq!(out.len(), 1);
        let o = out[0];
        assert!((o.bearing_rad - 11.0 * STEP).abs() < 1e-12);
        assert_eq!(o.azimuths, 3);
        assert_eq!(o.power_db, 50.0);
        assert_eq!(o.timestamp_s, 1.1);
        // Weights 1 : 10 : 1 on ranges 20, 20.1, 20.
        assert!((o.range_m - (20.0 + 10.0 * 20.1 + 20.0) / 12.0).abs() < 1e-12);
    }

    #[test]
    fn two_targets_down_one_beam_stay_two_observations() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        g.push(0.0, 1.0, &[det(8.5, 30.0), det(14.0, 20.0)], &mut out);
        g.push(STEP, 1.1, &[det(8.5, 31.0), det(14.0, 21.0)], &mut out);
        g.flush(&mut out);
        assert_eq!(out.len(), 2);
        let mut ranges: Vec<f64> = out.iter().map(|o| o.range_m).collect();
        ranges.sort_by(f64::total_cmp);
        assert!((ranges[0] - 8.5).abs() < 1e-9 && (ranges[1] - 14.0).abs() < 1e-9);
    }

    #[test]
    fn a_target_straddling_azimuth_zero_is_not_split() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        g.push(
            std::f64::consts::PI - 0.5 * STEP,
            1.0,
            &[det(30.0, 40.0)],
            &mut out,
        );
        g.push(
            -std::f64::consts::PI + 0.5 * STEP,
            1.1,
            &[det(30.0, 40.0)],
            &mut out,
        );
        g.flush(&mut out);
        assert_eq!(out.len(), 1);
        assert!((out[0].bearing_rad.abs() - std::f64::consts::PI).abs() < 1e-9);
    }

    #[test]
    fn a_wall_wider_than_the_limit_becomes_several_observations() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        for k in 0..12 {
            g.push(k as f64 * STEP, k as f64, &[det(50.0, 40.0)], &mut out);
        }
        g.flush(&mut out);
        assert!(out.len() >= 3, "{}", out.len());
    }

    #[test]
    fn observations_are_released_in_time_order() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        // A long group starting first, a short one closing earlier.
        g.push(0.0, 1.0, &[det(10.0, 40.0), det(30.0, 20.0)], &mut out);
        g.push(STEP, 2.0, &[det(10.0, 41.0), det(30.0, 25.0)], &mut out);
        g.push(2.0 * STEP, 3.0, &[det(10.0, 50.0)], &mut out);
        g.push(3.0 * STEP, 4.0, &[det(10.0, 40.0)], &mut out);
        g.flush(&mut out);
        let times: Vec<f64> = out.iter().map(|o| o.timestamp_s).collect();
        assert_eq!(times, vec![2.0, 3.0]);
    }

    #[test]
    fn non_finite_detections_are_ignored() {
        let mut g = Grouper::new(settings());
        let mut out = Vec::new();
        g.push(
            0.0,
            1.0,
            &[det(f64::NAN, 40.0), det(5.0, f64::INFINITY)],
            &mut out,
        );
        g.flush(&mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn the_fast_bearing_difference_is_wrap_angle_to_the_bit() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut values = vec![
            0.0,
            -0.0,
            std::f64::consts::PI,
            -std::f64::consts::PI,
            std::f64::consts::TAU,
            -std::f64::consts::TAU,
            1e-300,
            -1e-300,
            7.0,
            -7.0,
            f64::NAN,
            f64::INFINITY,
        ];
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values
                .push(((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 4.0 * std::f64::consts::TAU);
        }
        for d in values {
            let (fast, slow) = (wrap_difference(d), wrap_angle(d));
            assert!(
                fast.to_bits() == slow.to_bits() || (fast.is_nan() && slow.is_nan()),
                "{d}: {fast} against {slow}"
            );
        }
    }
}
