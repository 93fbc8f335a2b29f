//! Two-view triangulation of a point seen along rays `f1` (camera 1) and `f2` (camera 2).
//!
//! Frames: the result is in camera 1; `pose = T_21` maps camera-1 points into camera 2,
//! `X2 = R X1 + t`. The rays are bearings or homogeneous normalized coordinates.

use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Vector3, Vector4};

use crate::residual::{row_major, Epipolar};

/// Linear (DLT) triangulation: the homogeneous `X` minimising `|A X|` with, for each view
/// `P = [R | t]` and ray `f`, the rows `f_x P_3 - f_z P_1` and `f_y P_3 - f_z P_2`
/// (each row scaled to unit norm). `None` for a point at infinity or non-finite input.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use vofront_geometry::triangulate::triangulate_dlt;
/// let t21 = Isometry3::new(Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.0, 0.1, 0.0));
/// let p = Point3::new(0.2, -0.1, 4.0);
/// let x = triangulate_dlt(&t21, &p.coords, &(t21 * p).coords).unwrap();
/// assert!((x - p).norm() < 1e-9);
/// ```
pub fn triangulate_dlt(
    pose: &Isometry3<f64>,
    f1: &Vector3<f64>,
    f2: &Vector3<f64>,
) -> Option<Point3<f64>> {
    let p2 = pose.to_homogeneous();
    let p1 = Matrix4::<f64>::identity();
    let mut ata = Matrix4::zeros();
    for (p, f) in [(&p1, f1), (&p2, f2)] {
        for (a, b) in [(f.x, 0), (f.y, 1)] {
            let row: Vector4<f64> = (p.row(2) * a - p.row(b) * f.z).transpose();
            let n = row.norm();
            if !(n > 0.0 && n.is_finite()) {
                return None;
            }
            ata += row * row.transpose() / (n * n);
        }
    }
    let x = ata.svd(false, true).v_t?.row(3).transpose();
    if x[3].abs() < 1e-12 {
        return None;
    }
    let p = Point3::new(x[0] / x[3], x[1] / x[3], x[2] / x[3]);
    p.coords.iter().all(|v| v.is_finite()).then_some(p)
}

/// Depths `(l1, l2)` along the rays (in the ray units) of the closest points of the two rays
/// `l1 f1` and `c2 + l2 R^T f2` (camera 2 centre `c2 = -R^T t`), or `None` when they are
/// parallel.
#[inline]
pub fn ray_depths(
    pose: &Isometry3<f64>,
    f1: &Vector3<f64>,
    f2: &Vector3<f64>,
) -> Option<(f64, f64)> {
    SecondCamera::new(pose).ray_depths(f1, f2)
}

/// Camera 2 of a pose `T_21` seen from camera 1: `R^T` and the centre `c2 = -R^T t`, computed
/// once for the [`ray_depths`] of many ray pairs under one pose.
pub(crate) struct SecondCamera {
    rt: Matrix3<f64>,
    c2: Vector3<f64>,
}

impl SecondCamera {
    /// Camera 2 of `pose`.
    pub(crate) fn new(pose: &Isometry3<f64>) -> Self {
        let rt = pose.rotation.to_rotation_matrix().transpose();
        let c2 = -(rt * pose.translation.vector);
        Self {
            rt: *rt.matrix(),
            c2,
        }
    }

    /// [`ray_depths`] of the rays `f1` (camera 1) and `f2` (camera 2).
    #[inline]
    pub(crate) fn ray_depths(&self, f1: &Vector3<f64>, f2: &Vector3<f64>) -> Option<(f64, f64)> {
        let (c2, d2) = (self.c2, self.rt * f2);
        // Minimise |l1 f1 - c2 - l2 d2|^2: [f1.f1, -f1.d2; -f1.d2, d2.d2] [l1 l2] = [f1.c2, -d2.c2].
        let a = f1.dot(f1);
        let b = f1.dot(&d2);
        let c = d2.dot(&d2);
        let det = a * c - b * b;
        if det <= 1e-14 * a * c {
            return None;
        }
        let r1 = f1.dot(&c2);
        let r2 = -d2.dot(&c2);
        let l1 = (c * r1 + b * r2) / det;
        let l2 = (b * r1 + a * r2) / det;
        Some((l1, l2))
    }
}

/// Inverse-depth-weighted midpoint triangulation (Lee and Civera 2019): with `P1 = l1 f1` and
/// `P2 = c2 + l2 R^T f2` the closest points of the two rays (camera 1 frame) at distances `d1`,
/// `d2` from their centres, `X = (P1 / d1 + P2 / d2) / (1 / d1 + 1 / d2)`, which splits the
/// ray gap into equal angular errors in both views. `None` for parallel rays and when either
/// closest point lies behind its centre (`l1 <= 0` or `l2 <= 0`): nearly parallel rays of a far
/// point can meet behind the cameras, and such a point is no triangulation.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use vofront_geometry::triangulate::triangulate_midpoint;
/// let t21 = Isometry3::new(Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.0, 0.1, 0.0));
/// let p = Point3::new(0.2, -0.1, 4.0);
/// let x = triangulate_midpoint(&t21, &p.coords, &(t21 * p).coords).unwrap();
/// assert!((x - p).norm() < 1e-9);
/// ```
pub fn triangulate_midpoint(
    pose: &Isometry3<f64>,
    f1: &Vector3<f64>,
    f2: &Vector3<f64>,
) -> Option<Point3<f64>> {
    let camera = SecondCamera::new(pose);
    let (l1, l2) = camera.ray_depths(f1, f2)?;
    if !(l1 > 0.0 && l2 > 0.0) {
        return None;
    }
    let d2 = camera.rt * f2;
    let (p1, p2) = (f1 * l1, camera.c2 + d2 * l2);
    let (w1, w2) = (1.0 / (f1.norm() * l1), 1.0 / (d2.norm() * l2));
    let p = if w1.is_finite() && w2.is_finite() {
        (p1 * w1 + p2 * w2) / (w1 + w2)
    } else {
        (p1 + p2) * 0.5
    };
    p.iter().all(|v| v.is_finite()).then_some(Point3::from(p))
}

/// First-order optimal triangulation: both observations (dehomogenised to `(x, y, 1)`) are
/// moved by the Sampson correction onto the epipolar constraint of `E = [t]_x R`,
/// `x1' = x1 - c / D (E^T x2)_{1,2}`, `x2' = x2 - c / D (E x1)_{1,2}` with `c = x2^T E x1` and
/// `D = (E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2`, then intersected by
/// [`triangulate_midpoint`]. The reprojection errors are then about the Sampson distance even
/// for nearly parallel rays. `None` for rays with `z <= 0`, parallel rays, or a degenerate
/// Sampson denominator (an outlier, as everywhere in [`crate::residual`]).
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use vofront_geometry::triangulate::triangulate_corrected;
/// let t21 = Isometry3::new(Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.0, 0.1, 0.0));
/// let p = Point3::new(0.2, -0.1, 4.0);
/// let x = triangulate_corrected(&t21, &p.coords, &(t21 * p).coords).unwrap();
/// assert!((x - p).norm() < 1e-9);
/// ```
pub fn triangulate_corrected(
    pose: &Isometry3<f64>,
    f1: &Vector3<f64>,
    f2: &Vector3<f64>,
) -> Option<Point3<f64>> {
    if f1.z <= 0.0 || f2.z <= 0.0 {
        return None;
    }
    let x1 = f1 / f1.z;
    let x2 = f2 / f2.z;
    let e = crate::lie::hat(&pose.translation.vector) * pose.rotation.to_rotation_matrix().matrix();
    let ep = Epipolar::new(&row_major(&e), x1.x, x1.y, x2.x, x2.y);
    if !ep.is_regular() {
        return None;
    }
    let k = ep.c / ep.d;
    let y1 = Vector3::new(x1.x - k * ep.l1[0], x1.y - k * ep.l1[1], 1.0);
    let y2 = Vector3::new(x2.x - k * ep.l2[0], x2.y - k * ep.l2[1], 1.0);
    triangulate_midpoint(pose, &y1, &y2)
}

/// Parallax angle in degrees at `p` (camera-1 frame) between the rays from the two camera
/// centres.
pub fn parallax_deg(pose: &Isometry3<f64>, p: &Point3<f64>) -> f64 {
    let c2 = -(pose.rotation.inverse() * pose.translation.vector);
    crate::lie::direction_angle_deg(&p.coords, &(p.coords - c2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera 2 one unit right of camera 1, no rotation: both rays look forward (`z > 0`) but
    /// their lines meet at `(0.5, 0, -5)`, behind both centres.
    #[test]
    fn rays_meeting_behind_the_cameras_give_no_point() {
        let pose = Isometry3::translation(-1.0, 0.0, 0.0);
        let f1 = Vector3::new(-0.5, 0.0, 5.0);
        let f2 = Vector3::new(0.5, 0.0, 5.0);
        let (l1, l2) = ray_depths(&pose, &f1, &f2).unwrap();
        assert!(l1 < 0.0 && l2 < 0.0, "{l1} {l2}");
        assert_eq!(triangulate_midpoint(&pose, &f1, &f2), None);
        assert_eq!(triangulate_corrected(&pose, &f1, &f2), None);
        // The mirrored rays meet in front, at (0.5, 0, 5).
        let p = triangulate_midpoint(
            &pose,
            &Vector3::new(0.5, 0.0, 5.0),
            &Vector3::new(-0.5, 0.0, 5.0),
        )
        .unwrap();
        assert!((p - Point3::new(0.5, 0.0, 5.0)).norm() < 1e-12);
    }
}
