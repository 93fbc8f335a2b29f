//! Metric estimates of a pair whose first frame is a rectified stereo pair (`vofront two-view
//! --right1 PNG --baseline M`, Python `two_view(..., right1=, baseline=)`): the left image of
//! frame 2 located against the metric points of frame 1.
//!
//! - [`stereo_pose`] (`feature_stereo`): ORB on both images of frame 1 matched along their
//!   rows (the stereo tracker's own matching: points `P = Z K^-1 [u, v, 1]` with
//!   `Z = f b / d`, only those with `sigma_d / d` at most the tracker's
//!   [`StereoTrackerConfig::max_relative_depth_sigma`]), the left features matched by
//!   descriptor to frame 2's ORB features, then PnP RANSAC with robust refinement: `T_21`
//!   with a metric translation, its quality from [`PnpResult::quality`].
//! - [`check_against_epipolar`]: the metric pose flagged [`Reason::Inconsistent`] when the
//!   epipolar (`feature`) estimate of the same pair is `ok` and disagrees with it, in rotation
//!   and the direction of travel judged together, by more than [`MAX_DISAGREEMENT_SIGMAS`]
//!   combined stated sigmas. On a straight road most matched points are far, their stereo
//!   depths uncertain, and PnP can trade yaw for sideways translation; the essential matrix,
//!   which needs no depth, pins both.
//! - [`stereo_depth`]: frame 1's semi-dense depth from the disparity of its high-gradient
//!   pixels ([`vofront_image::disparity`]), the depth map with which the direct SE(3)
//!   alignment of [`super::estimate`] runs when no `depth1` is given.
//!
//! The pair must be rectified (a pinhole camera without distortion, the right camera at
//! `x = +baseline` in the left one, as KITTI's `image_0`/`image_1`).

use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, Vector3};
use vofront_core::rig::Rig;
use vofront_core::Camera;
use vofront_features::{match_descriptors, Orb};
use vofront_geometry::{solve_pnp_ransac_with_point_covariances, PnpResult, RelativePose};
use vofront_image::disparity::{match_pixels, select_pixels, DisparityConfig};
use vofront_image::Image;
use vofront_robust::{Quality, Reason};

use crate::error::VoError;
use crate::odometry::mono::KEYPOINT_QUANTISATION_PX;
use crate::odometry::stereo::rectified::{DepthRule, Rectified};
use crate::odometry::stereo::StereoTrackerConfig;
use crate::pipeline::feature_pixel;
use crate::timing::ms_since;

/// The right image of frame 1 and the rig's baseline.
pub struct StereoFirst {
    /// Right image of frame 1, rectified with the left one.
    pub right1: Image<u8>,
    /// Distance between the two camera centres, metres.
    pub baseline: f64,
}

/// `T_21` of frame 2's left camera from frame 1's metric stereo points.
#[derive(Debug, Clone)]
pub struct StereoPose {
    /// PnP's pose `T_21` (frame-1 left-camera points into frame 2, metres), inliers,
    /// covariance and quality.
    pub pnp: PnpResult,
    /// ORB keypoints of frame 1's left image and of frame 2.
    pub keypoints: [usize; 2],
    /// Frame-1 features with a metric point (matched in the right image, depth trusted).
    pub stereo_points: usize,
    /// Those points matched by descriptor in frame 2: PnP's correspondences.
    pub matches: usize,
    /// Wall-clock time, milliseconds.
    pub ms: f64,
    /// The rotation and direction disagreements with the epipolar estimate of the pair, judged
    /// together ([`epipolar_disagreement_sigmas`]), in combined stated sigmas ([`check_against_epipolar`]; `None`: not checked).
    pub epipolar_disagreement_sigmas: Option<f64>,
}

/// Largest disagreement of the metric pose with an `ok` epipolar estimate of the same pair, in
/// combined stated sigmas, before the metric pose is flagged [`Reason::Inconsistent`]: 10, or 5
/// sigmas of estimates whose stated sigmas the shared KITTI pairs show to be about 2 times
/// too small (README, "Honest estimates").
pub const MAX_DISAGREEMENT_SIGMAS: f64 = 10.0;

/// Compares the metric pose `stereo` with the `ok` epipolar estimate `epipolar` of the same
/// pair ([`epipolar_disagreement_sigmas`] with PnP's pose, quality and covariance): records the
/// figure in `stereo` and flags its quality [`Reason::Inconsistent`] when it exceeds
/// [`MAX_DISAGREEMENT_SIGMAS`].
pub fn check_against_epipolar(stereo: &mut StereoPose, epipolar: &RelativePose) {
    let pnp = &mut stereo.pnp;
    let sigmas =
        epipolar_disagreement_sigmas(&pnp.pose, &pnp.quality, pnp.covariance.as_ref(), epipolar);
    stereo.epipolar_disagreement_sigmas = flag_if_inconsistent(&mut pnp.quality, sigmas);
}

/// Flags `quality` [`Reason::Inconsistent`] when another estimate disagrees with it by
/// `sigmas` beyond [`MAX_DISAGREEMENT_SIGMAS`]; returns `sigmas` (`None`: not compared).
pub fn flag_if_inconsistent(quality: &mut Quality, sigmas: Option<f64>) -> Option<f64> {
    if sigmas.is_some_and(|s| s > MAX_DISAGREEMENT_SIGMAS) {
        quality.flag(Reason::Inconsistent);
    }
    sigmas
}

/// How far a metric pose `pose` (`T_21`, with its `quality` and the 6x6 covariance of its left
/// increment `(rho, phi)`) is from the `ok` epipolar estimate `epipolar` of the same pair, in
/// combined stated sigmas: `hypot(z_rot, z_dir)` of
/// - rotation: `z_rot = angle(R_s R_e^T) / hypot(sigma_s, sigma_e)`, the sigmas RMS rotation
///   sigmas;
/// - direction, when both translate: `z_dir = angle(t_s, t_e) / hypot(sigma_s, sigma_e)`, the
///   metric direction sigma `sqrt(trace(P C_t P)) / |t_s|` with `C_t` the translation block of
///   the covariance and `P = I - n n^T` the projection across `n = t_s / |t_s|`;
///
/// `z_rot` alone without a direction to compare. The two are judged together (a chi with two
/// degrees of freedom, not the larger of two tests) because the failure they catch moves both:
/// a PnP on far points that trades yaw for sideways motion turns the rotation and the direction
/// of travel at once (`kitti_01` frames 1-4: 6.1 and 9.1 sigmas, 11.0 together; README).
///
/// `None` (nothing checked) when `epipolar` is not `ok` or a rotation sigma is unknown.
pub fn epipolar_disagreement_sigmas(
    pose: &Isometry3<f64>,
    quality: &Quality,
    covariance: Option<&Matrix6<f64>>,
    epipolar: &RelativePose,
) -> Option<f64> {
    if !epipolar.quality.is_ok() {
        return None;
    }
    let e = &epipolar.pose;
    let q_e = &epipolar.quality.uncertainty;
    let rot_s = quality.uncertainty.rotation_sigma_deg?;
    let rot_e = q_e.rotation_sigma_deg?;
    let rotation = (pose.rotation * e.rotation.inverse()).angle().to_degrees();
    let (t_s, t_e) = (pose.translation.vector, e.translation.vector);
    let dir_s = covariance.and_then(|c| direction_sigma_deg(c, &t_s));
    let direction = match (dir_s, q_e.translation_direction_sigma_deg) {
        (Some(dir_s), Some(dir_e)) if t_e.norm() > 0.0 => {
            Some((t_s.angle(&t_e).to_degrees(), dir_s, dir_e))
        }
        _ => None,
    };
    combined_sigmas(&[Some((rotation, rot_s, rot_e)), direction])
}

/// Two estimates' disagreement in their combined stated sigmas, the parts judged together:
/// `sqrt(sum z_i^2)` over the parts `(difference, sigma_a, sigma_b)` that are given (degrees),
/// `z_i = difference / hypot(sigma_a, sigma_b)`; `None` when it is not finite.
pub fn combined_sigmas(parts: &[Option<(f64, f64, f64)>]) -> Option<f64> {
    let sigmas = parts
        .iter()
        .flatten()
        .map(|(d, a, b)| d / a.hypot(*b))
        .fold(0.0f64, f64::hypot);
    sigmas.is_finite().then_some(sigmas)
}

/// RMS standard deviation of the direction of the translation `t` (degrees), from the
/// translation block of the pose covariance `covariance` across `t`; `None` without a
/// translation.
fn direction_sigma_deg(covariance: &Matrix6<f64>, t: &Vector3<f64>) -> Option<f64> {
    let length = t.norm();
    if length == 0.0 {
        return None;
    }
    let c_t: Matrix3<f64> = covariance.fixed_view::<3, 3>(0, 0).into_owned();
    let n = t / length;
    let across = Matrix3::identity() - n * n.transpose();
    let variance = (across * c_t * across).trace().max(0.0);
    Some((variance.sqrt() / length).to_degrees())
}

/// The rectified rig of a distortion-free `camera` with the right camera at `x = +baseline`.
fn rectified(camera: &Camera, baseline: f64, size: (usize, usize)) -> Result<Rectified, VoError> {
    if !camera.distortion.is_identity() {
        return Err(VoError::StereoFrame(
            "the stereo pair must be rectified: the camera has lens distortion".into(),
        ));
    }
    let right = Isometry3::from_parts(Translation3::new(baseline, 0.0, 0.0), Default::default());
    let rig = Rig::stereo(*camera, Isometry3::identity(), *camera, right)
        .map_err(|e| VoError::StereoFrame(e.to_string()))?;
    Rectified::new(&rig, size).map_err(|e| VoError::StereoFrame(e.to_string()))
}

/// The metric pose of `left2` against the stereo pair `(left1, first.right1)` seen by
/// `camera` (see the module documentation), with at most `features` ORB features per image.
///
/// Errors: images of different sizes, a distorted camera or a bad baseline
/// ([`VoError::StereoFrame`]), fewer than 6 points matched in frame 2 ([`VoError::TooFew`]),
/// PnP failing ([`VoError::Geometry`]).
pub fn stereo_pose(
    left1: &Image<u8>,
    first: &StereoFirst,
    left2: &Image<u8>,
    camera: &Camera,
    features: usize,
) -> Result<StereoPose, VoError> {
    let start = Instant::now();
    let mut cfg = StereoTrackerConfig::default();
    cfg.orb.n_features = features;
    let rect = rectified(camera, first.baseline, left1.size())?;
    if left2.size() != left1.size() {
        return Err(VoError::StereoFrame(format!(
            "frame 2 is {:?}, frame 1 {:?}",
            left2.size(),
            left1.size()
        )));
    }
    let orb = Orb::new(cfg.orb.clone())?;
    let depth = DepthRule {
        disparity_sigma_px: KEYPOINT_QUANTISATION_PX,
        max_relative_sigma: cfg.max_relative_depth_sigma,
    };
    let (view, f2) = rayon::join(
        || rect.view(&orb, &cfg.stereo, depth, left1, &first.right1),
        || orb.detect_and_describe(left2),
    );
    let (view, f2) = (view.map_err(|e| VoError::StereoFrame(e.to_string()))?, f2?);
    let with_point: Vec<u32> = (0..view.features.len() as u32)
        .filter(|&i| view.points[i as usize].is_some())
        .collect();
    let descriptors: Vec<_> = with_point
        .iter()
        .map(|&i| view.features.descriptors()[i as usize])
        .collect();
    let matches = match_descriptors(&descriptors, f2.descriptors(), &cfg.matching);
    const MIN_MATCHES: usize = 6;
    if matches.len() < MIN_MATCHES {
        return Err(VoError::TooFew {
            what: "stereo points matched in frame 2",
            got: matches.len(),
            need: MIN_MATCHES,
        });
    }
    let mut points = Vec::with_capacity(matches.len());
    let mut pixels = Vec::with_capacity(matches.len());
    let mut sigmas = Vec::with_capacity(matches.len());
    let mut covariances = Vec::with_capacity(matches.len());
    for m in &matches {
        let i = with_point[m.query as usize] as usize;
        points.extend(view.points[i]);
        pixels.push(feature_pixel(&f2, m.train));
        sigmas.push(f64::from(f2.scales()[m.train as usize]));
        covariances.push(view.covariances[i]);
    }
    let pnp = solve_pnp_ransac_with_point_covariances(
        &points,
        &pixels,
        &sigmas,
        &covariances,
        &rect.camera,
        None,
        &cfg.pnp,
    )?;
    Ok(StereoPose {
        pnp,
        keypoints: [view.features.len(), f2.len()],
        stereo_points: with_point.len(),
        matches: matches.len(),
        ms: ms_since(start),
        epipolar_disagreement_sigmas: None,
    })
}

/// Frame 1's semi-dense metric depth (metres, 0 where unknown) from the disparity of its
/// high-gradient pixels against `first.right1`, `Z = f b / d`, keeping depths whose relative
/// uncertainty `sigma_d / d` is at most the stereo tracker's
/// [`StereoTrackerConfig::max_relative_depth_sigma`].
///
/// Errors: as [`stereo_pose`]'s rig and size checks.
pub fn stereo_depth(
    left1: &Image<u8>,
    first: &StereoFirst,
    camera: &Camera,
) -> Result<Image<f32>, VoError> {
    let rect = rectified(camera, first.baseline, left1.size())?;
    let max_relative_sigma = StereoTrackerConfig::default().max_relative_depth_sigma;
    let (left, right) = (left1.to_f32(), first.right1.to_f32());
    let cfg = DisparityConfig::default();
    let found = match_pixels(&left, &right, &select_pixels(&left, &cfg), &cfg)
        .map_err(|e| VoError::StereoFrame(e.to_string()))?;
    let (width, height) = left1.size();
    let mut depth = vec![0.0f32; width * height];
    for m in found
        .iter()
        .flatten()
        .filter(|m| f64::from(m.sigma / m.disparity) <= max_relative_sigma)
    {
        depth[m.y as usize * width + m.x as usize] = m.depth(rect.fb) as f32;
    }
    Image::new(width, height, depth).map_err(|e| VoError::StereoFrame(e.to_string()))
}
