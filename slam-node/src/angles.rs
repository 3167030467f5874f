//! Angle helpers shared by the daemon's stages.

use std::f64::consts::{PI, TAU};

/// Wraps an angle to (-pi, pi]. Non-finite input is returned unchanged (callers reject it).
pub fn wrap_angle(angle_rad: f64) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let mut a = angle_rad.rem_euclid(TAU);
    if a > PI {
        a -= TAU;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_lands_in_minus_pi_exclusive_to_pi_inclusive() {
        assert!((wrap_angle(PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!(wrap_angle(f64::NAN).is_nan());
    }
}
