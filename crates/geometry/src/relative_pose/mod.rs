//! Two-view relative pose from pixel correspondences.
//!
//! Pipeline of [`estimate_relative_pose`]:
//! 1. validation and undistortion of the pixels into normalized coordinates `x_n`;
//! 2. LO-MSAC of the essential matrix (five-point samples, Sampson error, threshold
//!    `threshold_px / f` with `f = (fx + fy) / 2`) and of a homography (four-point DLT,
//!    symmetric transfer error), the latter with the iteration budget that would find it if it
//!    explained as many correspondences as the essential matrix;
//! 3. model selection as in ORB-SLAM's initialiser: with `sigma = threshold_px`,
//!    `S_H = sum_i sum_{images} max(0, 5.99 - d^2 / sigma^2)` over transfer errors and
//!    `S_E = sum_i sum_{images} [d^2 / sigma^2 < 3.84] (5.99 - d^2 / sigma^2)` over distances to
//!    the epipolar lines; the homography is used when `S_H / (S_H + S_E) > homography_ratio`;
//! 4. pose recovery: the four factorisations of `E` (or up to eight of `H`) are triangulated and
//!    the one with most points in front of both cameras and closer than the far limit kept;
//! 5. refinement of `(R, t)` (`t` on the unit sphere) on the inliers by Huber IRLS on the
//!    Sampson distance; when the homography was selected, the essential matrix's own motion is
//!    refined too and the lower MSAC Sampson cost wins; the chosen motion then gets a
//!    maximum-likelihood refit ([`refine_maximum_likelihood`]: Huber on the Sampson distance at
//!    a noise scale estimated from its own residuals, `3 sigma` gate, re-selection until the
//!    gated set is stable); final inliers and points from the refined pose;
//! 6. a median parallax under `min_parallax_deg` flags `low_parallax` (translation direction
//!    poorly determined); when a rotation alone explains at least 90% of the model's inliers
//!    the motion is a pure rotation: least-squares rotation of the rays, zero translation;
//! 7. the quality record ([`RelativePose::quality`]): fewer than five final inliers is
//!    [`GeometryError::NoModel`]; otherwise support, the a-contrario chance test and the
//!    covariance `sigma^2 (J^T J)^-1` of `(R, t)` from the Sampson Jacobian on the refit's
//!    gated correspondences decide `ok`, `unreliable` or `failed`.

mod estimators;
mod quality;
mod refine;
mod rotation;

pub use estimators::{Correspondences, EssentialEstimator, HomographyEstimator, HomographyModel};
pub use refine::{
    refine_maximum_likelihood, refine_relative_pose, refine_relative_pose_fit, sampson_information,
    tangent_basis, MlRefineConfig, RelRefinement, RelState,
};
use vofront_robust::{Loss, Quality, QualityConfig, Reason};

use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3,
};

use crate::camera::Camera;
use crate::error::GeometryError;
use crate::essential::{decompose_essential, select_by_chirality, PoseRecovery, RecoverConfig};
use crate::homography::{decompose_homography, HomographyDecomposition};
use crate::lie::hat;
use crate::ransac::{ransac, required_iterations, Estimator, RansacConfig};
use estimators::transfer_sq;
use rotation::{nearest_rotation, refine_rotation};

/// Chi-square (95%, 2 DoF) bound of ORB-SLAM's homography score, also its score offset.
const CHI2_2DOF: f64 = 5.99;
/// Chi-square (95%, 1 DoF) bound of ORB-SLAM's epipolar score.
const CHI2_1DOF: f64 = 3.84;
/// Homography inlier threshold over the Sampson one: the transfer error carries the noise of
/// both images in two dimensions (`2 sigma^2` per axis, 95% chi-square 5.99) where the Sampson
/// distance is one-dimensional with variance `sigma^2` (95% chi-square 3.84).
const H_THRESHOLD_FACTOR: f64 = 1.766; // sqrt(2 * 5.99 / 3.84)
/// Fraction of the selected model's inliers that a rotation alone must explain for the motion
/// to be declared a pure rotation.
const ROTATION_SUPPORT: f64 = 0.9;
/// Two refined motions whose MSAC costs are within this factor are reported as ambiguous.
const AMBIGUITY_MARGIN: f64 = 0.95;
/// Lower bound on the homography's iteration budget.
const H_MIN_ITERATIONS: usize = 100;
/// Minimum correspondences: the five-point solver's sample; fewer final inliers is
/// [`GeometryError::NoModel`].
const MIN_CORRESPONDENCES: usize = 5;
/// Minimal sample of a rotation-only model (two rays fix a rotation).
const ROTATION_SAMPLE: usize = 2;

/// Settings of [`estimate_relative_pose`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativePoseConfig {
    /// Inlier threshold on the Sampson / transfer distance, pixels.
    pub threshold_px: f64,
    /// RANSAC confidence.
    pub confidence: f64,
    /// RANSAC iteration cap (each of the two models).
    pub max_iterations: usize,
    /// Sampler seed (results are reproducible for a given seed).
    pub seed: u64,
    /// Nonlinear refinement of `(R, t)` on the inliers.
    pub refine: bool,
    /// Median parallax (degrees) below which `low_parallax` flags the translation direction as
    /// poorly determined.
    pub min_parallax_deg: f64,
    /// `S_H / (S_H + S_E)` above which the homography is used.
    pub homography_ratio: f64,
    /// Points farther than this many baselines are not counted by the chirality test.
    pub far_distance: f64,
    /// Minimum support of an `ok` pose ([`RelativePose::quality`]).
    pub quality: QualityConfig,
}

impl Default for RelativePoseConfig {
    fn default() -> Self {
        Self {
            threshold_px: 1.0,
            confidence: 0.999,
            max_iterations: 10_000,
            seed: 0,
            refine: true,
            min_parallax_deg: 1.0,
            homography_ratio: 0.45,
            far_distance: 50.0,
            quality: QualityConfig::default(),
        }
    }
}

/// Which model produced the pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// The essential matrix (general scene).
    Essential,
    /// The homography (planar scene or pure rotation).
    Homography,
}

/// Relative pose `T_21` between two views.
#[derive(Debug, Clone, PartialEq)]
pub struct RelativePose {
    /// `R_21`.
    pub rotation: UnitQuaternion<f64>,
    /// Unit translation direction `t_21`, zero for a pure rotation.
    pub translation: Vector3<f64>,
    /// `T_21 = (R_21, t_21)`.
    pub pose: Isometry3<f64>,
    /// Model used.
    pub model: Model,
    /// Per input correspondence: consistent with the final pose (Sampson distance under the
    /// threshold; for a pure rotation, transfer error under the threshold).
    pub inliers: Vec<bool>,
    /// Number of `true` in `inliers`.
    pub inlier_count: usize,
    /// Per input correspondence: the triangulated point in camera 1, in baseline units, for
    /// inliers in front of both cameras and closer than the far limit.
    pub points: Vec<Option<Point3<f64>>>,
    /// Number of `Some` in `points`.
    pub triangulated: usize,
    /// Median parallax angle of the triangulated points, degrees.
    pub parallax_deg: f64,
    /// Median parallax under `min_parallax_deg` (or a pure rotation): the translation direction
    /// is poorly determined.
    pub low_parallax: bool,
    /// A rotation alone explains the correspondences: the translation is reported as zero and
    /// the rotation is the least-squares rotation of the rays.
    pub pure_rotation: bool,
    /// Two motions explain the data about equally (planar two-fold ambiguity).
    pub ambiguous: bool,
    /// The other motion when `ambiguous`.
    pub alternative: Option<Isometry3<f64>>,
    /// `S_H / (S_H + S_E)`.
    pub homography_score_ratio: f64,
    /// RANSAC iterations (essential, homography).
    pub iterations: (usize, usize),
    /// Verdict, reasons, support (with the a-contrario chance test), Sampson noise scale and
    /// the covariance of the rotation and of the translation direction; `iterations` there is
    /// the RANSAC total and `converged` is always true (the refit stops at a stable inlier set
    /// or its round limit).
    pub quality: Quality,
}

/// Checks and undistorts the input; returns the correspondences and their input indices.
fn prepare(
    x1: &[Vector2<f64>],
    x2: &[Vector2<f64>],
    camera: &Camera,
    cfg: &RelativePoseConfig,
) -> Result<(Correspondences, Vec<usize>), GeometryError> {
    camera.validate()?;
    if !(cfg.threshold_px > 0.0 && cfg.confidence > 0.0 && cfg.confidence < 1.0) {
        return Err(GeometryError::InvalidConfig(
            "threshold_px must be > 0 and confidence in (0, 1)".into(),
        ));
    }
    if x1.len() != x2.len() {
        return Err(GeometryError::LengthMismatch(x1.len(), x2.len()));
    }
    if x1.len() < MIN_CORRESPONDENCES {
        return Err(GeometryError::TooFewCorrespondences {
            got: x1.len(),
            need: MIN_CORRESPONDENCES,
        });
    }
    if x1
        .iter()
        .chain(x2)
        .any(|p| !p.iter().all(|v| v.is_finite()))
    {
        return Err(GeometryError::NonFinite);
    }
    let mut data = Correspondences::default();
    let mut index = Vec::with_capacity(x1.len());
    for (i, (a, b)) in x1.iter().zip(x2).enumerate() {
        if let (Some(p), Some(q)) = (camera.pixel_to_normalized(a), camera.pixel_to_normalized(b)) {
            data.push(&p, &q);
            index.push(i);
        }
    }
    if data.len() < MIN_CORRESPONDENCES {
        return Err(GeometryError::TooFewCorrespondences {
            got: data.len(),
            need: MIN_CORRESPONDENCES,
        });
    }
    let spread = |u: &[f64], v: &[f64]| {
        let (u0, v0) = (u[0], v[0]);
        u.iter()
            .zip(v)
            .map(|(a, b)| (a - u0).abs().max((b - v0).abs()))
            .fold(0.0, f64::max)
    };
    if spread(data.u1(), data.v1()) < 1e-12 || spread(data.u2(), data.v2()) < 1e-12 {
        return Err(GeometryError::Degenerate("all points are identical".into()));
    }
    Ok((data, index))
}

/// ORB-SLAM scores `(S_H, S_E)` of the two models over all correspondences.
fn model_scores(
    data: &Correspondences,
    e: Option<&Matrix3<f64>>,
    h: Option<&HomographyModel>,
    sigma: f64,
) -> (f64, f64) {
    let inv_s2 = 1.0 / (sigma * sigma);
    let term = |d2: f64, bound: f64| {
        let c = d2 * inv_s2;
        if c < bound {
            CHI2_2DOF - c
        } else {
            0.0
        }
    };
    let mut s_h = 0.0;
    let mut s_e = 0.0;
    for i in 0..data.len() {
        if let Some(h) = h {
            let (a, b) = transfer_sq(h, data, i);
            s_h += term(a, CHI2_2DOF) + term(b, CHI2_2DOF);
        }
        if let Some(e) = e {
            let (d1, d2) = crate::essential::epipolar_distances_sq(e, &data.p1(i), &data.p2(i));
            s_e += term(d1, CHI2_1DOF) + term(d2, CHI2_1DOF);
        }
    }
    (s_h, s_e)
}

/// `T_21` from a rotation and a translation.
fn isometry(r: &Rotation3<f64>, t: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(*t),
        UnitQuaternion::from_rotation_matrix(r),
    )
}

/// Rays `(x, y, 1)` of both images and the `used` mask for the chirality test.
fn rays(data: &Correspondences) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    (
        (0..data.len()).map(|i| data.ray1(i)).collect(),
        (0..data.len()).map(|i| data.ray2(i)).collect(),
    )
}

/// Estimates `T_21` (unit translation) from pixel correspondences `x1[i] <-> x2[i]` of a
/// calibrated camera; see the module documentation for the pipeline.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector2, Vector3};
/// use vofront_geometry::{Camera, Pinhole};
/// use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};
/// let cam = Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).unwrap());
/// let t21 = Isometry3::new(Vector3::new(0.3, 0.05, 0.1), Vector3::new(0.05, 0.1, 0.02));
/// let (mut x1, mut x2) = (vec![], vec![]);
/// for i in 0..100 {
///     let f = i as f64;
///     let p = Point3::new((f * 0.37).sin() * 2.0, (f * 0.73).cos() * 1.5, 2.0 + (f * 0.51).sin().abs() * 6.0);
///     x1.push(cam.project(&p.coords).unwrap());
///     x2.push(cam.project(&(t21 * p).coords).unwrap());
/// }
/// let rel = estimate_relative_pose(&x1, &x2, &cam, &RelativePoseConfig::default()).unwrap();
/// assert!(rel.rotation.angle_to(&t21.rotation) < 1e-6);
/// assert!((rel.translation - t21.translation.vector.normalize()).norm() < 1e-6);
/// ```
pub fn estimate_relative_pose(
    x1: &[Vector2<f64>],
    x2: &[Vector2<f64>],
    camera: &Camera,
    cfg: &RelativePoseConfig,
) -> Result<RelativePose, GeometryError> {
    let (data, index) = prepare(x1, x2, camera, cfg)?;
    let focal = 0.5 * (camera.pinhole.fx + camera.pinhole.fy);
    let threshold = cfg.threshold_px / focal;
    let rcfg = RansacConfig {
        threshold,
        confidence: cfg.confidence,
        max_iterations: cfg.max_iterations,
        seed: cfg.seed,
        ..RansacConfig::default()
    };
    let ess = ransac(&EssentialEstimator(&data, 0.5 * threshold), &rcfg);
    // The homography only matters if it can compete with the essential matrix: it gets the
    // iterations that find an all-inlier 4-sample when its inlier ratio equals the essential's.
    let h_iterations = ess.as_ref().map_or(cfg.max_iterations, |e| {
        required_iterations(cfg.confidence, e.inlier_count as f64 / data.len() as f64, 4)
    });
    let hcfg = RansacConfig {
        threshold: threshold * H_THRESHOLD_FACTOR,
        max_iterations: h_iterations.max(H_MIN_ITERATIONS).min(cfg.max_iterations),
        ..rcfg
    };
    let hom = ransac(&HomographyEstimator(&data), &hcfg);
    let (s_h, s_e) = model_scores(
        &data,
        ess.as_ref().map(|r| &r.model),
        hom.as_ref().map(|r| &r.model),
        threshold,
    );
    let ratio = if s_h + s_e > 0.0 {
        s_h / (s_h + s_e)
    } else {
        0.0
    };
    let iterations = (
        ess.as_ref().map_or(0, |r| r.iterations),
        hom.as_ref().map_or(0, |r| r.iterations),
    );
    let (b1, b2) = rays(&data);
    let rec_cfg = RecoverConfig {
        far_distance: cfg.far_distance,
    };

    // Candidate motions of the selected model and the correspondences they are tested on.
    let mut model = Model::Essential;
    let mut recovery: Option<PoseRecovery> = None;
    let mut rotation_only: Option<Rotation3<f64>> = None;
    if let Some(h) = hom.as_ref().filter(|_| ratio > cfg.homography_ratio) {
        model = Model::Homography;
        match decompose_homography(&h.model.h) {
            HomographyDecomposition::Motion(c) => {
                let rt: Vec<_> = c.iter().map(|(r, t, _)| (*r, *t)).collect();
                recovery = select_by_chirality(&rt, &b1, &b2, &h.inliers, &rec_cfg);
                rotation_only = Some(nearest_rotation(&h.model.h));
            }
            HomographyDecomposition::Rotation(r) => rotation_only = Some(r),
            HomographyDecomposition::Degenerate => model = Model::Essential,
        }
    }
    if model == Model::Essential {
        let e = ess.as_ref().ok_or(GeometryError::NoModel {
            best: 0,
            need: MIN_CORRESPONDENCES,
        })?;
        recovery = select_by_chirality(
            &decompose_essential(&e.model),
            &b1,
            &b2,
            &e.inliers,
            &rec_cfg,
        );
    }
    // The essential matrix's own motion competes with the homography's after refinement
    // (near-planar scenes: the homography's decomposition may pick the wrong twin).
    let e_recovery = match (model, ess.as_ref()) {
        (Model::Homography, Some(e)) => select_by_chirality(
            &decompose_essential(&e.model),
            &b1,
            &b2,
            &e.inliers,
            &rec_cfg,
        ),
        _ => None,
    };
    let n_in = x1.len();
    let recovered = recovery.as_ref().filter(|r| r.good >= MIN_CORRESPONDENCES);
    // Pure rotation: the rotation-only model `x2 ~ R x1` (from the homography) explains nearly
    // every correspondence the selected model explains.
    let support = match model {
        Model::Homography => hom.as_ref().map_or(0, |h| h.inlier_count),
        Model::Essential => ess.as_ref().map_or(0, |e| e.inlier_count),
    };
    let rotation_support: Vec<usize> = hom.as_ref().map_or(Vec::new(), |h| {
        refine_rotation(
            &data,
            nearest_rotation(&h.model.h),
            threshold * H_THRESHOLD_FACTOR,
        )
        .1
    });
    let pure_rotation = rotation_support.len() as f64 >= ROTATION_SUPPORT * support as f64;
    let rotation_only_case = pure_rotation
        || (recovered.is_none()
            && e_recovery
                .as_ref()
                .map_or(true, |r| r.good < MIN_CORRESPONDENCES));

    let sigma = 0.5 * cfg.threshold_px;
    let hypotheses = quality::ESSENTIAL_SOLUTIONS * iterations.0 + iterations.1;
    let rotation_only_pose = |initial: &[Rotation3<f64>], parallax_deg: f64| {
        // The starting rotation whose refinement explains most correspondences.
        let (rotation, inl) = initial
            .iter()
            .map(|r| refine_rotation(&data, *r, threshold * H_THRESHOLD_FACTOR))
            .max_by_key(|(_, inl)| inl.len())
            .ok_or_else(|| {
                GeometryError::Degenerate("no motion in front of both cameras".into())
            })?;
        if inl.len() < MIN_CORRESPONDENCES {
            return Err(GeometryError::NoModel {
                best: inl.len(),
                need: MIN_CORRESPONDENCES,
            });
        }
        let mut inliers = vec![false; n_in];
        for &k in &inl {
            inliers[index[k]] = true;
        }
        let rotation_model = HomographyModel {
            h: *rotation.matrix(),
            h_inv: rotation.matrix().transpose(),
        };
        let transfer =
            |c: &Correspondences, k: usize| HomographyEstimator(c).residual_sq(&rotation_model, k);
        let h_thr_sq = (threshold * H_THRESHOLD_FACTOR).powi(2);
        let residuals: Vec<f64> = inl
            .iter()
            .map(|&k| transfer(&data, k).sqrt() * focal)
            .collect();
        let evidence = quality::Evidence {
            candidates: n_in,
            inliers: inl.len(),
            tested: data.len(),
            p0: quality::chance_rate(&data, |c, k| transfer(c, k) < h_thr_sq),
            hypotheses: hypotheses as f64,
            sample: ROTATION_SAMPLE,
            sigma_px: vofront_robust::mad_sigma_about_zero(&residuals).unwrap_or(sigma),
            information: None,
            iterations: iterations.0 + iterations.1,
        };
        let flags = [Reason::PureRotation, Reason::LowParallax];
        let pose = isometry(&rotation, &Vector3::zeros());
        Ok(RelativePose {
            rotation: pose.rotation,
            translation: Vector3::zeros(),
            pose,
            model,
            inlier_count: inl.len(),
            inliers,
            points: vec![None; n_in],
            triangulated: 0,
            parallax_deg,
            low_parallax: true,
            pure_rotation: true,
            ambiguous: false,
            alternative: None,
            homography_score_ratio: ratio,
            iterations,
            quality: quality::judge(&evidence, &flags, &cfg.quality),
        })
    };
    if rotation_only_case {
        // Rotation only: from the homography when it explains the data, else from the
        // recovered motion; then least squares on the rotation-only inliers.
        let mut initial: Vec<Rotation3<f64>> = rotation_only.into_iter().collect();
        initial.extend(hom.as_ref().map(|h| nearest_rotation(&h.model.h)));
        initial.extend(recovered.map(|r| r.pose.rotation.to_rotation_matrix()));
        if let Some(e) = &ess {
            initial.extend(decompose_essential(&e.model).iter().step_by(2).map(|c| c.0));
        }
        return rotation_only_pose(&initial, recovered.map_or(0.0, |r| r.median_parallax_deg));
    }
    // Refine each candidate motion on its triangulated correspondences; keep the lowest MSAC
    // Sampson cost over all correspondences.
    let thr_sq = threshold * threshold;
    let est = EssentialEstimator(&data, 0.5 * threshold);
    let mut refined: Vec<(RelState, f64, Model, &PoseRecovery)> = Vec::with_capacity(2);
    let candidates = [
        (recovered, model),
        (
            e_recovery
                .as_ref()
                .filter(|r| r.good >= MIN_CORRESPONDENCES),
            Model::Essential,
        ),
    ];
    for (rec, m) in candidates {
        let Some(rec) = rec else { continue };
        let mut state = (
            rec.pose.rotation.to_rotation_matrix(),
            rec.pose.translation.vector,
        );
        if cfg.refine {
            let used: Vec<usize> = (0..data.len())
                .filter(|&k| rec.points[k].is_some())
                .collect();
            state = refine_relative_pose(&data, &used, focal, sigma, Loss::Huber(1.345), state);
        }
        let e = hat(&state.1) * state.0.matrix();
        let (cost, _) = est.score(&e, thr_sq, f64::INFINITY);
        refined.push((state, cost, m, rec));
    }
    refined.sort_by(|a, b| a.1.total_cmp(&b.1));
    // Nearly equal costs: prefer the motion whose rotation is closest to the least-squares
    // rotation-only fit (the infinite homography), the small-baseline prior of video frames.
    if refined.len() == 2 && refined[1].1 * AMBIGUITY_MARGIN <= refined[0].1 {
        {
            let mut starts = vec![refined[0].0 .0, refined[1].0 .0];
            starts.extend(hom.as_ref().map(|h| nearest_rotation(&h.model.h)));
            let r_inf = starts
                .into_iter()
                .map(|r| refine_rotation(&data, r, threshold * H_THRESHOLD_FACTOR))
                .max_by_key(|(_, inl)| inl.len())
                .map(|(r, _)| r)
                .expect("two starting rotations");
            let q_inf = UnitQuaternion::from_rotation_matrix(&r_inf);
            let dist = |s: &RelState| UnitQuaternion::from_rotation_matrix(&s.0).angle_to(&q_inf);
            if dist(&refined[1].0) < dist(&refined[0].0) {
                refined.swap(0, 1);
            }
        }
    }
    // Not the rotation-only case, so at least one candidate had a recovery to refine.
    let (state, cost, model, rec) = *refined
        .first()
        .ok_or_else(|| GeometryError::Degenerate("no recovered motion to refine".to_string()))?;
    // Two refined motions with nearly equal cost (a plane's twins, or a near-planar scene):
    // report both.
    let rival = refined.get(1).filter(|r| {
        r.1 * AMBIGUITY_MARGIN <= cost
            && cost * AMBIGUITY_MARGIN <= r.1
            && (UnitQuaternion::from_rotation_matrix(&r.0 .0)
                .angle_to(&UnitQuaternion::from_rotation_matrix(&state.0))
                > 1e-3
                || r.0 .1.dot(&state.1) < 0.9998)
    });
    // Final maximum-likelihood refit of the chosen motion with the noise scale estimated from
    // its own residuals.
    let (mut state, mut sigma_px) = (state, sigma);
    if cfg.refine {
        let ml = MlRefineConfig {
            initial_sigma_px: sigma,
            ..MlRefineConfig::default()
        };
        (state, sigma_px) = refine_maximum_likelihood(&data, focal, &ml, state);
    }
    let (ambiguous, alternative) = match rival {
        Some(r) => (true, Some(isometry(&r.0 .0, &r.0 .1))),
        None if 4 * rec.second_good >= 3 * rec.good => (true, rec.runner_up),
        None => (false, None),
    };
    // Final inliers and points from the refined pose.
    let e = hat(&state.1) * state.0.matrix();
    let mask: Vec<bool> = (0..data.len())
        .map(|k| est.residual_sq(&e, k) < thr_sq)
        .collect();
    let final_rec = select_by_chirality(&[(state.0, state.1)], &b1, &b2, &mask, &rec_cfg)
        .ok_or_else(|| GeometryError::Degenerate("refined pose lost chirality".into()))?;
    let used: Vec<usize> = (0..data.len()).filter(|&k| mask[k]).collect();
    if used.len() < MIN_CORRESPONDENCES {
        return Err(GeometryError::NoModel {
            best: used.len(),
            need: MIN_CORRESPONDENCES,
        });
    }
    // The information comes from the correspondences the maximum-likelihood refit used (its
    // `3 sigma` gate), not from the inlier threshold, which may cut into the noise.
    let gate_sq = (MlRefineConfig::default().gate_sigmas * sigma_px / focal).powi(2);
    let gated: Vec<usize> = (0..data.len())
        .filter(|&k| est.residual_sq(&e, k) < gate_sq.max(thr_sq))
        .collect();
    let evidence = quality::Evidence {
        candidates: n_in,
        inliers: used.len(),
        tested: data.len(),
        p0: quality::chance_rate(&data, |c, k| {
            EssentialEstimator(c, 0.0).residual_sq(&e, k) < thr_sq
        }),
        hypotheses: hypotheses as f64,
        sample: MIN_CORRESPONDENCES,
        sigma_px,
        information: Some(sampson_information(&data, &gated, focal, &state)),
        iterations: iterations.0 + iterations.1,
    };
    let low_parallax = final_rec.median_parallax_deg < cfg.min_parallax_deg;
    let flags: Vec<Reason> = [
        (low_parallax, Reason::LowParallax),
        (ambiguous, Reason::PlanarAmbiguous),
    ]
    .into_iter()
    .filter_map(|(on, r)| on.then_some(r))
    .collect();
    let mut inliers = vec![false; n_in];
    let mut points = vec![None; n_in];
    for (k, &i) in index.iter().enumerate() {
        inliers[i] = mask[k];
        points[i] = final_rec.points[k];
    }
    let pose = isometry(&state.0, &state.1);
    Ok(RelativePose {
        rotation: pose.rotation,
        translation: state.1,
        pose,
        model,
        inlier_count: inliers.iter().filter(|&&b| b).count(),
        inliers,
        triangulated: final_rec.good,
        points,
        parallax_deg: final_rec.median_parallax_deg,
        low_parallax,
        pure_rotation: false,
        ambiguous,
        alternative,
        homography_score_ratio: ratio,
        iterations,
        quality: quality::judge(&evidence, &flags, &cfg.quality),
    })
}
