//! Minimal absolute pose from three bearings (Grunert's formulation solved through the
//! resultant of two conics).
//!
//! With unknown depths `s_i` of the camera points `X_i = s_i f_i`, the squared world distances
//! `a = |P2 - P3|^2`, `b = |P1 - P3|^2`, `c = |P1 - P2|^2` and the ray cosines
//! `ca = f2.f3`, `cb = f1.f3`, `cg = f1.f2` give, with `u = s2 / s1` and `v = s3 / s1`,
//! `b (1 + u^2 - 2 u cg) = c (1 + v^2 - 2 v cb)` and `b (u^2 + v^2 - 2 u v ca) = a (1 + v^2 - 2 v cb)`:
//! two quadratics in `u` whose resultant is a quartic in `v`. Each positive root gives `u`,
//! `s1 = sqrt(c / (1 + u^2 - 2 u cg))` and the camera points, and `(R, t)` with `X_i = R P_i + t`
//! follows by absolute orientation (SVD of the cross-covariance).

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point3, Rotation3, Schur, Translation3, UnitQuaternion, Vector3,
};

/// Product of two polynomials given by ascending coefficients.
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// `a - b` for ascending coefficients.
fn poly_sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    let n = a.len().max(b.len());
    (0..n)
        .map(|k| a.get(k).copied().unwrap_or(0.0) - b.get(k).copied().unwrap_or(0.0))
        .collect()
}

/// Evaluates ascending coefficients at `x` and the derivative.
fn poly_eval(c: &[f64], x: f64) -> (f64, f64) {
    let mut v = 0.0;
    let mut d = 0.0;
    for &k in c.iter().rev() {
        d = d * x + v;
        v = v * x + k;
    }
    (v, d)
}

/// Upper bound on the Schur decomposition's QR iterations for the 4x4 companion matrix.
const MAX_QR_ITERATIONS: usize = 1000;

/// Real roots of a quartic (ascending coefficients `c[0..5]`) from the companion matrix,
/// polished by Newton steps; none when the QR iteration does not converge.
pub fn quartic_real_roots(c: &[f64; 5]) -> Vec<f64> {
    if c[4].abs() < 1e-14 * c.iter().fold(0.0f64, |m, v| m.max(v.abs())) {
        return Vec::new();
    }
    let mut comp = Matrix4::<f64>::zeros();
    for k in 0..4 {
        comp[(k, 3)] = -c[k] / c[4];
    }
    for k in 1..4 {
        comp[(k, k - 1)] = 1.0;
    }
    // A bounded QR iteration (nalgebra's `complex_eigenvalues()` iterates without limit).
    let Some(schur) = Schur::try_new(comp, f64::EPSILON, MAX_QR_ITERATIONS) else {
        return Vec::new();
    };
    schur
        .complex_eigenvalues()
        .iter()
        .filter(|z| z.im.abs() < 1e-6 * (1.0 + z.re.abs()))
        .map(|z| {
            let mut x = z.re;
            for _ in 0..3 {
                let (v, d) = poly_eval(c, x);
                if d.abs() > 0.0 {
                    x -= v / d;
                }
            }
            x
        })
        .collect()
}

/// `(R, t)` minimising `sum |X_i - (R P_i + t)|^2` (Kabsch); `None` when degenerate.
pub fn absolute_orientation(
    world: &[Vector3<f64>],
    cam: &[Vector3<f64>],
) -> Option<Isometry3<f64>> {
    let n = world.len() as f64;
    let mw = world.iter().sum::<Vector3<f64>>() / n;
    let mc = cam.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (p, x) in world.iter().zip(cam) {
        h += (x - mc) * (p - mw).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let t = mc - r * mw;
    if !r.iter().chain(t.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Some(Isometry3::from_parts(Translation3::from(t), rot))
}

/// Residuals of the three distance constraints at the depths `s`:
/// `F_1 = s2^2 + s3^2 - 2 s2 s3 ca - a`, `F_2 = s1^2 + s3^2 - 2 s1 s3 cb - b`,
/// `F_3 = s1^2 + s2^2 - 2 s1 s2 cg - c` (metres squared), and their Jacobian in `s`.
fn distance_residuals(
    s: &Vector3<f64>,
    cos: [f64; 3],
    dist2: [f64; 3],
) -> (Vector3<f64>, Matrix3<f64>) {
    let [ca, cb, cg] = cos;
    let [a, b, c] = dist2;
    let (s1, s2, s3) = (s.x, s.y, s.z);
    let r = Vector3::new(
        s2 * s2 + s3 * s3 - 2.0 * s2 * s3 * ca - a,
        s1 * s1 + s3 * s3 - 2.0 * s1 * s3 * cb - b,
        s1 * s1 + s2 * s2 - 2.0 * s1 * s2 * cg - c,
    );
    let j = Matrix3::new(
        0.0,
        2.0 * (s2 - s3 * ca),
        2.0 * (s3 - s2 * ca),
        2.0 * (s1 - s3 * cb),
        0.0,
        2.0 * (s3 - s1 * cb),
        2.0 * (s1 - s2 * cg),
        2.0 * (s2 - s1 * cg),
        0.0,
    );
    (r, j)
}

/// Newton steps on the depths `s = (s1, s2, s3)` against the three distance constraints
/// themselves ([`distance_residuals`]), keeping the best iterate.
///
/// The quartic's root comes through an elimination (the resultant) whose coefficients cancel
/// badly when two world points are close together or a root is nearly double: on exact data
/// the pose can then be off by 1e-4 although the constraints at the true depths are well
/// conditioned. A few Newton steps on the original equations restore full precision (the
/// Jacobian is regular away from the danger cylinder, where the solutions truly merge); a
/// step that does not lower the residual is discarded.
fn polish_depths(s: Vector3<f64>, cos: [f64; 3], dist2: [f64; 3]) -> Vector3<f64> {
    let (mut best, mut best_norm) = (s, distance_residuals(&s, cos, dist2).0.norm());
    for _ in 0..POLISH_STEPS {
        let (r, j) = distance_residuals(&best, cos, dist2);
        let Some(step) = j.lu().solve(&r) else {
            break;
        };
        let next = best - step;
        let norm = distance_residuals(&next, cos, dist2).0.norm();
        if norm.is_nan() || norm >= best_norm {
            break;
        }
        (best, best_norm) = (next, norm);
    }
    best
}

/// Newton steps of [`polish_depths`]: quadratic convergence from a root that already holds
/// four or more digits needs two; the third is a margin.
const POLISH_STEPS: usize = 3;

/// Camera poses `T_cw` (world points into the camera, `X = R P + t`) consistent with three
/// world points seen along the unit bearings `f` (up to four solutions, appended to `out`
/// after clearing it).
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use vofront_geometry::p3p::p3p;
/// let t_cw = Isometry3::new(Vector3::new(0.1, -0.2, 0.5), Vector3::new(0.1, 0.2, -0.05));
/// let pw = [Point3::new(0.0, 0.0, 4.0), Point3::new(1.0, 0.2, 5.0), Point3::new(-0.5, 0.8, 3.0)];
/// let f = pw.map(|p| (t_cw * p).coords.normalize());
/// let mut sols = Vec::new();
/// p3p(&pw, &f, &mut sols);
/// assert!(sols.iter().any(|s| (s.to_homogeneous() - t_cw.to_homogeneous()).norm() < 1e-6));
/// ```
pub fn p3p(world: &[Point3<f64>; 3], f: &[Vector3<f64>; 3], out: &mut Vec<Isometry3<f64>>) {
    out.clear();
    let [p1, p2, p3] = world;
    let a = (p2 - p3).norm_squared();
    let b = (p1 - p3).norm_squared();
    let c = (p1 - p2).norm_squared();
    if a < 1e-18 || b < 1e-18 || c < 1e-18 {
        return;
    }
    let ca = f[1].dot(&f[2]);
    let cb = f[0].dot(&f[2]);
    let cg = f[0].dot(&f[1]);
    // Quadratics in u: p2 u^2 + p1 u + p0 and q2 u^2 + q1 u + q0 (p2 = q2 = b), coefficients
    // ascending polynomials in v.
    let p1c = [-2.0 * b * cg];
    let p0c = [b - c, 2.0 * c * cb, -c];
    let q1c = [0.0, -2.0 * b * ca];
    let q0c = [-a, 2.0 * a * cb, b - a];
    let d0 = poly_sub(&q0c, &p0c); // q0 - p0
    let d1 = poly_sub(&q1c, &p1c); // q1 - p1
    let cross = poly_sub(&poly_mul(&p1c, &q0c), &poly_mul(&q1c, &p0c)); // p1 q0 - q1 p0
    let res = poly_sub(&poly_mul(&poly_mul(&d0, &d0), &[b]), &poly_mul(&d1, &cross));
    let mut quartic = [0.0; 5];
    for (k, v) in res.iter().enumerate().take(5) {
        quartic[k] = *v;
    }
    let world_v = [p1.coords, p2.coords, p3.coords];
    for v in quartic_real_roots(&quartic) {
        if v <= 0.0 {
            continue;
        }
        let (num, _) = poly_eval(&d0, v);
        let (den, _) = poly_eval(&d1, v);
        if den.abs() < 1e-14 {
            continue;
        }
        // (p1 - q1) u + (p0 - q0) = 0.
        let u = num / (-den);
        if u <= 0.0 {
            continue;
        }
        let q = 1.0 + u * u - 2.0 * u * cg;
        if q <= 0.0 {
            continue;
        }
        let s1 = (c / q).sqrt();
        let depths = polish_depths(Vector3::new(s1, u * s1, v * s1), [ca, cb, cg], [a, b, c]);
        let cam = [f[0] * depths.x, f[1] * depths.y, f[2] * depths.z];
        if let Some(pose) = absolute_orientation(&world_v, &cam) {
            out.push(pose);
        }
    }
}
