//! Loop closures scored against the truth over every true revisit: pairs of submap frames
//! whose true origins lie within [`RevisitRule::within_m`] of each other after at least
//! [`RevisitRule::min_apart_m`] of driving between them (the definition of issue 35: within
//! 10 m, at least 300 m apart). Recall counts the revisiting frames (the later frame of at
//! least one such pair) whose place a correct closure joins to a true partner's: frame `i`
//! is where submap `i - 1` ended and submap `i` started, so both hold the place, and a
//! closure between submap `a` and submap `b` joins the pair `(i, j)` when `a` is `i - 1` or
//! `i` and `b` is `j - 1` or `j` (a street driven the other way is mapped by the submap
//! before the frame on one visit and after it on the other). Precision counts the closures
//! that agree with the truth. Pure arithmetic, no IO.

use radar_model::geometry::{wrap_angle, Pose2};

use crate::layer::LoopClosure;
use crate::se2::between;

/// What a true revisit is and when a closure is correct.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RevisitRule {
    /// True origins at most this far apart (m).
    pub within_m: f64,
    /// After at least this much driving (m).
    pub min_apart_m: f64,
    /// A closure is correct when its transform is within this of the truth (m)...
    pub correct_m: f64,
    /// ... and this (rad).
    pub correct_rad: f64,
}

impl Default for RevisitRule {
    fn default() -> Self {
        Self {
            within_m: 10.0,
            min_apart_m: 300.0,
            correct_m: 1.0,
            correct_rad: 2f64.to_radians(),
        }
    }
}

/// Closures over the true revisits.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RevisitScore {
    /// Pairs of frames that are true revisits.
    pub pairs: usize,
    /// Frames that revisit at least one earlier frame.
    pub revisiting: usize,
    /// Of which a correct closure joins to a true partner (the recall's numerator).
    pub closed: usize,
    /// Closures in the graph.
    pub closures: usize,
    /// Of which agree with the truth.
    pub correct: usize,
    /// Correct closures joining a revisiting frame's place to a true partner's.
    pub correct_on_revisits: usize,
    /// Closures (correct or not) that came from a place descriptor.
    pub from_place: usize,
}

impl RevisitScore {
    /// Closed revisiting frames over all revisiting frames (`None` without any).
    pub fn recall(&self) -> Option<f64> {
        (self.revisiting > 0).then(|| self.closed as f64 / self.revisiting as f64)
    }

    /// Correct closures over all closures (`None` without any).
    pub fn precision(&self) -> Option<f64> {
        (self.closures > 0).then(|| self.correct as f64 / self.closures as f64)
    }
}

/// Whether closure `l` agrees with the true frames.
pub fn is_correct(l: &LoopClosure, truth: &[Option<Pose2>], rule: &RevisitRule) -> Option<bool> {
    let (a, b) = (truth.get(l.from).copied()??, truth.get(l.to).copied()??);
    let t = between(&a, &b);
    Some(
        (t.x - l.transform.x).hypot(t.y - l.transform.y) <= rule.correct_m
            && wrap_angle(t.theta - l.transform.theta).abs() <= rule.correct_rad,
    )
}

/// Scores `loops` over the true frames (`truth[i]`: frame `i`'s true pose, `None` when
/// unknown), the vehicle's true position when each frame started (`origins[i]`: the same
/// as the frame's but for frame 0, the world's, where the vehicle may start elsewhere) and
/// the true distance driven to each frame (`driven_m[i]`).
pub fn score_revisits(
    loops: &[LoopClosure],
    truth: &[Option<Pose2>],
    origins: &[Option<[f64; 2]>],
    driven_m: &[f64],
    rule: &RevisitRule,
) -> RevisitScore {
    let n = origins.len().min(driven_m.len());
    let partners = |j: usize| {
        (0..j).filter(move |&i| {
            let (Some(a), Some(b)) = (origins[i], origins[j]) else {
                return false;
            };
            (a[0] - b[0]).hypot(a[1] - b[1]) <= rule.within_m
                && driven_m[j] - driven_m[i] >= rule.min_apart_m
        })
    };
    let holds = |frame: usize, submap: usize| submap == frame || submap + 1 == frame;
    tally(
        loops,
        truth,
        rule,
        n,
        |j| partners(j).collect(),
        |l, j, p| holds(j, l.to) && p.iter().any(|&i| holds(i, l.from)),
    )
}

/// Counts the revisits (`partners(j)`: the frames or submaps frame `j` revisits) and the
/// correct closures that join them (`joins(closure, j, partners)`).
fn tally(
    loops: &[LoopClosure],
    truth: &[Option<Pose2>],
    rule: &RevisitRule,
    frames: usize,
    partners: impl Fn(usize) -> Vec<usize>,
    joins: impl Fn(&LoopClosure, usize, &[usize]) -> bool,
) -> RevisitScore {
    let mut s = RevisitScore {
        closures: loops.len(),
        from_place: loops.iter().filter(|l| l.from_place).count(),
        ..RevisitScore::default()
    };
    let correct: Vec<&LoopClosure> = loops
        .iter()
        .filter(|l| is_correct(l, truth, rule) == Some(true))
        .collect();
    s.correct = correct.len();
    for j in 0..frames {
        let p = partners(j);
        if p.is_empty() {
            continue;
        }
        s.pairs += p.len();
        s.revisiting += 1;
        let joined = correct.iter().filter(|l| joins(l, j, &p)).count();
        tracing::debug!(submap = j, partners = ?p, closed = joined > 0, "a true revisit");
        s.correct_on_revisits += joined;
        if joined > 0 {
            s.closed += 1;
        }
    }
    s
}

/// One true pose of the drive for [`score_path_revisits`]: where the vehicle was, how far
/// it had driven, and in which submap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSample {
    /// True position (m).
    pub xy: [f64; 2],
    /// True distance driven (m).
    pub driven_m: f64,
    /// The submap the vehicle was mapping.
    pub submap: usize,
}

/// Scores `loops` over the revisits of the earlier *path*, not only of earlier frame
/// origins: frame `j` revisits submap `i` when `j`'s true origin lies within
/// [`RevisitRule::within_m`] of the true path driven in submap `i`, at least
/// [`RevisitRule::min_apart_m`] of driving before (frames are 100 m apart along the route,
/// so a second pass rarely starts a frame where the first did; this counts every return).
/// A correct closure joins the revisit when it links submap `j - 1` or `j` (both hold
/// frame `j`'s place) to a submap `i` whose path passed within reach.
/// Arguments as [`score_revisits`], with `path` the true drive.
pub fn score_path_revisits(
    loops: &[LoopClosure],
    truth: &[Option<Pose2>],
    origins: &[Option<[f64; 2]>],
    driven_m: &[f64],
    path: &[PathSample],
    rule: &RevisitRule,
) -> RevisitScore {
    let n = origins.len().min(driven_m.len());
    let partners = |j: usize| -> Vec<usize> {
        let Some(o) = origins[j] else {
            return Vec::new();
        };
        let mut p: Vec<usize> = path
            .iter()
            .filter(|q| {
                q.submap < j
                    && driven_m[j] - q.driven_m >= rule.min_apart_m
                    && (q.xy[0] - o[0]).hypot(q.xy[1] - o[1]) <= rule.within_m
            })
            .map(|q| q.submap)
            .collect();
        p.sort_unstable();
        p.dedup();
        p
    };
    let holds_new = |submap: usize, j: usize| submap == j || submap + 1 == j;
    tally(loops, truth, rule, n, partners, |l, j, p| {
        holds_new(l.to, j) && p.contains(&l.from)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    fn closure(from: usize, to: usize, transform: Pose2) -> LoopClosure {
        LoopClosure {
            from,
            to,
            transform,
            covariance: Matrix3::identity(),
            matches: 10,
            nis: 1.0,
            dof: 17,
            rival_matches: 0,
            from_place: false,
        }
    }

    #[test]
    fn revisits_recall_and_precision_are_counted_from_the_truth() {
        // Frames 0..5 along x every 100 m, then 6 back at frame 1 (7 m off), 7 at frame 0.
        let mut truth: Vec<Option<Pose2>> = (0..6)
            .map(|i| Some(Pose2::new(100.0 * i as f64, 0.0, 0.0)))
            .collect();
        truth.push(Some(Pose2::new(100.0, 7.0, std::f64::consts::PI)));
        truth.push(Some(Pose2::new(0.0, 0.0, std::f64::consts::PI)));
        let driven: Vec<f64> = (0..8).map(|i| 100.0 * i as f64).collect();
        let rule = RevisitRule::default();
        let right = between(&truth[1].unwrap(), &truth[6].unwrap());
        let loops = [
            closure(1, 6, right),
            // Wrong by 3 m.
            closure(0, 7, Pose2::new(3.0, 0.0, std::f64::consts::PI)),
        ];
        let origins: Vec<Option<[f64; 2]>> = truth.iter().map(|t| t.map(|p| [p.x, p.y])).collect();
        let s = score_revisits(&loops, &truth, &origins, &driven, &rule);
        // 6 revisits 1 (500 m driven), 7 revisits 0 (700 m); 7 and 1 are 100 m apart.
        assert_eq!((s.pairs, s.revisiting), (2, 2));
        assert_eq!((s.closed, s.closures, s.correct), (1, 2, 1));
        assert_eq!(s.recall(), Some(0.5));
        assert_eq!(s.precision(), Some(0.5));
        // Submap 0 ends at frame 1 and submap 5 at frame 6: a correct closure between them
        // joins the same place.
        let beside = [closure(
            0,
            5,
            between(&truth[0].unwrap(), &truth[5].unwrap()),
        )];
        let s = score_revisits(&beside, &truth, &origins, &driven, &rule);
        assert_eq!((s.closed, s.correct, s.precision()), (1, 1, Some(1.0)));
        // Along the path: frame 6's origin (100, 7) lies within 10 m of the path driven in
        // submap 1 (from x = 100 to 200) and submap 0 (ending at x = 100).
        let path: Vec<PathSample> = (0..60)
            .map(|k| PathSample {
                xy: [10.0 * k as f64, 0.0],
                driven_m: 10.0 * k as f64,
                submap: k / 10,
            })
            .collect();
        let s = score_path_revisits(&loops, &truth, &origins, &driven, &path, &rule);
        assert_eq!((s.revisiting, s.closed, s.correct), (2, 1, 1));
        // Too little driving between them: no revisit.
        let short: Vec<f64> = (0..8).map(|i| 10.0 * i as f64).collect();
        let s = score_revisits(&loops, &truth, &origins, &short, &rule);
        assert_eq!((s.pairs, s.recall()), (0, None));
    }
}
