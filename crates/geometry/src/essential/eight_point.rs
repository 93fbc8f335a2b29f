//! Normalized eight-point algorithm for the essential matrix (Hartley 1997).
//!
//! Each correspondence gives one row `(x2 (x) x1)^T e = 0` of `A e = 0` with `e` the row-major
//! entries of `E`. The inhomogeneous coordinates `(x/z, y/z)` are first translated to their
//! centroid and scaled to a mean distance of `sqrt 2` (`T1`, `T2`), the least-squares `e` is the
//! right singular vector of `A^T A` with the smallest singular value, then `E = T2^T E' T1` is projected onto
//! the essential manifold: `E = U diag(1, 1, 0) V^T` from the SVD `E = U S V^T`.

use nalgebra::{Matrix3, SMatrix, Vector3};

/// Similarity `T` with `T (x, y, 1)` centred and scaled to mean distance `sqrt 2`.
fn normalizing_transform(pts: impl Iterator<Item = (f64, f64)> + Clone) -> Option<Matrix3<f64>> {
    let n = pts.clone().count() as f64;
    let (sx, sy) = pts
        .clone()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let mean_dist = pts.map(|(x, y)| (x - mx).hypot(y - my)).sum::<f64>() / n;
    if !(mean_dist > 1e-12 && mean_dist.is_finite()) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean_dist;
    Some(Matrix3::new(
        s,
        0.0,
        -s * mx,
        0.0,
        s,
        -s * my,
        0.0,
        0.0,
        1.0,
    ))
}

/// Projects a 3x3 matrix onto the essential manifold `U diag(1, 1, 0) V^T`, unit Frobenius
/// norm scaled to `sqrt 2` (so the two singular values are 1).
pub fn project_to_essential(e: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = e.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::zeros();
    };
    u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0)) * v_t
}

/// Least-squares essential matrix from `n >= 8` correspondences `x2_i^T E x1_i = 0`.
///
/// `x1`, `x2`: rays with positive `z` (bearings or `(x, y, 1)` normalized coordinates).
/// Writes the single solution (singular values `1, 1, 0`) into `out` after clearing it;
/// leaves `out` empty for fewer than eight points or a degenerate configuration.
///
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// use vofront_geometry::essential::essential_8pt;
/// let r = Rotation3::new(Vector3::new(0.05, -0.1, 0.02));
/// let t = Vector3::new(0.3, 0.05, 0.1);
/// let x1: Vec<Vector3<f64>> = (0..12)
///     .map(|i| Vector3::new((i as f64 * 0.37).sin(), (i as f64 * 0.91).cos(), 3.0 + (i % 4) as f64))
///     .collect();
/// let x2: Vec<Vector3<f64>> = x1.iter().map(|p| r * p + t).collect();
/// let mut sols = Vec::new();
/// essential_8pt(&x1, &x2, &mut sols);
/// let truth = vofront_geometry::lie::hat(&t) * r.matrix();
/// let (e, truth) = (sols[0] / sols[0].norm(), truth / truth.norm());
/// assert!((e - truth).norm() < 1e-6 || (e + truth).norm() < 1e-6);
/// ```
pub fn essential_8pt(x1: &[Vector3<f64>], x2: &[Vector3<f64>], out: &mut Vec<Matrix3<f64>>) {
    out.clear();
    if x1.len() < 8 || x1.len() != x2.len() {
        return;
    }
    let inh = |p: &Vector3<f64>| (p.x / p.z, p.y / p.z);
    let (Some(t1), Some(t2)) = (
        normalizing_transform(x1.iter().map(inh)),
        normalizing_transform(x2.iter().map(inh)),
    ) else {
        return;
    };
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (p, q) in x1.iter().zip(x2) {
        let a = t1 * Vector3::new(p.x / p.z, p.y / p.z, 1.0);
        let b = t2 * Vector3::new(q.x / q.z, q.y / q.z, 1.0);
        let row: [f64; 9] = std::array::from_fn(|k| b[k / 3] * a[k % 3]);
        // The upper triangle only; the lower one is filled by symmetry below.
        for j in 0..9 {
            for i in 0..=j {
                ata[(i, j)] += row[i] * row[j];
            }
        }
    }
    ata.fill_lower_triangle_with_upper_triangle();
    if !ata.iter().all(|v| v.is_finite()) {
        return;
    }
    // Null vector from the SVD (sorted singular values; the last right singular vector).
    let Some(v_t) = ata.svd(false, true).v_t else {
        return;
    };
    let e = v_t.row(8);
    let en = Matrix3::from_fn(|r, c| e[3 * r + c]);
    let ess = project_to_essential(&(t2.transpose() * en * t1));
    let n = ess.norm();
    if n > 0.0 && n.is_finite() {
        out.push(ess / n * std::f64::consts::SQRT_2);
    }
}
