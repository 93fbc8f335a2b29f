//! The four `(R, t)` factorisations of an essential matrix and the chirality test.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::triangulate::{parallax_deg, triangulate_corrected, SecondCamera};

/// The four candidates `(R, t)` with `E ~ [t]_x R`, `|t| = 1`: with `E = U S V^T`
/// (`det U = det V = 1`) and `W` the rotation by 90 degrees about `z`,
/// `R in {U W V^T, U W^T V^T}`, `t = +-u_3`.
pub fn decompose_essential(e: &Matrix3<f64>) -> [(Rotation3<f64>, Vector3<f64>); 4] {
    let svd = e.svd(true, true);
    let mut u = svd.u.unwrap_or_else(Matrix3::identity);
    let mut v_t = svd.v_t.unwrap_or_else(Matrix3::identity);
    if u.determinant() < 0.0 {
        u = -u;
    }
    if v_t.determinant() < 0.0 {
        v_t = -v_t;
    }
    let w = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let r1 = Rotation3::from_matrix_unchecked(u * w * v_t);
    let r2 = Rotation3::from_matrix_unchecked(u * w.transpose() * v_t);
    let t: Vector3<f64> = u.column(2).into_owned();
    [(r1, t), (r1, -t), (r2, t), (r2, -t)]
}

/// Settings of [`recover_pose`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecoverConfig {
    /// Points farther than this (in units of the baseline `|t| = 1`) from camera 1 are not
    /// counted as good (they carry no translation information).
    pub far_distance: f64,
}

impl Default for RecoverConfig {
    fn default() -> Self {
        Self { far_distance: 50.0 }
    }
}

/// Result of the chirality test.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PoseRecovery {
    /// `T_21` with a unit translation.
    pub pose: Isometry3<f64>,
    /// Sampson-corrected midpoints ([`crate::triangulate::triangulate_corrected`]) in camera 1 (baseline units) of the used correspondences
    /// in front of both cameras and closer than the far limit; `None` otherwise.
    pub points: Vec<Option<Point3<f64>>>,
    /// Number of `Some` in `points`.
    pub good: usize,
    /// Good points of the runner-up candidate (ambiguity check).
    pub second_good: usize,
    /// The runner-up candidate pose (the other solution of a planar scene).
    pub runner_up: Option<Isometry3<f64>>,
    /// Median parallax angle (degrees) of the good points, 0 when there are none.
    pub median_parallax_deg: f64,
}

/// Whether the rays `a` (camera 1) and `b` (camera 2) meet in front of both cameras, closer
/// than `far` to camera 1.
fn in_front(camera: &SecondCamera, a: &Vector3<f64>, b: &Vector3<f64>, far: f64) -> bool {
    camera
        .ray_depths(a, b)
        .is_some_and(|(l1, l2)| l1 > 0.0 && l2 > 0.0 && a.norm() * l1 < far)
}

/// Counts, for the pose `T_21`, the used correspondences in front of both cameras and
/// closer than `far`.
fn count_in_front(
    pose: &Isometry3<f64>,
    x1: &[Vector3<f64>],
    x2: &[Vector3<f64>],
    used: &[bool],
    far: f64,
) -> usize {
    let camera = SecondCamera::new(pose);
    x1.iter()
        .zip(x2)
        .zip(used)
        .filter(|((a, b), &u)| u && in_front(&camera, a, b, far))
        .count()
}

/// The candidate poses with their numbers of used correspondences in front of both cameras
/// and closer than `far`, most first; equal counts (the two-fold ambiguity of a plane) prefer
/// the smaller rotation, the usual case between nearby video frames.
fn rank_by_chirality(
    candidates: &[(Rotation3<f64>, Vector3<f64>)],
    x1: &[Vector3<f64>],
    x2: &[Vector3<f64>],
    used: &[bool],
    far: f64,
) -> Vec<(usize, Isometry3<f64>)> {
    let mut ranked: Vec<(usize, Isometry3<f64>)> = candidates
        .iter()
        .map(|(r, t)| {
            let pose = Isometry3::from_parts(
                Translation3::from(*t),
                UnitQuaternion::from_rotation_matrix(r),
            );
            (count_in_front(&pose, x1, x2, used, far), pose)
        })
        .collect();
    ranked.sort_by(|a, b| {
        b.0.cmp(&a.0)
            .then(a.1.rotation.angle().total_cmp(&b.1.rotation.angle()))
    });
    ranked
}

/// The candidate pose with the most used correspondences in front of both cameras and closer
/// than the far limit, with that number; the choice of [`select_by_chirality`] without its
/// triangulation, for callers that only need the pose.
///
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// use vofront_geometry::essential::{
///     best_by_chirality, decompose_essential, select_by_chirality, RecoverConfig,
/// };
/// let r = Rotation3::new(Vector3::new(0.02, -0.1, 0.03));
/// let t = Vector3::new(0.2, -0.1, 1.0).normalize();
/// let x1: Vec<Vector3<f64>> = (0..30)
///     .map(|i| Vector3::new((i as f64 * 0.7).sin(), (i as f64 * 1.3).cos(), 4.0 + (i % 7) as f64))
///     .collect();
/// let x2: Vec<Vector3<f64>> = x1.iter().map(|p| r * p + t).collect();
/// let candidates = decompose_essential(&(vofront_geometry::lie::hat(&t) * r.matrix()));
/// let (used, cfg) = (vec![true; 30], RecoverConfig::default());
/// let (pose, good) = best_by_chirality(&candidates, &x1, &x2, &used, &cfg).unwrap();
/// let full = select_by_chirality(&candidates, &x1, &x2, &used, &cfg).unwrap();
/// assert_eq!((pose, good), (full.pose, full.good));
/// assert!((pose.translation.vector - t).norm() < 1e-9 && good == 30);
/// ```
pub fn best_by_chirality(
    candidates: &[(Rotation3<f64>, Vector3<f64>)],
    x1: &[Vector3<f64>],
    x2: &[Vector3<f64>],
    used: &[bool],
    cfg: &RecoverConfig,
) -> Option<(Isometry3<f64>, usize)> {
    let (good, pose) = *rank_by_chirality(candidates, x1, x2, used, cfg.far_distance).first()?;
    Some((pose, good))
}

/// Chooses, among candidate poses, the one with the most correspondences (where `used`) in
/// front of both cameras and closer than the far limit, and triangulates them.
pub fn select_by_chirality(
    candidates: &[(Rotation3<f64>, Vector3<f64>)],
    x1: &[Vector3<f64>],
    x2: &[Vector3<f64>],
    used: &[bool],
    cfg: &RecoverConfig,
) -> Option<PoseRecovery> {
    let ranked = rank_by_chirality(candidates, x1, x2, used, cfg.far_distance);
    let &(_, pose) = ranked.first()?;
    let second_good = ranked.get(1).map_or(0, |c| c.0);
    let runner_up = ranked.get(1).map(|c| c.1);
    let camera = SecondCamera::new(&pose);
    let mut parallax = Vec::with_capacity(x1.len());
    let points: Vec<Option<Point3<f64>>> = x1
        .iter()
        .zip(x2)
        .zip(used)
        .map(|((a, b), &u)| {
            if !(u && in_front(&camera, a, b, cfg.far_distance)) {
                return None;
            }
            let p = triangulate_corrected(&pose, a, b)?;
            parallax.push(parallax_deg(&pose, &p));
            Some(p)
        })
        .collect();
    let good = points.iter().filter(|p| p.is_some()).count();
    parallax.sort_by(f64::total_cmp);
    let median_parallax_deg = parallax.get(parallax.len() / 2).copied().unwrap_or(0.0);
    Some(PoseRecovery {
        pose,
        points,
        good,
        second_good,
        runner_up,
        median_parallax_deg,
    })
}

/// Recovers `T_21` (unit translation) from an essential matrix and the correspondences used
/// (`used[i]`, e.g. RANSAC inliers): the candidate of [`decompose_essential`] with the most
/// points in front of both cameras and closer than `cfg.far_distance`.
///
/// ```
/// use nalgebra::{Point3, Rotation3, Vector3};
/// use vofront_geometry::essential::{recover_pose, RecoverConfig};
/// let r = Rotation3::new(Vector3::new(0.0, 0.1, 0.0));
/// let t = Vector3::new(1.0, 0.0, 0.0);
/// let x1: Vec<Vector3<f64>> = (0..20).map(|i| Vector3::new(i as f64 * 0.1 - 1.0, (i % 3) as f64 * 0.3, 5.0 + (i % 5) as f64)).collect();
/// let x2: Vec<Vector3<f64>> = x1.iter().map(|p| r * p + t).collect();
/// let e = vofront_geometry::lie::hat(&t) * r.matrix();
/// let rec = recover_pose(&e, &x1, &x2, &vec![true; 20], &RecoverConfig::default()).unwrap();
/// assert_eq!(rec.good, 20);
/// assert!((rec.pose.translation.vector - t).norm() < 1e-9);
/// ```
pub fn recover_pose(
    e: &Matrix3<f64>,
    x1: &[Vector3<f64>],
    x2: &[Vector3<f64>],
    used: &[bool],
    cfg: &RecoverConfig,
) -> Option<PoseRecovery> {
    if x1.len() != x2.len() || x1.len() != used.len() {
        return None;
    }
    select_by_chirality(&decompose_essential(e), x1, x2, used, cfg)
}
