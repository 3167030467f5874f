//! Occlusion for the point-target renderer: opaque line objects (building fronts and walls,
//! which a scene without `[realism]` holds only when the `[city]` generator made them) hide
//! the features behind them. Decided once per rotation from the rotation's middle pose (the
//! vehicle moves about 2.5 m in a rotation at 10 m/s), as the realistic renderer decides
//! visibility; features exactly on an outline are not hidden by it.

use crate::index::GridIndex;
use crate::scene::objects::{ObjectKind, ObjectSpec};

/// The opaque segments of a scene, indexed by their midpoints.
#[derive(Debug, Clone)]
pub(crate) struct Occluders {
    segments: Vec<[[f64; 2]; 2]>,
    grid: GridIndex,
    /// Longest half-length: a segment reaching a disk has its midpoint within the disk's
    /// radius plus this.
    max_half_m: f64,
}

impl Occluders {
    /// The building fronts and walls among `objects`; `None` when there are none.
    pub(crate) fn new(objects: &[ObjectSpec]) -> Option<Occluders> {
        let segments: Vec<[[f64; 2]; 2]> = objects
            .iter()
            .filter(|o| matches!(o.kind, ObjectKind::BuildingFront | ObjectKind::Wall))
            .filter_map(|o| Some([o.from?, o.to?]))
            .filter(|[a, b]| a.iter().chain(b).all(|v| v.is_finite()))
            .collect();
        if segments.is_empty() {
            return None;
        }
        let mids: Vec<[f64; 2]> = segments
            .iter()
            .map(|[a, b]| [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])])
            .collect();
        let max_half_m = segments
            .iter()
            .map(|[a, b]| 0.5 * (b[0] - a[0]).hypot(b[1] - a[1]))
            .fold(0.0, f64::max);
        Some(Occluders {
            grid: GridIndex::new(&mids, (2.0 * max_half_m).clamp(10.0, 200.0)),
            segments,
            max_half_m,
        })
    }

    /// The segments that may cross a sight line from `centre` out to `reach_m`, into `out`.
    pub(crate) fn gather(&self, centre: [f64; 2], reach_m: f64, out: &mut Vec<[[f64; 2]; 2]>) {
        out.clear();
        self.grid
            .for_each_near(centre, reach_m + self.max_half_m, |i| {
                if let Some(s) = self.segments.get(i) {
                    out.push(*s);
                }
            });
    }
}

/// Whether the sight line from `eye` to `p` properly crosses one of `segments` (touching an
/// end or running along one does not count).
pub(crate) fn hidden(eye: [f64; 2], p: [f64; 2], segments: &[[[f64; 2]; 2]]) -> bool {
    segments.iter().any(|&[a, b]| crosses(eye, p, a, b))
}

fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Proper intersection of segments `p1 p2` and `q1 q2`.
fn crosses(p1: [f64; 2], p2: [f64; 2], q1: [f64; 2], q2: [f64; 2]) -> bool {
    let d1 = cross(q1, q2, p1);
    let d2 = cross(q1, q2, p2);
    let d3 = cross(p1, p2, q1);
    let d4 = cross(p1, p2, q2);
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_between_the_eye_and_a_point_hides_it_and_one_beside_the_line_does_not() {
        let wall = [[5.0, -1.0], [5.0, 1.0]];
        assert!(hidden([0.0, 0.0], [10.0, 0.0], &[wall]));
        assert!(!hidden([0.0, 0.0], [10.0, 3.0], &[wall]));
        // A point before the wall, or on its end, is seen.
        assert!(!hidden([0.0, 0.0], [4.0, 0.0], &[wall]));
        assert!(!hidden([0.0, 0.0], [5.0, 1.0], &[wall]));
    }
}
