//! Where a city's route comes back to streets it has already driven, from the layout alone
//! (no trajectory, no rendering): the route as a sequence of street edges (junction to
//! adjacent junction), and each run of consecutive edges that were driven before, with the
//! direction and the driving since.
//!
//! IO: none.

use super::CityLayout;

/// One run of consecutive street edges of the route that were driven earlier.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StreetReturn {
    /// Distance along the route (junction to junction) where the run starts, metres.
    pub at_m: f64,
    /// Its length, metres.
    pub length_m: f64,
    /// Edges in the run.
    pub edges: usize,
    /// The least driving between an edge of the run and the last time that edge was
    /// driven (end of the earlier pass to the start of this one), metres.
    pub driven_since_m: f64,
    /// Whether the run's first edge is driven the other way than the last time.
    pub opposite: bool,
    /// Where the run starts, world metres.
    pub from: [f64; 2],
}

/// One edge of the route: junction `a` to the adjacent junction `b` (column, row).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Edge {
    a: [i64; 2],
    b: [i64; 2],
}

impl CityLayout {
    /// The route's street edges in driving order, with the distance along the route at
    /// each edge's start.
    fn route_edges(&self) -> Vec<(Edge, f64)> {
        let [px, py] = self.pitch_m;
        let junction = |p: [f64; 2]| [(p[0] / px).round() as i64, (p[1] / py).round() as i64];
        let mut out = Vec::new();
        let mut along = 0.0;
        for w in self.route_corners.windows(2) {
            let (a, b) = (junction(w[0]), junction(w[1]));
            let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs());
            let dir = [(b[0] - a[0]).signum(), (b[1] - a[1]).signum()];
            let step_m = if dir[0] != 0 { px } else { py };
            let mut at = a;
            for _ in 0..steps {
                let next = [at[0] + dir[0], at[1] + dir[1]];
                out.push((Edge { a: at, b: next }, along));
                along += step_m;
                at = next;
            }
        }
        out
    }

    /// Junctions the route passes (turning or straight on), its ends included.
    pub fn route_junctions(&self) -> usize {
        self.route_edges().len() + usize::from(!self.route_corners.is_empty())
    }

    /// Every return of the route to streets it drove before (see [`StreetReturn`]).
    pub fn street_returns(&self) -> Vec<StreetReturn> {
        let edges = self.route_edges();
        let [px, py] = self.pitch_m;
        let len = |e: &Edge| if e.a[1] == e.b[1] { px } else { py };
        // For each edge, the last earlier pass over the same street edge (either way).
        let earlier: Vec<Option<(usize, bool)>> = edges
            .iter()
            .enumerate()
            .map(|(k, (e, _))| {
                edges[..k]
                    .iter()
                    .rposition(|(f, _)| (f.a == e.a && f.b == e.b) || (f.a == e.b && f.b == e.a))
                    .map(|j| (j, edges[j].0.a == e.b))
            })
            .collect();
        let mut out: Vec<StreetReturn> = Vec::new();
        let mut k = 0;
        while k < edges.len() {
            let Some((j, opposite)) = earlier[k] else {
                k += 1;
                continue;
            };
            let (e, at_m) = edges[k];
            let mut run = StreetReturn {
                at_m,
                length_m: 0.0,
                edges: 0,
                driven_since_m: f64::INFINITY,
                opposite,
                from: [e.a[0] as f64 * px, e.a[1] as f64 * py],
            };
            let mut last = Some(j);
            while let (Some((e, at)), Some(j)) = (edges.get(k), last) {
                let (f, f_at) = edges[j];
                run.driven_since_m = run.driven_since_m.min(at - (f_at + len(&f)));
                run.length_m += len(e);
                run.edges += 1;
                k += 1;
                last = earlier.get(k).copied().flatten().map(|(j, _)| j);
            }
            out.push(run);
        }
        out
    }
}
