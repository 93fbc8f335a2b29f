//! SO(3) and SE(3) in one place: hat, exp, log, Jacobians.
//!
//! Poses are [`Isometry3<f64>`] read as a transform *from* one frame *to* another: `T_21` maps
//! a point expressed in frame 1 into frame 2, `x2 = R x1 + t`. Tangent vectors of SE(3) are
//! ordered translation first, `xi = (rho, phi)`, as in Sophus. Every estimator in vofront
//! perturbs a pose on the left, `T <- exp(delta) T`, so the derivative of a transformed point
//! `p' = T p` with respect to `delta` at zero is `[I | -hat(p')]` ([`point_jacobian`]).

use nalgebra::{
    Isometry3, Matrix3, Matrix3x6, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3,
    Vector6,
};

/// Below this angle (radians) series expansions replace the closed forms.
const SMALL_ANGLE: f64 = 1e-6;

/// The skew-symmetric matrix with `hat(v) w = v x w`.
pub fn hat(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// SO(3) exponential: the rotation by `|phi|` radians about `phi / |phi|` (Rodrigues).
pub fn so3_exp(phi: &Vector3<f64>) -> Rotation3<f64> {
    Rotation3::new(*phi)
}

/// SO(3) logarithm: the rotation vector `phi` with `so3_exp(phi) = r`, `|phi| <= pi`.
pub fn so3_log(r: &Rotation3<f64>) -> Vector3<f64> {
    r.scaled_axis()
}

/// Left Jacobian of SO(3), `J_l(phi) = I + (1 - cos a)/a^2 hat(phi) + (a - sin a)/a^3 hat(phi)^2`
/// with `a = |phi|`. It maps `rho` to the translation of `exp((rho, phi))`.
pub fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let a = phi.norm();
    let w = hat(phi);
    if a < SMALL_ANGLE {
        return Matrix3::identity() + 0.5 * w + w * w / 6.0;
    }
    let a2 = a * a;
    Matrix3::identity() + (1.0 - a.cos()) / a2 * w + (a - a.sin()) / (a2 * a) * w * w
}

/// Inverse of [`so3_left_jacobian`]:
/// `I - hat(phi)/2 + (1/a^2 - (1 + cos a) / (2 a sin a)) hat(phi)^2`.
pub fn so3_left_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let a = phi.norm();
    let w = hat(phi);
    if a < SMALL_ANGLE {
        return Matrix3::identity() - 0.5 * w + w * w / 12.0;
    }
    let coeff = 1.0 / (a * a) - (1.0 + a.cos()) / (2.0 * a * a.sin());
    Matrix3::identity() - 0.5 * w + coeff * w * w
}

/// SE(3) exponential of `xi = (rho, phi)`: `R = exp(phi)`, `t = J_l(phi) rho`.
pub fn se3_exp(xi: &Vector6<f64>) -> Isometry3<f64> {
    let rho = xi.fixed_rows::<3>(0).into_owned();
    let phi = xi.fixed_rows::<3>(3).into_owned();
    let t = so3_left_jacobian(&phi) * rho;
    Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&so3_exp(&phi)),
    )
}

/// SE(3) logarithm, the inverse of [`se3_exp`]: `phi = log(R)`, `rho = J_l(phi)^-1 t`.
pub fn se3_log(t: &Isometry3<f64>) -> Vector6<f64> {
    let phi = t.rotation.scaled_axis();
    let rho = so3_left_jacobian_inverse(&phi) * t.translation.vector;
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// The pose moved by a left increment: `exp(delta) * t`, renormalised.
pub fn retract_left(t: &Isometry3<f64>, delta: &Vector6<f64>) -> Isometry3<f64> {
    normalized(&(se3_exp(delta) * t))
}

/// The pose with its rotation quaternion renormalised to unit length.
///
/// Composing poses does not renormalise: chains of products, such as a constant-velocity
/// prediction `T_k (T_{k-1}^-1 T_k)` fed back every frame, let the error compound until the
/// "rotation" also scales points. Anything that stores poses across frames normalises them.
pub fn normalized(t: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        t.translation,
        UnitQuaternion::new_normalize(t.rotation.into_inner()),
    )
}

/// `d (exp(delta) p') / d delta` at `delta = 0` for a transformed point `p' = T p`:
/// `[I | -hat(p')]` (3 x 6, translation columns first).
pub fn point_jacobian(transformed: &Vector3<f64>) -> Matrix3x6<f64> {
    let mut j = Matrix3x6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-hat(transformed)));
    j
}

/// Adjoint of a pose, `Ad(T) = [[R, hat(t) R], [0, R]]`, with `T exp(xi) = exp(Ad(T) xi) T`.
pub fn adjoint(t: &Isometry3<f64>) -> Matrix6<f64> {
    let r = t.rotation.to_rotation_matrix().into_inner();
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(hat(&t.translation.vector) * r));
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    ad
}

/// Angle in degrees of the rotation `a^-1 b` (the geodesic distance between two rotations).
pub fn rotation_angle_deg(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b).to_degrees()
}

/// Angle in degrees between two translation directions (0 when either is zero).
pub fn direction_angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let n = a.norm() * b.norm();
    if n == 0.0 {
        return 0.0;
    }
    (a.dot(b) / n).clamp(-1.0, 1.0).acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn xi_strategy() -> impl Strategy<Value = Vector6<f64>> {
        (
            prop::array::uniform3(-2.0f64..2.0),
            prop::array::uniform3(-1.5f64..1.5),
        )
            .prop_map(|(r, p)| Vector6::new(r[0], r[1], r[2], p[0], p[1], p[2]))
    }

    proptest! {
        #[test]
        fn log_inverts_exp(xi in xi_strategy()) {
            let back = se3_log(&se3_exp(&xi));
            prop_assert!((back - xi).norm() < 1e-9, "{xi} -> {back}");
        }

        #[test]
        fn left_jacobian_inverse_is_an_inverse(phi in prop::array::uniform3(-1.5f64..1.5)) {
            let phi = Vector3::from(phi);
            let prod = so3_left_jacobian(&phi) * so3_left_jacobian_inverse(&phi);
            prop_assert!((prod - Matrix3::identity()).norm() < 1e-9);
        }

        #[test]
        fn point_jacobian_matches_finite_differences(xi in xi_strategy(), p in prop::array::uniform3(-5.0f64..5.0)) {
            let t = se3_exp(&xi);
            let p = nalgebra::Point3::from(Vector3::from(p));
            let j = point_jacobian(&(t * p).coords);
            let h = 1e-6;
            for k in 0..6 {
                let mut d = Vector6::zeros();
                d[k] = h;
                let plus = (retract_left(&t, &d) * p).coords;
                let minus = (retract_left(&t, &(-d)) * p).coords;
                let numeric = (plus - minus) / (2.0 * h);
                prop_assert!((numeric - j.column(k)).norm() < 1e-6);
            }
        }

        #[test]
        fn normalized_restores_unit_length(xi in xi_strategy(), k in 0.5f64..1.5) {
            let t = se3_exp(&xi);
            let scaled = Isometry3::from_parts(t.translation, UnitQuaternion::new_unchecked(t.rotation.into_inner() * k));
            let fixed = normalized(&scaled);
            prop_assert!((fixed.rotation.norm() - 1.0).abs() < 1e-12);
            prop_assert!(fixed.rotation.angle_to(&t.rotation) < 1e-9);
        }

        #[test]
        fn adjoint_moves_a_right_increment_to_the_left(xi in xi_strategy(), d in xi_strategy()) {
            let t = se3_exp(&xi);
            let d = d * 0.1;
            let right = t * se3_exp(&d);
            let left = se3_exp(&(adjoint(&t) * d)) * t;
            prop_assert!((se3_log(&(right.inverse() * left))).norm() < 1e-9);
        }
    }
}
