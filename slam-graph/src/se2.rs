//! Rigid transforms of the plane as the filter writes poses: `(x, y, theta)`, a frame's
//! origin and heading in its parent frame. `compose(a, b)` is `b` expressed in `a`'s parent;
//! `between(a, b)` is `b` expressed in `a`'s frame.

use nalgebra::{Matrix2, Matrix3, Vector2};
use radar_model::geometry::{wrap_angle, Pose2};

/// The rotation of heading `theta`.
pub fn rotation(theta: f64) -> Matrix2<f64> {
    let (s, c) = theta.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// `b` (given in `a`'s frame) expressed in `a`'s parent frame.
pub fn compose(a: &Pose2, b: &Pose2) -> Pose2 {
    a.compose(b)
}

/// The inverse transform: `a`'s parent expressed in `a`'s frame.
pub fn inverse(a: &Pose2) -> Pose2 {
    let t = rotation(a.theta).transpose() * Vector2::new(-a.x, -a.y);
    Pose2::new(t.x, t.y, wrap_angle(-a.theta))
}

/// `b` expressed in `a`'s frame (both given in the same parent).
pub fn between(a: &Pose2, b: &Pose2) -> Pose2 {
    compose(&inverse(a), b)
}

/// A point of `a`'s frame in `a`'s parent.
pub fn transform_point(a: &Pose2, p: [f64; 2]) -> [f64; 2] {
    let t = rotation(a.theta) * Vector2::new(p[0], p[1]);
    [a.x + t.x, a.y + t.y]
}

/// Jacobians of `compose(a, b)` with respect to `a` and to `b` (rows and columns x, y, theta):
/// [`Pose2::compose_jacobians`].
pub fn compose_jacobians(a: &Pose2, b: &Pose2) -> (Matrix3<f64>, Matrix3<f64>) {
    a.compose_jacobians(b)
}

/// Covariance of `compose(a, b)` for independent `a` (covariance `ca`) and `b` (`cb`).
pub fn compose_covariance(
    a: &Pose2,
    ca: &Matrix3<f64>,
    b: &Pose2,
    cb: &Matrix3<f64>,
) -> Matrix3<f64> {
    let (ja, jb) = compose_jacobians(a, b);
    let c = ja * ca * ja.transpose() + jb * cb * jb.transpose();
    0.5 * (c + c.transpose())
}

/// The residual of a relative measurement `z` of `b` in `a`'s frame, in `a`'s frame:
/// `[R_a^T (t_b - t_a) - z_t, wrap(theta_b - theta_a - z_theta)]`, with its Jacobians with
/// respect to `a` and `b`.
pub fn between_residual(
    a: &Pose2,
    b: &Pose2,
    z: &Pose2,
) -> (nalgebra::Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let (s, c) = a.theta.sin_cos();
    let d = Vector2::new(b.x - a.x, b.y - a.y);
    let rt = Matrix2::new(c, s, -s, c);
    let local = rt * d;
    let e = nalgebra::Vector3::new(
        local.x - z.x,
        local.y - z.y,
        wrap_angle(b.theta - a.theta - z.theta),
    );
    // d(R^T d)/d theta_a.
    let drt = Matrix2::new(-s, c, -c, -s) * d;
    let ja = Matrix3::new(-c, -s, drt.x, s, -c, drt.y, 0.0, 0.0, -1.0);
    let jb = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
    (e, ja, jb)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Pose2, b: &Pose2, tol: f64) -> bool {
        (a.x - b.x).abs() < tol
            && (a.y - b.y).abs() < tol
            && wrap_angle(a.theta - b.theta).abs() < tol
    }

    #[test]
    fn between_undoes_compose() {
        let a = Pose2::new(3.0, -2.0, 2.5);
        let b = Pose2::new(-1.0, 4.0, -3.0);
        assert!(close(&between(&a, &compose(&a, &b)), &b, 1e-12));
        assert!(close(
            &compose(&a, &inverse(&a)),
            &Pose2::new(0.0, 0.0, 0.0),
            1e-12
        ));
    }

    fn perturbed(p: &Pose2, k: usize, h: f64) -> Pose2 {
        let mut v = [p.x, p.y, p.theta];
        v[k] += h;
        Pose2::new(v[0], v[1], v[2])
    }

    #[test]
    fn residual_jacobians_match_finite_differences() {
        let a = Pose2::new(1.0, 2.0, 0.7);
        let b = Pose2::new(4.0, -1.0, -2.9);
        let z = Pose2::new(0.5, -3.0, 2.8);
        let (_, ja, jb) = between_residual(&a, &b, &z);
        let h = 1e-6;
        for k in 0..3 {
            let (ep, _, _) = between_residual(&perturbed(&a, k, h), &b, &z);
            let (em, _, _) = between_residual(&perturbed(&a, k, -h), &b, &z);
            let fd = (ep - em) / (2.0 * h);
            for r in 0..3 {
                assert!((fd[r] - ja[(r, k)]).abs() < 1e-7, "a: row {r} col {k}");
            }
            let (ep, _, _) = between_residual(&a, &perturbed(&b, k, h), &z);
            let (em, _, _) = between_residual(&a, &perturbed(&b, k, -h), &z);
            let fd = (ep - em) / (2.0 * h);
            for r in 0..3 {
                assert!((fd[r] - jb[(r, k)]).abs() < 1e-7, "b: row {r} col {k}");
            }
        }
    }

    #[test]
    fn compose_jacobians_match_finite_differences() {
        let a = Pose2::new(1.0, 2.0, 0.7);
        let b = Pose2::new(4.0, -1.0, 1.2);
        let (ja, jb) = compose_jacobians(&a, &b);
        let h = 1e-6;
        let v = |p: Pose2| nalgebra::Vector3::new(p.x, p.y, p.theta);
        for k in 0..3 {
            let fd = (v(compose(&perturbed(&a, k, h), &b)) - v(compose(&perturbed(&a, k, -h), &b)))
                / (2.0 * h);
            let fdb = (v(compose(&a, &perturbed(&b, k, h)))
                - v(compose(&a, &perturbed(&b, k, -h))))
                / (2.0 * h);
            for r in 0..3 {
                assert!((fd[r] - ja[(r, k)]).abs() < 1e-7);
                assert!((fdb[r] - jb[(r, k)]).abs() < 1e-7);
            }
        }
    }
}
