//! Plane-induced homography `x2 ~ H x1` between normalized coordinates: estimation by the
//! normalized DLT and decomposition into `(R, t, n)` with `H ~ R + t n^T` (Faugeras 1988).

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};

/// Similarity `T` with `T (x, y, 1)` centred and scaled to mean distance `sqrt 2`.
fn normalizing_transform(pts: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    let n = pts.len() as f64;
    let mean = pts.iter().sum::<Vector2<f64>>() / n;
    let d = pts.iter().map(|p| (p - mean).norm()).sum::<f64>() / n;
    if d.is_nan() || d <= 1e-12 || !d.is_finite() {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / d;
    Some(Matrix3::new(
        s,
        0.0,
        -s * mean.x,
        0.0,
        s,
        -s * mean.y,
        0.0,
        0.0,
        1.0,
    ))
}

/// The two DLT rows of `x2 ~ H x1` (entries of `H` row-major).
fn dlt_rows(a: &Vector3<f64>, b: &Vector3<f64>) -> [SVector<f64, 9>; 2] {
    let (x, y) = (a.x, a.y);
    let (u, v) = (b.x, b.y);
    [
        SVector::from([-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]),
        SVector::from([0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]),
    ]
}

/// Homography from `n >= 4` correspondences of normalized coordinates by the DLT on
/// Hartley-normalized points; `None` for degenerate input (coincident or collinear points).
/// The result is scaled to unit Frobenius norm.
///
/// ```
/// use nalgebra::{Matrix3, Vector2};
/// use vofront_geometry::homography::{homography_dlt, transfer};
/// let h = Matrix3::new(1.0, 0.1, 0.05, -0.05, 0.9, 0.02, 0.01, 0.02, 1.0);
/// let x1 = [Vector2::new(0.0, 0.0), Vector2::new(0.5, 0.1), Vector2::new(-0.3, 0.4), Vector2::new(0.2, -0.5)];
/// let x2: Vec<Vector2<f64>> = x1.iter().map(|p| transfer(&h, p)).collect();
/// let est = homography_dlt(&x1, &x2).unwrap();
/// assert!((transfer(&est, &Vector2::new(0.1, 0.1)) - transfer(&h, &Vector2::new(0.1, 0.1))).norm() < 1e-9);
/// ```
pub fn homography_dlt(x1: &[Vector2<f64>], x2: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    if x1.len() < 4 || x1.len() != x2.len() {
        return None;
    }
    let t1 = normalizing_transform(x1)?;
    let t2 = normalizing_transform(x2)?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (a, b) in x1.iter().zip(x2) {
        for row in dlt_rows(&(t1 * a.push(1.0)), &(t2 * b.push(1.0))) {
            ata += row * row.transpose();
        }
    }
    if !ata.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = ata.svd(false, true);
    let sv = svd.singular_values;
    // A second (near-)zero singular value means the points do not determine H.
    if sv[7] <= 1e-10 * sv[0] {
        return None;
    }
    let h = svd.v_t?.row(8).transpose();
    let hn = Matrix3::from_fn(|r, c| h[3 * r + c]);
    let t2_inv = t2.try_inverse()?;
    let hm = t2_inv * hn * t1;
    let n = hm.norm();
    (n > 0.0 && n.is_finite()).then(|| hm / n)
}

/// The transfer `H x` and its squared errors, from [`crate::residual`] (their one
/// implementation).
pub use crate::residual::{transfer, transfer_sq as transfer_errors_sq};

/// Relative tolerance under which all three singular values of `H` count as equal (a
/// rotation: the translation is below `1e-5` of the plane distance).
const EQUAL_SINGULAR: f64 = 1e-5;

/// Relative gap `d_i / d_j - 1` under which two singular values are taken as exactly equal.
/// The general formulas stay exact as the gap closes (their error grows like
/// `eps / sqrt(gap)`), but each pair of twin solutions, which differ by about `sqrt(gap)` rad,
/// becomes one; at this gap the merged twins are `1e-6` rad apart.
const TWIN_MERGE: f64 = 1e-12;

/// Outcome of [`decompose_homography`]; serialised externally tagged (`{"Motion": [[R, t, n],
/// ...]}`, `{"Rotation": R}`, `"Degenerate"`), each `R` a flat column-major array.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum HomographyDecomposition {
    /// Up to eight `(R, t, n)`, unit `t` and unit plane normal `n`, with `H ~ R + t n^T` up
    /// to the sign of `n`, which is returned towards the camera (`n_z > 0`); the chirality test
    /// chooses among them. Four when two singular values are equal (see
    /// [`decompose_homography`]).
    Motion(Vec<(nalgebra::Rotation3<f64>, Vector3<f64>, Vector3<f64>)>),
    /// All three singular values are equal: `H` is a rotation (no translation or a plane at
    /// infinity), `R` the nearest rotation.
    Rotation(nalgebra::Rotation3<f64>),
    /// `H` is singular or not finite, or its SVD failed.
    Degenerate,
}

/// Decomposes a homography between normalized coordinates (Faugeras' SVD method).
///
/// With `H = U diag(d1, d2, d3) V^T`, `s = det U det V` and, for `e1, e3 = +-1`,
/// `x1 = e1 sqrt((d1^2 - d2^2) / (d1^2 - d3^2))`, `x3 = e3 sqrt((d2^2 - d3^2) / (d1^2 - d3^2))`:
///
/// - `d' = d2`: `R' = [[c, 0, -s'], [0, 1, 0], [s', 0, c]]` with `s' = (d1 - d3) x1 x3 / d2`,
///   `c = (d1 x3^2 + d3 x1^2) / d2`, `t' = (d1 - d3) (x1, 0, -x3)`;
/// - `d' = -d2`: `R' = [[c, 0, s'], [0, -1, 0], [s', 0, -c]]` with `s' = (d1 + d3) x1 x3 / d2`,
///   `c = (d3 x1^2 - d1 x3^2) / d2`, `t' = (d1 + d3) (x1, 0, x3)`;
///
/// and `n' = (x1, 0, x3)`, `R = s U R' V^T`, `t ~ U t'`, `n = V n'`.
///
/// Two equal singular values mean a translation along the plane normal (`R^T t || n`, a
/// camera moving straight at a wall). Then `x1 = 0` (`d1 = d2`) or `x3 = 0` (`d2 = d3`) in
/// closed form: the only singular vectors used are those of the distinct singular value, which
/// are well defined, and each twin pair `+-x1` (or `+-x3`) is one solution, so four remain.
///
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// use vofront_geometry::homography::{decompose_homography, HomographyDecomposition};
/// // Plane n^T X = 2 in camera 1, motion (R, t): H = R + t n^T / 2, known up to scale.
/// let r = Rotation3::from_euler_angles(0.05, -0.1, 0.02);
/// let t = Vector3::new(0.3, -0.1, 0.05);
/// let n = Vector3::new(0.1, -0.2, 1.0).normalize();
/// let h = (r.matrix() + t * n.transpose() / 2.0) * 3.7;
/// let HomographyDecomposition::Motion(candidates) = decompose_homography(&h) else {
///     panic!("a general motion");
/// };
/// assert!(candidates.iter().any(|(r2, t2, n2)| {
///     r2.angle_to(&r) < 1e-9 && (t2 - t.normalize()).norm() < 1e-9 && (n2 - n).norm() < 1e-9
/// }));
/// ```
pub fn decompose_homography(h: &Matrix3<f64>) -> HomographyDecomposition {
    use nalgebra::Rotation3;
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return HomographyDecomposition::Degenerate;
    };
    let (d1, d2, d3) = (
        svd.singular_values[0],
        svd.singular_values[1],
        svd.singular_values[2],
    );
    // Equal singular values may come out one rounding error out of order.
    let ordered = d2 <= d1 * (1.0 + TWIN_MERGE) && d3 <= d2 * (1.0 + TWIN_MERGE);
    if !(ordered && d3 > 0.0 && d1.is_finite()) {
        return HomographyDecomposition::Degenerate;
    }
    let s = u.determinant() * v_t.determinant();
    if d1 / d3 < 1.0 + EQUAL_SINGULAR {
        return HomographyDecomposition::Rotation(Rotation3::from_matrix(&(u * v_t * s)));
    }
    let (s1, s2, s3) = (d1 * d1, d2 * d2, d3 * d3);
    let a1 = if d1 / d2 - 1.0 <= TWIN_MERGE {
        0.0
    } else {
        ((s1 - s2) / (s1 - s3)).sqrt()
    };
    let a3 = if d2 / d3 - 1.0 <= TWIN_MERGE {
        0.0
    } else {
        ((s2 - s3) / (s1 - s3)).sqrt()
    };
    // With a1 = 0 or a3 = 0 the twins `+-x1` (or `+-x3`) coincide.
    let signs = if a1 == 0.0 {
        vec![(0.0, a3), (0.0, -a3)]
    } else if a3 == 0.0 {
        vec![(a1, 0.0), (-a1, 0.0)]
    } else {
        vec![(a1, a3), (a1, -a3), (-a1, a3), (-a1, -a3)]
    };
    let v = v_t.transpose();
    let mut out = Vec::with_capacity(2 * signs.len());
    let mut push = |rp: Matrix3<f64>, tp: Vector3<f64>, np: Vector3<f64>| {
        let r = u * rp * v_t * s;
        let t = u * tp;
        let mut n = v * np;
        if n.z < 0.0 {
            n = -n;
        }
        let tn = t.norm();
        if tn > 0.0 {
            out.push((Rotation3::from_matrix(&r), t / tn, n.normalize()));
        }
    };
    for &(x1, x3) in &signs {
        let np = Vector3::new(x1, 0.0, x3);
        // d' = d2.
        let (st, ct) = ((d1 - d3) * x1 * x3 / d2, (d1 * x3 * x3 + d3 * x1 * x1) / d2);
        let rp = Matrix3::new(ct, 0.0, -st, 0.0, 1.0, 0.0, st, 0.0, ct);
        push(rp, Vector3::new(x1, 0.0, -x3) * (d1 - d3), np);
        // d' = -d2.
        let (sp, cp) = ((d1 + d3) * x1 * x3 / d2, (d3 * x1 * x1 - d1 * x3 * x3) / d2);
        let rp = Matrix3::new(cp, 0.0, sp, 0.0, -1.0, 0.0, sp, 0.0, -cp);
        push(rp, Vector3::new(x1, 0.0, x3) * (d1 + d3), np);
    }
    HomographyDecomposition::Motion(out)
}
