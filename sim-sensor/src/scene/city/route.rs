//! The city's route and its control schedule.
//!
//! The route (legs of whole blocks along the grid's streets) becomes a reference path along
//! the street centre lines with each 90 degree corner rounded by a circular arc of
//! `turn_radius_m`. A path-following controller then drives the bicycle model along it,
//! integrated exactly as the simulator integrates the schedule (10 ms steps, controls
//! interpolated linearly between keyframes every `control_step_s`), and its commands become
//! the keyframes:
//!
//! - speed: `cruise_mps` on the straights, `turn_mps` through the arcs, braking at
//!   `decel_mps2` before each arc and to a stop at the last junction, accelerating at
//!   `accel_mps2`;
//! - steering: the path's curvature previewed half a steering ramp ahead
//!   (`atan(wheelbase x curvature)`), plus feedback on the heading error `psi` and the lateral
//!   error `e`, `-(2 L / D) psi - (L / D^2) e` with `D = 6 m` (critically damped with a
//!   settling distance of about `D` at any speed), limited to `max_steer_rad` and to
//!   `steer_rate_rad_s`.
//!
//! The generator refuses a route the controller leaves the carriageway on (a lateral error
//! over `carriageway_half_m - 1 m`).

use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::{ControlInput, MotionModel};

use super::{invalid, CitySpec};
use crate::error::SceneError;
use crate::schedule::{ControlKey, STEP_NS};

/// Settling distance of the steering feedback, metres.
const SETTLE_M: f64 = 6.0;

/// Parses the route into the junctions where it turns (with its two ends), world metres.
pub(super) fn parse_route(spec: &CitySpec) -> Result<Vec<[f64; 2]>, SceneError> {
    let [px, py] = spec.pitch_m();
    let mut at = [i64::from(spec.start[0]), i64::from(spec.start[1])];
    let mut corners = vec![at];
    let mut last_dir: Option<[i64; 2]> = None;
    for (k, leg) in spec.route.iter().enumerate() {
        let field = format!("route[{k}]");
        let leg = leg.trim();
        let mut chars = leg.chars();
        let dir = match chars.next().map(|c| c.to_ascii_uppercase()) {
            Some('E') => [1, 0],
            Some('W') => [-1, 0],
            Some('N') => [0, 1],
            Some('S') => [0, -1],
            _ => {
                return Err(invalid(
                    &field,
                    format!("{leg:?}: a leg is E, N, W or S and a number of blocks, e.g. \"E3\""),
                ))
            }
        };
        let blocks: i64 = match chars.as_str().parse::<u32>() {
            Ok(n) if (1..=super::MAX_BLOCKS).contains(&n) => i64::from(n),
            _ => {
                return Err(invalid(
                    &field,
                    format!(
                        "{leg:?}: the number of blocks must be in [1, {}]",
                        super::MAX_BLOCKS
                    ),
                ))
            }
        };
        if last_dir == Some([-dir[0], -dir[1]]) {
            return Err(invalid(
                &field,
                format!("{leg:?} turns back on the previous leg (no U-turns)"),
            ));
        }
        at = [at[0] + dir[0] * blocks, at[1] + dir[1] * blocks];
        if !(0..=i64::from(spec.blocks_x)).contains(&at[0])
            || !(0..=i64::from(spec.blocks_y)).contains(&at[1])
        {
            return Err(invalid(
                &field,
                format!(
                    "{leg:?} leaves the grid: junction {at:?} is outside [0, {}] x [0, {}]",
                    spec.blocks_x, spec.blocks_y
                ),
            ));
        }
        if last_dir == Some(dir) {
            // Straight on: extend the previous leg.
            if let Some(end) = corners.last_mut() {
                *end = at;
            }
        } else {
            corners.push(at);
        }
        last_dir = Some(dir);
    }
    Ok(corners
        .into_iter()
        .map(|[i, j]| [i as f64 * px, j as f64 * py])
        .collect())
}

/// A piece of the reference path.
#[derive(Debug, Clone, Copy)]
enum Piece {
    /// A straight from `a` along unit `dir` for `len` metres.
    Line {
        a: [f64; 2],
        dir: [f64; 2],
        len: f64,
    },
    /// An arc about `c` of radius `r` from angle `a0`, turning `sweep` (positive: left).
    Arc {
        c: [f64; 2],
        r: f64,
        a0: f64,
        sweep: f64,
    },
}

impl Piece {
    fn len(&self) -> f64 {
        match *self {
            Piece::Line { len, .. } => len,
            Piece::Arc { r, sweep, .. } => r * sweep.abs(),
        }
    }

    fn curvature(&self) -> f64 {
        match *self {
            Piece::Line { .. } => 0.0,
            Piece::Arc { r, sweep, .. } => sweep.signum() / r,
        }
    }

    /// Point and heading `u` metres along the piece.
    fn at(&self, u: f64) -> ([f64; 2], f64) {
        match *self {
            Piece::Line { a, dir, .. } => {
                ([a[0] + u * dir[0], a[1] + u * dir[1]], dir[1].atan2(dir[0]))
            }
            Piece::Arc { c, r, a0, sweep } => {
                let sign = sweep.signum();
                let phi = a0 + sign * u / r;
                (
                    [c[0] + r * phi.cos(), c[1] + r * phi.sin()],
                    phi + sign * std::f64::consts::FRAC_PI_2,
                )
            }
        }
    }

    /// The distance along the piece of the point nearest `p` (clamped to the piece).
    fn project(&self, p: [f64; 2]) -> f64 {
        match *self {
            Piece::Line { a, dir, len } => {
                ((p[0] - a[0]) * dir[0] + (p[1] - a[1]) * dir[1]).clamp(0.0, len)
            }
            Piece::Arc { c, r, a0, sweep } => {
                let phi = (p[1] - c[1]).atan2(p[0] - c[0]);
                let t = wrap_angle(phi - a0) * sweep.signum();
                // Past either end (within half a turn): the nearer end.
                let span = sweep.abs();
                let t = if t < 0.0 || t > span {
                    let to_start = wrap_angle(t).abs();
                    let to_end = wrap_angle(t - span).abs();
                    if to_start <= to_end {
                        0.0
                    } else {
                        span
                    }
                } else {
                    t
                };
                t * r
            }
        }
    }
}

/// The reference path: pieces with their start distances.
struct Path {
    pieces: Vec<Piece>,
    starts: Vec<f64>,
    length: f64,
}

impl Path {
    fn new(corners: &[[f64; 2]], radius: f64) -> Path {
        let mut pieces = Vec::new();
        let unit = |a: [f64; 2], b: [f64; 2]| {
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            [(b[0] - a[0]) / len, (b[1] - a[1]) / len]
        };
        let mut from = corners.first().copied().unwrap_or_default();
        for k in 1..corners.len() {
            let v = corners[k];
            let d_in = unit(corners[k - 1], v);
            let (to, arc) = match corners.get(k + 1) {
                Some(&next) => {
                    let d_out = unit(v, next);
                    let sign = (d_in[0] * d_out[1] - d_in[1] * d_out[0]).signum();
                    let t1 = [v[0] - radius * d_in[0], v[1] - radius * d_in[1]];
                    let left = [-d_in[1], d_in[0]];
                    let c = [
                        t1[0] + sign * radius * left[0],
                        t1[1] + sign * radius * left[1],
                    ];
                    let a0 = (t1[1] - c[1]).atan2(t1[0] - c[0]);
                    let arc = Piece::Arc {
                        c,
                        r: radius,
                        a0,
                        sweep: sign * std::f64::consts::FRAC_PI_2,
                    };
                    (
                        t1,
                        Some((arc, [v[0] + radius * d_out[0], v[1] + radius * d_out[1]])),
                    )
                }
                None => (v, None),
            };
            let len = (to[0] - from[0]).hypot(to[1] - from[1]);
            if len > 1e-9 {
                pieces.push(Piece::Line {
                    a: from,
                    dir: d_in,
                    len,
                });
            }
            if let Some((arc, exit)) = arc {
                pieces.push(arc);
                from = exit;
            }
        }
        let mut starts = Vec::with_capacity(pieces.len());
        let mut s = 0.0;
        for p in &pieces {
            starts.push(s);
            s += p.len();
        }
        Path {
            pieces,
            starts,
            length: s,
        }
    }

    /// The piece holding distance `s` and the distance into it.
    fn piece_at(&self, s: f64) -> Option<(usize, f64)> {
        if self.pieces.is_empty() {
            return None;
        }
        let k = self.starts.partition_point(|&start| start <= s).max(1) - 1;
        let start = self.starts.get(k).copied()?;
        Some((k, (s - start).max(0.0)))
    }

    fn curvature_at(&self, s: f64) -> f64 {
        self.piece_at(s)
            .and_then(|(k, _)| self.pieces.get(k))
            .map_or(0.0, |p| if s > self.length { 0.0 } else { p.curvature() })
    }

    /// The nearest point to `p` among the pieces near `hint` (so that a street driven twice
    /// is not confused with its later visit): its piece, distance `s`, lateral error (left
    /// positive) and heading.
    fn locate(&self, p: [f64; 2], hint: usize) -> Option<(usize, f64, f64, f64)> {
        let lo = hint.saturating_sub(1);
        let hi = (hint + 3).min(self.pieces.len());
        let mut best: Option<(f64, usize, f64, f64, f64)> = None;
        for k in lo..hi {
            let piece = self.pieces.get(k)?;
            let u = piece.project(p);
            let (foot, heading) = piece.at(u);
            let d = (p[0] - foot[0]).hypot(p[1] - foot[1]);
            let e = heading.cos() * (p[1] - foot[1]) - heading.sin() * (p[0] - foot[0]);
            if best.is_none_or(|b| d < b.0 - 1e-9) {
                best = Some((d, k, self.starts.get(k)? + u, e, heading));
            }
        }
        best.map(|(_, k, s, e, h)| (k, s, e, h))
    }
}

/// The drive the controller made.
pub(super) struct Drive {
    pub start: [f64; 3],
    pub keys: Vec<ControlKey>,
    pub path_length_m: f64,
    pub duration_s: f64,
}

/// Drives the route: the keyframes of a controller following the reference path.
pub(super) fn drive(
    spec: &CitySpec,
    corners: &[[f64; 2]],
    wheelbase_m: f64,
) -> Result<Drive, SceneError> {
    let path = Path::new(corners, spec.turn_radius_m);
    let start_xy = corners.first().copied().unwrap_or_default();
    let theta0 = path.pieces.first().map_or(0.0, |p| p.at(0.0).1);
    let start = [start_xy[0], start_xy[1], theta0];
    let mut keys = vec![ControlKey {
        t_s: 0.0,
        speed_mps: 0.0,
        steer_rad: 0.0,
    }];
    if path.pieces.is_empty() {
        return Ok(Drive {
            start,
            keys,
            path_length_m: 0.0,
            duration_s: 0.0,
        });
    }
    let model = MotionModel::Bicycle { wheelbase_m };
    let dt = spec.control_step_s;
    let sub_steps = (dt * 1e9 / STEP_NS as f64).round() as u64;
    let step_s = STEP_NS as f64 * 1e-9;
    let arcs: Vec<(f64, f64)> = path
        .pieces
        .iter()
        .zip(&path.starts)
        .filter(|(p, _)| matches!(p, Piece::Arc { .. }))
        .map(|(p, &s)| (s, s + p.len()))
        .collect();
    let (v_turn, v_cruise) = (spec.turn_mps, spec.cruise_mps);
    let brake = spec.decel_mps2;
    let speed_limit = |s: f64| -> f64 {
        let mut v = v_cruise.min((2.0 * brake * (path.length - s).max(0.0)).sqrt());
        for &(a, b) in &arcs {
            if b < s {
                continue;
            }
            if a - s > (v_cruise * v_cruise) / (2.0 * brake) + 1.0 {
                break;
            }
            v = v.min(if s >= a {
                v_turn
            } else {
                (v_turn * v_turn + 2.0 * brake * (a - s)).sqrt()
            });
        }
        v
    };
    let steer_max = spec.max_steer_rad;
    let preview_s = 0.5 * (wheelbase_m / spec.turn_radius_m).atan() / spec.steer_rate_rad_s + dt;
    let (k_psi, k_e) = (
        2.0 * wheelbase_m / SETTLE_M,
        wheelbase_m / (SETTLE_M * SETTLE_M),
    );
    let mut pose = Pose2::new(start[0], start[1], start[2]);
    let (mut v, mut steer) = (0.0_f64, 0.0_f64);
    let mut hint = 0usize;
    let mut t = 0.0_f64;
    let max_keys = ((path.length / v_turn.min(1.0) + 600.0) / dt).ceil() as usize;
    let rate_step = spec.steer_rate_rad_s * dt;
    loop {
        let (k, s, e, heading) = path
            .locate([pose.x, pose.y], hint)
            .ok_or_else(|| invalid("route", "the path has no pieces".into()))?;
        hint = k;
        if e.abs() > spec.carriageway_half_m - 1.0 {
            return Err(invalid(
                "route",
                format!(
                    "the vehicle leaves the carriageway ({e:.2} m off the centre line at {:.0} m along the route, t = {t:.1} s): lower turn_mps or raise turn_radius_m, max_steer_rad or steer_rate_rad_s",
                    s
                ),
            ));
        }
        let remaining = path.length - s;
        let (v_next, done) = if remaining < 0.3 {
            (0.0, true)
        } else {
            let limit = speed_limit(s + v * dt);
            let next = limit.min(v + spec.accel_mps2 * dt).max(0.0);
            // Creeping the last metres at walking pace rather than stalling short.
            (next.max(0.3), false)
        };
        let psi = wrap_angle(pose.theta - heading);
        let kappa = path.curvature_at(s + v.max(1.0) * preview_s);
        let want = (wheelbase_m * kappa).atan() - k_psi * psi - (k_e * e).atan();
        let want = if done { steer } else { want };
        let steer_next = want
            .clamp(steer - rate_step, steer + rate_step)
            .clamp(-steer_max, steer_max);
        let t_next = (keys.len() as f64) * dt;
        // Integrate this interval exactly as the schedule will be (linear interpolation).
        for j in 0..sub_steps {
            let w = j as f64 / sub_steps as f64;
            let input = ControlInput::new(v + w * (v_next - v), steer + w * (steer_next - steer));
            pose = model.predict(&pose, &input, step_s).map_err(|err| {
                invalid("route", format!("the motion model refused a step: {err}"))
            })?;
        }
        keys.push(ControlKey {
            t_s: t_next,
            speed_mps: v_next,
            steer_rad: steer_next,
        });
        t = t_next;
        v = v_next;
        steer = steer_next;
        if done {
            break;
        }
        if keys.len() > max_keys {
            return Err(invalid(
                "route",
                format!("the controller did not finish the route within {max_keys} keyframes"),
            ));
        }
    }
    Ok(Drive {
        start,
        keys,
        path_length_m: path.length,
        duration_s: t,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_route_is_four_straights_joined_by_four_quarter_arcs_but_the_last() {
        let corners = [
            [0.0, 0.0],
            [100.0, 0.0],
            [100.0, 80.0],
            [0.0, 80.0],
            [0.0, 0.0],
        ];
        let path = Path::new(&corners, 8.0);
        let arcs = path
            .pieces
            .iter()
            .filter(|p| matches!(p, Piece::Arc { .. }))
            .count();
        assert_eq!(arcs, 3);
        let expected = 360.0 - 3.0 * 2.0 * 8.0 + 3.0 * 8.0 * std::f64::consts::FRAC_PI_2;
        assert!((path.length - expected).abs() < 1e-9, "{}", path.length);
        // Continuity: each piece starts where the previous ended, with the same heading.
        for w in path.pieces.windows(2) {
            let (end, h_end) = w[0].at(w[0].len());
            let (start, h_start) = w[1].at(0.0);
            assert!((end[0] - start[0]).hypot(end[1] - start[1]) < 1e-9);
            assert!(wrap_angle(h_end - h_start).abs() < 1e-9);
        }
    }

    #[test]
    fn a_point_left_of_the_path_has_a_positive_lateral_error() {
        let path = Path::new(&[[0.0, 0.0], [50.0, 0.0], [50.0, -50.0]], 8.0);
        let (_, s, e, _) = path.locate([10.0, 1.5], 0).expect("located");
        assert!((s - 10.0).abs() < 1e-9 && (e - 1.5).abs() < 1e-9);
        // On the right turn's arc, outside the arc is left of the path.
        let (k, _, e, _) = path.locate([50.0, 0.0], 1).expect("located");
        assert_eq!(k, 1);
        assert!(e > 0.0, "{e}");
    }
}
