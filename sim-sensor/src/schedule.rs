//! The vehicle's control schedule: speed and steering as functions of time.

use serde::Deserialize;

use crate::error::SceneError;

/// The trajectory's integration step, nanoseconds (10 ms): the schedule's controls are
/// sampled on this grid.
pub const STEP_NS: u64 = 10_000_000;

/// One keyframe: from `t_s` (seconds after the start) the vehicle is driven at
/// `speed_mps` with steering `steer_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlKey {
    /// Seconds after the scene's start.
    pub t_s: f64,
    /// Forward speed, metres a second.
    pub speed_mps: f64,
    /// Steering input, radians, interpreted by the scene's motion model.
    pub steer_rad: f64,
}

/// How controls vary between keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Each keyframe's controls hold until the next keyframe (a zero-order hold).
    #[default]
    Hold,
    /// Linear between keyframes.
    Linear,
}

/// Speed and steering over time. Before the first keyframe the vehicle stands still;
/// after the last one its controls hold.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlSchedule {
    keys: Vec<ControlKey>,
    interpolation: Interpolation,
}

impl ControlSchedule {
    /// A vehicle that never moves.
    pub fn stationary() -> Self {
        Self {
            keys: Vec::new(),
            interpolation: Interpolation::Hold,
        }
    }

    /// Validates keyframes: finite values, strictly increasing times from `t_s >= 0`.
    pub fn new(keys: Vec<ControlKey>, interpolation: Interpolation) -> Result<Self, SceneError> {
        let mut last_t = f64::NEG_INFINITY;
        for (i, key) in keys.iter().enumerate() {
            let field = |name: &str| format!("control[{i}].{name}");
            if !(key.t_s.is_finite() && key.t_s >= 0.0) {
                return Err(SceneError::Invalid {
                    field: field("t_s"),
                    reason: format!("must be finite and >= 0, got {}", key.t_s),
                });
            }
            if key.t_s <= last_t {
                return Err(SceneError::Invalid {
                    field: field("t_s"),
                    reason: format!("must be greater than the previous keyframe's {last_t}"),
                });
            }
            if !key.speed_mps.is_finite() || key.speed_mps.abs() > 100.0 {
                return Err(SceneError::Invalid {
                    field: field("speed_mps"),
                    reason: format!(
                        "must be finite and within +/-100 m/s, got {}",
                        key.speed_mps
                    ),
                });
            }
            if !key.steer_rad.is_finite() || key.steer_rad.abs() > 1.5 {
                return Err(SceneError::Invalid {
                    field: field("steer_rad"),
                    reason: format!(
                        "must be finite and within +/-1.5 rad, got {}",
                        key.steer_rad
                    ),
                });
            }
            last_t = key.t_s;
        }
        Ok(Self {
            keys,
            interpolation,
        })
    }

    /// The same schedule with every steering input negated (the vehicle turns the other way).
    pub fn with_steer_negated(&self) -> Self {
        Self {
            keys: self
                .keys
                .iter()
                .map(|k| ControlKey {
                    steer_rad: -k.steer_rad,
                    ..*k
                })
                .collect(),
            interpolation: self.interpolation,
        }
    }

    /// The keyframes.
    pub fn keys(&self) -> &[ControlKey] {
        &self.keys
    }

    /// Time of the last keyframe (0 for an empty schedule).
    pub fn last_key_s(&self) -> f64 {
        self.keys.last().map_or(0.0, |k| k.t_s)
    }

    /// `(speed_mps, steer_rad)` at `t_s` seconds after the start.
    pub fn controls_at(&self, t_s: f64) -> (f64, f64) {
        let next = self.keys.partition_point(|k| k.t_s <= t_s);
        if next == 0 {
            return (0.0, 0.0);
        }
        let Some(key) = self.keys.get(next - 1) else {
            return (0.0, 0.0);
        };
        match (self.interpolation, self.keys.get(next)) {
            (Interpolation::Linear, Some(after)) => {
                let w = (t_s - key.t_s) / (after.t_s - key.t_s);
                (
                    key.speed_mps + w * (after.speed_mps - key.speed_mps),
                    key.steer_rad + w * (after.steer_rad - key.steer_rad),
                )
            }
            _ => (key.speed_mps, key.steer_rad),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t_s: f64, speed_mps: f64, steer_rad: f64) -> ControlKey {
        ControlKey {
            t_s,
            speed_mps,
            steer_rad,
        }
    }

    #[test]
    fn a_held_schedule_keeps_each_keyframe_until_the_next() {
        let s = ControlSchedule::new(
            vec![key(1.0, 2.0, 0.1), key(3.0, 4.0, -0.1)],
            Interpolation::Hold,
        )
        .expect("valid");
        assert_eq!(s.controls_at(0.5), (0.0, 0.0));
        assert_eq!(s.controls_at(1.0), (2.0, 0.1));
        assert_eq!(s.controls_at(2.999), (2.0, 0.1));
        assert_eq!(s.controls_at(3.0), (4.0, -0.1));
        assert_eq!(s.controls_at(1e6), (4.0, -0.1));
    }

    #[test]
    fn a_linear_schedule_interpolates_between_keyframes() {
        let s = ControlSchedule::new(
            vec![key(0.0, 0.0, 0.0), key(2.0, 4.0, 0.2)],
            Interpolation::Linear,
        )
        .expect("valid");
        let (v, a) = s.controls_at(0.5);
        assert!((v - 1.0).abs() < 1e-12 && (a - 0.05).abs() < 1e-12);
        assert_eq!(s.controls_at(5.0), (4.0, 0.2));
    }

    #[test]
    fn keyframes_out_of_order_are_rejected_with_their_index() {
        let err = ControlSchedule::new(
            vec![key(1.0, 1.0, 0.0), key(1.0, 1.0, 0.0)],
            Interpolation::Hold,
        )
        .expect_err("duplicate time");
        assert!(err.to_string().contains("control[1].t_s"), "{err}");
    }

    #[test]
    fn non_finite_controls_are_rejected() {
        assert!(ControlSchedule::new(vec![key(0.0, f64::NAN, 0.0)], Interpolation::Hold).is_err());
        assert!(ControlSchedule::new(vec![key(0.0, 1.0, 2.0)], Interpolation::Hold).is_err());
    }
}
