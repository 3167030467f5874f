//! One rotation after another: each azimuth's strongest returns placed in the frame of the
//! vehicle at the last mark (the caller's motion estimate de-skews the cloud), and at the
//! end of a rotation the cloud registered against the previous rotation's, giving the
//! vehicle's motion between the two with a covariance and how well the scene pinned it.
//!
//! Memory: two clouds of at most `points_per_azimuth` x azimuths points (16 bytes each),
//! bounded by [`MAX_POINTS`], and over the previous cloud a k-d tree (for the normals) and
//! a pair grid of at most 2^18 cells, rebuilt once a rotation.

use nalgebra::{Matrix3, Vector3};
use radar_model::geometry::Pose2;

use crate::cloud::ReferenceCloud;
use crate::register::{covariance, in_frame_of, register, Constraint, Registration};

/// Points a rotation's cloud holds at most, whatever the radar's geometry.
pub const MAX_POINTS: usize = 1 << 15;
/// A registration pairing under this share of what recent ones paired is retried from
/// other headings ([`ScanMatcher`]'s `follow`).
pub const TURN_PAIRED_SHARE: f64 = 0.7;
/// The heading offsets (rad, each either side) a registration is retried from.
pub const TURN_SEEDS_RAD: [f64; 2] = [0.05, 0.1];
/// Pairs a registration needs at least, however few points a rotation has.
pub const MIN_PAIRS_FLOOR: usize = 12;
/// A weak registration's standard deviation along its weak direction (m): no information.
pub const UNINFORMATIVE_SIGMA_M: f64 = 100.0;

/// Radar odometry's settings (`[odometry] radar_odometry*` and the radar's profile).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanMatchSettings {
    /// Whether rotations are registered and the result given to the filter.
    pub enabled: bool,
    /// Strongest returns kept per azimuth.
    pub points_per_azimuth: usize,
    /// Returns nearer than this are not used (m): the vehicle's own body and the antenna's
    /// leakage.
    pub min_range_m: f64,
    /// Returns farther than this are not used (m): the beam's width makes them coarse.
    pub max_range_m: f64,
    /// Standard deviation of a registration's translation on a well-constrained scene, each
    /// axis (m): the covariance's floor.
    pub sigma_xy_m: f64,
    /// Standard deviation of a registration's rotation on a well-constrained scene (rad).
    pub sigma_theta_rad: f64,
    /// Pairs farther apart than this are not paired at the first iteration (m); the gate
    /// narrows to a fifth of it.
    pub pair_gate_m: f64,
    /// A registration with fewer pairs is not used.
    pub min_pairs: usize,
    /// A reference point's normal is fitted to its neighbours within this distance (m).
    pub normal_radius_m: f64,
    /// Pairs taken to share one error in the covariance's information term (pairs along
    /// one surface are not independent); see [`covariance`].
    pub correlated_pairs: f64,
    /// The residual (m) the information term assumes at least, however small the fit's.
    pub min_residual_m: f64,
    /// A registration whose [`Constraint::weakest`] is below this is reported weak: the
    /// scene does not pin the motion in one direction (an open field, a long bare wall).
    pub weak_constraint: f64,
    /// Without a motion estimate (the first rotations, after a failed registration) the
    /// registration is tried from starts up to this far ahead and behind (m).
    pub search_m: f64,
}

impl Default for ScanMatchSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            points_per_azimuth: 6,
            min_range_m: 4.0,
            max_range_m: 80.0,
            sigma_xy_m: 0.05,
            sigma_theta_rad: 0.003,
            pair_gate_m: 0.6,
            min_pairs: 100,
            normal_radius_m: 1.5,
            correlated_pairs: 10.0,
            min_residual_m: 0.02,
            weak_constraint: 0.02,
            search_m: 6.0,
        }
    }
}

/// A radar return as radar odometry uses it: where down the beam, and how strong.
pub trait RadarReturn {
    /// Range (m).
    fn range_m(&self) -> f64;
    /// Strength (dB, any reference: only the order within an azimuth matters; `+inf` is
    /// the strongest, NaN is no return).
    fn strength_db(&self) -> f64;
}

/// A plain return.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Return {
    /// Range (m).
    pub range_m: f64,
    /// Strength (dB).
    pub strength_db: f64,
}

impl RadarReturn for Return {
    fn range_m(&self) -> f64 {
        self.range_m
    }
    fn strength_db(&self) -> f64 {
        self.strength_db
    }
}

/// The motion one rotation's registration measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationMotion {
    /// The vehicle's pose at this rotation's end in its frame at the previous rotation's
    /// end (the mark).
    pub motion: Pose2,
    /// Its covariance, `[x m, y m, heading rad]`.
    pub covariance: Matrix3<f64>,
    /// The registration.
    pub registration: Registration,
    /// How well the scene pinned it.
    pub constraint: Constraint,
    /// Whether [`Constraint::weakest`] is below [`ScanMatchSettings::weak_constraint`].
    pub weak: bool,
    /// Whether it came from a search over starts (no motion estimate was given).
    pub searched: bool,
}

/// What the matcher did so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MatcherCounts {
    /// Registrations tried (a rotation with a previous one to register against).
    pub tried: u64,
    /// Registrations with too few pairs or no usable covariance.
    pub failed: u64,
    /// Registrations the scene pinned weakly in one direction.
    pub weak: u64,
    /// Registrations that searched over starts.
    pub searched: u64,
    /// Registrations retried from other headings (few pairs: a turn's onset).
    pub turned: u64,
}

/// The clouds of the current and previous rotation.
#[derive(Debug, Default)]
pub struct ScanMatcher {
    settings: ScanMatchSettings,
    /// This rotation's points in the frame at the last mark.
    current: Vec<[f64; 2]>,
    /// The previous rotation's points in the vehicle's frame at its end.
    previous: Option<ReferenceCloud>,
    /// Scratch for one azimuth's strongest returns.
    order: Vec<usize>,
    counts: MatcherCounts,
    /// The share of a cloud's points paired in recent registrations (an average over about
    /// ten), against which a registration stuck short of a turn shows.
    paired_share: Option<f64>,
}

impl ScanMatcher {
    /// A matcher with `settings`.
    pub fn new(settings: ScanMatchSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// Its settings.
    pub fn settings(&self) -> &ScanMatchSettings {
        &self.settings
    }

    /// Whether it runs.
    pub fn enabled(&self) -> bool {
        self.settings.enabled
    }

    /// What it did so far.
    pub fn counts(&self) -> MatcherCounts {
        self.counts
    }

    /// Adds one azimuth's returns at `bearing_rad`, the sensor at `sensor` (the frame at the
    /// last mark; `None` when there is none: nothing is added). Keeps the strongest
    /// [`ScanMatchSettings::points_per_azimuth`] within the range limits.
    pub fn add_azimuth<R: RadarReturn>(
        &mut self,
        sensor: Option<Pose2>,
        bearing_rad: f64,
        returns: &[R],
    ) {
        let Some(sensor) = sensor else {
            return;
        };
        let s = &self.settings;
        self.order.clear();
        self.order.extend(
            returns
                .iter()
                .enumerate()
                .filter(|(_, d)| {
                    let r = d.range_m();
                    // An infinite strength (a return over a noise floor of zero, as a
                    // simulator may give) is the strongest; NaN is no return.
                    r >= s.min_range_m && r <= s.max_range_m && !d.strength_db().is_nan()
                })
                .map(|(i, _)| i),
        );
        let keep = s.points_per_azimuth.min(self.order.len());
        if keep < self.order.len() {
            self.order.select_nth_unstable_by(keep, |&a, &b| {
                returns[b]
                    .strength_db()
                    .total_cmp(&returns[a].strength_db())
            });
        }
        let room = MAX_POINTS.saturating_sub(self.current.len());
        for &i in self.order.iter().take(keep.min(room)) {
            self.current
                .push(sensor.point_at(returns[i].range_m(), bearing_rad));
        }
    }

    /// Closes a rotation: `end` is the vehicle's pose at the rotation's end in the frame at
    /// the last mark (the caller's motion estimate), `None` without a mark. Registers the
    /// cloud against the previous rotation's, started at `end`, or, with `search`, from
    /// starts spread [`ScanMatchSettings::search_m`] ahead and behind (the caller has no
    /// motion estimate), and returns the measured motion when the registration holds.
    pub fn end_rotation(&mut self, end: Option<Pose2>, search: bool) -> Option<RotationMotion> {
        let points = std::mem::take(&mut self.current);
        let Some(end) = end else {
            self.previous = None;
            return None;
        };
        let local = in_frame_of(&end, &points);
        let mut out = None;
        // Replaced by this rotation's cloud below, whatever the registration does.
        if let Some(reference) = self.previous.take() {
            let reference = &reference;
            self.counts.tried += 1;
            let min_pairs = self.min_pairs(local.len());
            let reg = if search {
                self.counts.searched += 1;
                self.search(reference, &local, end, min_pairs)
            } else {
                self.follow(reference, &local, end, min_pairs)
            };
            if let (Some(r), false) = (reg.as_ref(), local.is_empty()) {
                let share = r.pairs as f64 / local.len() as f64;
                self.paired_share = Some(match self.paired_share {
                    Some(s) => 0.9 * s + 0.1 * share,
                    None => share,
                });
            }
            out = reg.and_then(|reg| self.measured(reg, search));
            match &out {
                Some(m) if m.weak => self.counts.weak += 1,
                Some(_) => {}
                None => self.counts.failed += 1,
            }
        }
        self.previous = if local.is_empty() {
            None
        } else {
            Some(ReferenceCloud::new(
                local,
                self.settings.normal_radius_m,
                self.settings.pair_gate_m,
            ))
        };
        out
    }

    /// Pairs a registration of `points` points needs: [`ScanMatchSettings::min_pairs`], or
    /// half the cloud when that is fewer (a scene of a few point landmarks, as the paper's
    /// unit sees, gives tens of returns a rotation), but never fewer than
    /// [`MIN_PAIRS_FLOOR`].
    fn min_pairs(&self, points: usize) -> usize {
        self.settings
            .min_pairs
            .min((points / 2).max(MIN_PAIRS_FLOOR))
    }

    /// The registration started at `end`; when it pairs far fewer of the cloud's points than
    /// recent ones did (under [`TURN_PAIRED_SHARE`] of their share), it may have stopped short
    /// of a turn's onset, which the motion estimate did not foresee: the registration is
    /// tried again from headings [`TURN_SEEDS_RAD`] either side and the one with the most
    /// pairs kept (ICP's basin in heading is a few hundredths of a radian at this gate).
    fn follow(
        &mut self,
        reference: &ReferenceCloud,
        local: &[[f64; 2]],
        end: Pose2,
        min_pairs: usize,
    ) -> Option<Registration> {
        let gate = self.settings.pair_gate_m;
        let first = register(reference, local, end, gate, min_pairs);
        let (Some(typical), false) = (self.paired_share, local.is_empty()) else {
            return first;
        };
        let share = first
            .as_ref()
            .map_or(0.0, |r| r.pairs as f64 / local.len() as f64);
        if share >= TURN_PAIRED_SHARE * typical {
            return first;
        }
        self.counts.turned += 1;
        TURN_SEEDS_RAD
            .iter()
            .flat_map(|d| [*d, -*d])
            .filter_map(|d| {
                let start = Pose2::new(end.x, end.y, end.theta + d);
                register(reference, local, start, gate, min_pairs)
            })
            .chain(first)
            .max_by(|a, b| a.pairs.cmp(&b.pairs).then(b.rms_m.total_cmp(&a.rms_m)))
    }

    /// The registration with the most pairs (then the smallest residual) over starts spread
    /// along the vehicle's axis, a pair gate apart.
    fn search(
        &self,
        reference: &ReferenceCloud,
        local: &[[f64; 2]],
        end: Pose2,
        min_pairs: usize,
    ) -> Option<Registration> {
        let s = &self.settings;
        let step = s.pair_gate_m.max(0.1);
        let n = (s.search_m / step).ceil().clamp(0.0, 200.0) as i32;
        (-n..=n)
            .filter_map(|k| {
                let start = Pose2::new(end.x + f64::from(k) * step, end.y, end.theta);
                register(reference, local, start, s.pair_gate_m, min_pairs)
            })
            .max_by(|a, b| a.pairs.cmp(&b.pairs).then(b.rms_m.total_cmp(&a.rms_m)))
    }

    fn measured(&self, reg: Registration, searched: bool) -> Option<RotationMotion> {
        let s = &self.settings;
        let sxy = s.sigma_xy_m.powi(2);
        let floor = Matrix3::from_diagonal(&Vector3::new(sxy, sxy, s.sigma_theta_rad.powi(2)));
        let mut covariance = covariance(&reg, &floor, s.correlated_pairs, s.min_residual_m)?;
        let constraint = Constraint::of(&reg)?;
        let weak = constraint.weakest < s.weak_constraint;
        if weak {
            // What the pairs say along the weak direction is noise (or the samples moving
            // with the sensor): the measurement is made to say nothing there.
            let d = constraint.direction;
            let v = Vector3::new(d[0], d[1], d[2] / crate::register::HEADING_LENGTH_M);
            covariance += v * v.transpose() * UNINFORMATIVE_SIGMA_M.powi(2);
        }
        Some(RotationMotion {
            motion: reg.pose,
            covariance,
            registration: reg,
            weak,
            constraint,
            searched,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Returns of `world` seen from `pose`: per azimuth of 400, the points within a degree
    /// of the beam.
    fn scan(world: &[[f64; 2]], pose: &Pose2) -> Vec<(f64, Vec<Return>)> {
        let local = in_frame_of(pose, world);
        (0..400)
            .map(|k| {
                let bearing = std::f64::consts::TAU * f64::from(k) / 400.0;
                let returns = local
                    .iter()
                    .filter(|p| {
                        let b = p[1].atan2(p[0]);
                        radar_model::geometry::wrap_angle(-b - bearing).abs()
                            < std::f64::consts::PI / 400.0
                    })
                    .map(|p| Return {
                        range_m: p[0].hypot(p[1]),
                        strength_db: 30.0,
                    })
                    .collect();
                (bearing, returns)
            })
            .collect()
    }

    fn feed(m: &mut ScanMatcher, world: &[[f64; 2]], pose: &Pose2) {
        for (bearing, returns) in scan(world, pose) {
            m.add_azimuth(Some(Pose2::new(0.0, 0.0, 0.0)), bearing, &returns);
        }
    }

    /// Building fronts with set-backs every few metres on both sides and posts between:
    /// a street whose structure pins the motion along it.
    fn town() -> Vec<[f64; 2]> {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut uniform = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pts = Vec::new();
        for (side, base) in [(1.0, 8.0), (-1.0, 7.5)] {
            let mut s = -60.0;
            while s < 60.0 {
                let len = 4.0 + 8.0 * uniform();
                let offset = base + 2.0 * uniform();
                let n = (len / 0.3) as usize;
                for i in 0..n {
                    pts.push([s + len * i as f64 / n as f64, side * offset]);
                }
                for j in 0..10 {
                    pts.push([s + len, side * (offset + 0.2 * f64::from(j))]);
                }
                s += len;
            }
        }
        for _ in 0..15 {
            pts.push([
                -55.0 + 110.0 * uniform(),
                if uniform() < 0.5 { 4.0 } else { -4.0 },
            ]);
        }
        pts
    }

    #[test]
    fn a_search_finds_a_motion_far_beyond_the_pair_gate() {
        let world = town();
        let settings = ScanMatchSettings {
            enabled: true,
            points_per_azimuth: 50,
            min_pairs: 50,
            ..ScanMatchSettings::default()
        };
        let truth = Pose2::new(3.1, 0.02, 0.01);
        let mut m = ScanMatcher::new(settings);
        feed(&mut m, &world, &Pose2::new(0.0, 0.0, 0.0));
        assert!(m
            .end_rotation(Some(Pose2::new(0.0, 0.0, 0.0)), true)
            .is_none());
        feed(&mut m, &world, &truth);
        // Expressed at the mark: the cloud was placed at the origin, so `end` is the origin.
        let found = m
            .end_rotation(Some(Pose2::new(0.0, 0.0, 0.0)), true)
            .expect("found by the search");
        assert!(found.searched);
        assert!((found.motion.x - truth.x).abs() < 0.05, "{found:?}");
        assert!((found.motion.y - truth.y).abs() < 0.05, "{found:?}");
        assert_eq!(m.counts().searched, 1);
        assert_eq!(m.counts().tried, 1);
    }

    #[test]
    fn a_lone_wall_is_reported_weak_and_its_covariance_grows_along_it() {
        let wall: Vec<[f64; 2]> = (0..400)
            .map(|i| [-40.0 + 0.2 * f64::from(i), 6.0])
            .collect();
        // Within 15 m the wall's samples are dense enough for every one to get a normal;
        // farther, at grazing angles, the samples of one azimuth to the next lie metres
        // apart, get none, and are paired point to point, which pins the motion along the
        // wall falsely (the samples move with the sensor): a limit of the registration.
        let settings = ScanMatchSettings {
            enabled: true,
            points_per_azimuth: 50,
            min_pairs: 20,
            max_range_m: 15.0,
            ..ScanMatchSettings::default()
        };
        let mut m = ScanMatcher::new(settings);
        feed(&mut m, &wall, &Pose2::new(0.0, 0.0, 0.0));
        m.end_rotation(Some(Pose2::new(0.0, 0.0, 0.0)), false);
        feed(&mut m, &wall, &Pose2::new(1.0, 0.0, 0.0));
        let got = m
            .end_rotation(Some(Pose2::new(0.0, 0.0, 0.0)), false)
            .expect("registers across the wall");
        assert!(got.weak, "{:?}", got.constraint);
        assert_eq!(m.counts().weak, 1);
        assert!(
            got.covariance[(0, 0)].sqrt() > 50.0,
            "along-track sigma {} m for a motion it cannot see",
            got.covariance[(0, 0)].sqrt()
        );
        assert!(
            got.covariance[(1, 1)].sqrt() < 0.2,
            "across the wall the motion is seen: sigma {} m",
            got.covariance[(1, 1)].sqrt()
        );
    }
}
