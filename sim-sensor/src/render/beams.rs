//! Which features a beam sees, at a cost that does not grow with the scene.
//!
//! Once per rotation the features within range of the rotation's middle pose are gathered
//! from the grid, each seen rotated about that pose by its bearing error for the rotation,
//! and sorted by bearing. Each azimuth then tests only those whose bearing lies within the
//! beam plus a margin bounding how far the vehicle's motion during the rotation can move a
//! bearing; features within [`NEAR_RANGE_M`] plus twice the distance travelled, whose bearing
//! can swing widely, are tested on every azimuth.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use radar_model::geometry::{range_bearing, wrap_angle, Beam, Pose2};

use super::{azimuth_in_rotation, SceneRenderer};
use crate::error::SimError;
use crate::trajectory::TrajectoryCursor;

/// Features nearer than this to a rotation's middle pose (plus twice the distance travelled)
/// are tested on every azimuth of that rotation.
pub const NEAR_RANGE_M: f64 = 5.0;
/// Random stream reserved for the per-rotation bearing errors (azimuth streams use the
/// azimuth index, which never reaches it).
const BEARING_STREAM_BASE: u64 = 1 << 63;
/// Poses sampled per rotation to bound the vehicle's motion during it.
const MOTION_SAMPLES: u64 = 8;

#[derive(Debug, Clone, Copy)]
struct Candidate {
    bearing_mid: f64,
    index: usize,
    apparent: [f64; 2],
}

/// A feature inside a beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    /// True range from the azimuth's pose to the feature's apparent position, metres.
    pub range_m: f64,
    /// The feature's index in the scene.
    pub index: usize,
    /// How much nearer the radar's range-Doppler coupling renders it, metres.
    pub doppler_shift_m: f64,
}

impl Hit {
    /// The range its return is rendered at, metres.
    pub fn rendered_range_m(&self) -> f64 {
        self.range_m - self.doppler_shift_m
    }
}

/// One client's beam selection state: the current rotation's candidates and the last hits.
#[derive(Debug, Default)]
pub(crate) struct BeamSelector {
    rotation: Option<u64>,
    candidates: Vec<Candidate>,
    near: Vec<Candidate>,
    margin_rad: f64,
    /// Occluding segments near the current rotation.
    occluders: Vec<[[f64; 2]; 2]>,
    /// The features in the last selected beam, nearest (by true range) first.
    pub(super) hits: Vec<Hit>,
}

impl BeamSelector {
    /// Collects the features in azimuth `index`'s beam (sorted by range) into
    /// [`BeamSelector::hits`] and returns the pose they were seen from.
    pub(super) fn select(
        &mut self,
        r: &SceneRenderer,
        trajectory: &mut TrajectoryCursor,
        index: u64,
    ) -> Result<Pose2, SimError> {
        let n = u64::from(r.radar.azimuths);
        let rotation = index / n;
        if self.rotation != Some(rotation) {
            self.prepare_rotation(r, trajectory, rotation)?;
        }
        let offset_ns = r.offset_ns(index);
        let pose = r.trajectory.pose_with(trajectory, offset_ns)?;
        // The features are static: each closes on the radar at the vehicle's forward speed
        // times the cosine of its bearing.
        let coupling_m = r
            .radar
            .doppler_range_shift_m(r.trajectory.controls_at(offset_ns).0);
        let bearing = r
            .radar
            .angle_of_encoder(r.radar.encoder_of(azimuth_in_rotation(&r.radar, index)));
        let beam = Beam {
            bearing_rad: wrap_angle(bearing),
            width_rad: r.radar.beam_width_rad,
            min_range_m: 0.0,
            max_range_m: r.radar.max_range_m(),
        };
        self.hits.clear();
        let half = 0.5 * beam.width_rad + self.margin_rad;
        let test = |c: &Candidate, hits: &mut Vec<Hit>| {
            let rb = range_bearing(&pose, c.apparent);
            if beam.contains(&rb) {
                hits.push(Hit {
                    range_m: rb.range_m,
                    index: c.index,
                    doppler_shift_m: if coupling_m == 0.0 {
                        0.0
                    } else {
                        coupling_m * rb.bearing_rad.cos()
                    },
                });
            }
        };
        for c in &self.near {
            test(c, &mut self.hits);
        }
        for_each_in_window(&self.candidates, beam.bearing_rad, half, |c| {
            test(c, &mut self.hits)
        });
        self.hits
            .sort_by(|a, b| a.range_m.total_cmp(&b.range_m).then(a.index.cmp(&b.index)));
        Ok(pose)
    }

    fn prepare_rotation(
        &mut self,
        r: &SceneRenderer,
        trajectory: &mut TrajectoryCursor,
        rotation: u64,
    ) -> Result<(), SimError> {
        let n = u64::from(r.radar.azimuths);
        let first = rotation.saturating_mul(n);
        let mid_offset = r.offset_ns(first + n / 2);
        let mid = r.trajectory.pose_with(trajectory, mid_offset)?;
        // Bound the motion during the rotation from a few sampled poses.
        let mut travel_m: f64 = 0.0;
        let mut turn_rad: f64 = 0.0;
        for s in 0..=MOTION_SAMPLES {
            let k = first + (n.saturating_sub(1)) * s / MOTION_SAMPLES;
            let p = r.trajectory.pose_with(trajectory, r.offset_ns(k))?;
            travel_m = travel_m.max((p.x - mid.x).hypot(p.y - mid.y));
            turn_rad = turn_rad.max(wrap_angle(p.theta - mid.theta).abs());
        }
        // Samples can miss the extremes between them: pad generously.
        travel_m = travel_m * 1.25 + 0.05;
        turn_rad = turn_rad * 1.25 + 1e-3;
        let near_m = NEAR_RANGE_M + 2.0 * travel_m;
        let bearing_pad = 4.0 * r.bearing_sigma_rad;
        self.margin_rad = turn_rad + (travel_m / near_m).min(1.0).asin() + 1e-6;

        let mut rng = ChaCha8Rng::seed_from_u64(r.seed);
        rng.set_stream(BEARING_STREAM_BASE | rotation);
        self.candidates.clear();
        self.near.clear();
        let reach = r.radar.max_range_m() + travel_m;
        let mut found: Vec<usize> = Vec::new();
        r.grid
            .for_each_near([mid.x, mid.y], reach, |i| found.push(i));
        found.sort_unstable();
        match &r.occluders {
            Some(occluders) => occluders.gather([mid.x, mid.y], reach, &mut self.occluders),
            None => self.occluders.clear(),
        }
        for i in found {
            let Some(&p) = r.positions.get(i) else {
                continue;
            };
            let range_mid = (p[0] - mid.x).hypot(p[1] - mid.y);
            if range_mid > reach || super::occlusion::hidden([mid.x, mid.y], p, &self.occluders) {
                continue;
            }
            let apparent = if r.bearing_sigma_rad > 0.0 {
                let n: f64 = StandardNormal.sample(&mut rng);
                let delta = (n * r.bearing_sigma_rad).clamp(-bearing_pad, bearing_pad);
                rotate_about([mid.x, mid.y], p, delta)
            } else {
                p
            };
            let c = Candidate {
                bearing_mid: range_bearing(&mid, apparent).bearing_rad,
                index: i,
                apparent,
            };
            if range_mid < near_m {
                self.near.push(c);
            } else {
                self.candidates.push(c);
            }
        }
        self.candidates.sort_by(|a, b| {
            a.bearing_mid
                .total_cmp(&b.bearing_mid)
                .then(a.index.cmp(&b.index))
        });
        self.rotation = Some(rotation);
        Ok(())
    }
}

/// Rotates `p` about `centre` by `-delta` radians (counter-clockwise negative), which adds
/// `delta` to its bearing as eq. 4 measures it (clockwise).
fn rotate_about(centre: [f64; 2], p: [f64; 2], delta: f64) -> [f64; 2] {
    let (s, c) = (-delta).sin_cos();
    let dx = p[0] - centre[0];
    let dy = p[1] - centre[1];
    [centre[0] + c * dx - s * dy, centre[1] + s * dx + c * dy]
}

/// Visits the candidates (sorted by `bearing_mid` in (-pi, pi]) whose bearing lies within
/// `half` of `bearing`, across the +/-pi seam.
fn for_each_in_window(
    candidates: &[Candidate],
    bearing: f64,
    half: f64,
    mut visit: impl FnMut(&Candidate),
) {
    if half >= std::f64::consts::PI {
        candidates.iter().for_each(visit);
        return;
    }
    let lo = bearing - half;
    let hi = bearing + half;
    let range = |a: f64, b: f64, visit: &mut dyn FnMut(&Candidate)| {
        let start = candidates.partition_point(|c| c.bearing_mid < a);
        let end = candidates.partition_point(|c| c.bearing_mid <= b);
        if let Some(slice) = candidates.get(start..end.max(start)) {
            slice.iter().for_each(&mut *visit);
        }
    };
    let pi = std::f64::consts::PI;
    range(lo.max(-pi), hi.min(pi), &mut visit);
    if lo < -pi {
        range(lo + 2.0 * pi, pi, &mut visit);
    }
    if hi > pi {
        range(-pi, hi - 2.0 * pi, &mut visit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_finds_candidates_across_the_pi_seam() {
        let mk = |b: f64, i: usize| Candidate {
            bearing_mid: b,
            index: i,
            apparent: [0.0, 0.0],
        };
        let cands = vec![mk(-3.1, 0), mk(-1.0, 1), mk(0.0, 2), mk(3.1, 3)];
        let mut seen = Vec::new();
        for_each_in_window(&cands, 3.13, 0.1, |c| seen.push(c.index));
        seen.sort_unstable();
        assert_eq!(seen, vec![0, 3]);
    }

    #[test]
    fn rotating_a_point_adds_to_its_clockwise_bearing() {
        let pose = Pose2::new(1.0, 2.0, 0.3);
        let p = [11.0, 4.0];
        let before = range_bearing(&pose, p);
        let after = range_bearing(&pose, rotate_about([1.0, 2.0], p, 0.05));
        assert!((after.bearing_rad - before.bearing_rad - 0.05).abs() < 1e-12);
        assert!((after.range_m - before.range_m).abs() < 1e-12);
    }
}
