//! Step 4 of the pipeline, refinement: each recovered motion is refined on its triangulated
//! correspondences (Huber IRLS on the Sampson distance, [`refine_relative_pose`]); the lowest
//! MSAC Sampson cost over all correspondences wins, and the winner gets the
//! maximum-likelihood refit ([`refine_maximum_likelihood`]).
//!
//! Two refined motions whose costs are within 5% are a tie: the one whose rotation is closest
//! to the least-squares rotation-only fit (the infinite homography, the small-baseline prior
//! of video frames) wins, and both are reported (`ambiguous`, `alternative`). Both are
//! reported too when the cheaper motion puts under 3/4 as many of their shared inliers in
//! front of both cameras as the other.

use nalgebra::UnitQuaternion;
use vofront_robust::Loss;

use super::estimators::EssentialEstimator;
use super::prepare::TwoView;
use super::recover::Recovery;
use super::refine::{refine_maximum_likelihood, refine_relative_pose, MlRefineConfig, RelState};
use super::rotation::{homography_rotation, refine_rotation};
use super::select::Selection;
use super::types::{isometry, Model};
use crate::error::GeometryError;
use crate::essential::{best_by_chirality, PoseRecovery, RecoverConfig};
use crate::lie::hat;
use crate::ransac::Estimator;
use nalgebra::Isometry3;

/// Two refined motions whose MSAC costs are within this factor are reported as ambiguous.
const AMBIGUITY_MARGIN: f64 = 0.95;

/// The refined motion and how sure the choice was.
pub(super) struct Chosen {
    /// `(R, t)`, unit `t`.
    pub state: RelState,
    /// Noise scale of the Sampson distance, pixels (estimated by the refit when it ran).
    pub sigma_px: f64,
    /// The model the motion comes from.
    pub model: Model,
    /// Two motions explain the data about equally.
    pub ambiguous: bool,
    /// The other motion when `ambiguous`.
    pub alternative: Option<Isometry3<f64>>,
}

/// A refined candidate: its state, MSAC cost, model and recovery.
type Candidate<'a> = (RelState, f64, Model, &'a PoseRecovery);

/// Refines the recovered motions and chooses one; [`GeometryError::Degenerate`] when there is
/// none to refine.
pub(super) fn refine_and_choose<'a>(
    tv: &TwoView,
    sel: &Selection,
    rec: &'a Recovery,
) -> Result<Chosen, GeometryError> {
    let (data, cfg) = (&tv.data, tv.cfg);
    let est = EssentialEstimator(data, 0.5 * tv.threshold);
    let refine = |candidate: &'a PoseRecovery, model: Model| -> Candidate<'a> {
        let mut state = (
            candidate.pose.rotation.to_rotation_matrix(),
            candidate.pose.translation.vector,
        );
        if cfg.refine {
            let used: Vec<usize> = (0..data.len())
                .filter(|&k| candidate.points[k].is_some())
                .collect();
            let huber = Loss::Huber(1.345);
            state = refine_relative_pose(data, &used, tv.focal, tv.sigma_px, huber, state);
        }
        let e = hat(&state.1) * state.0.matrix();
        let (cost, _) = est.score(&e, tv.threshold * tv.threshold, f64::INFINITY);
        (state, cost, model, candidate)
    };
    // The two candidates are refined at once.
    let (selected, competing) = rayon::join(
        || rec.selected().map(|c| refine(c, rec.model)),
        || rec.competing().map(|c| refine(c, Model::Essential)),
    );
    let mut refined: Vec<Candidate> = [selected, competing].into_iter().flatten().collect();
    refined.sort_by(|a, b| a.1.total_cmp(&b.1));
    if refined.len() == 2 && refined[1].1 * AMBIGUITY_MARGIN <= refined[0].1 {
        prefer_rotation_prior(tv, sel, &mut refined);
    }
    let (state, cost, model, chosen) = *refined
        .first()
        .ok_or_else(|| GeometryError::Degenerate("no recovered motion to refine".to_string()))?;
    // Two refined motions with nearly equal cost (a plane's twins, or a near-planar scene), or
    // a cheaper one that puts more points behind a camera ([`fewer_in_front`]): report both.
    let rival = refined.get(1).filter(|r| {
        (r.1 * AMBIGUITY_MARGIN <= cost || fewer_in_front(tv, &state, &r.0))
            && (UnitQuaternion::from_rotation_matrix(&r.0 .0)
                .angle_to(&UnitQuaternion::from_rotation_matrix(&state.0))
                > 1e-3
                || r.0 .1.dot(&state.1) < 0.9998)
    });
    // Final maximum-likelihood refit of the chosen motion with the noise scale estimated from
    // its own residuals.
    let (mut state, mut sigma_px) = (state, tv.sigma_px);
    if cfg.refine {
        let ml = MlRefineConfig {
            initial_sigma_px: tv.sigma_px,
            ..MlRefineConfig::default()
        };
        (state, sigma_px) = refine_maximum_likelihood(data, tv.focal, &ml, state);
    }
    let (ambiguous, alternative) = match rival {
        Some(r) => (true, Some(isometry(&r.0 .0, &r.0 .1))),
        None if 4 * chosen.second_good >= 3 * chosen.good => (true, chosen.runner_up),
        None => (false, None),
    };
    Ok(Chosen {
        state,
        sigma_px,
        model,
        ambiguous,
        alternative,
    })
}

/// Whether `winner` puts fewer than 3/4 as many of the two states' shared inliers (Sampson
/// distance under the threshold for both) in front of both cameras as `other` does, with no
/// far limit. A plane's points fit the wrong twin of its motion about as well as the true one
/// by the Sampson distance, and a search that polished its essential matrix less can leave
/// that twin a few percent cheaper; but the wrong twin puts part of the plane behind a camera.
fn fewer_in_front(tv: &TwoView, winner: &RelState, other: &RelState) -> bool {
    let est = EssentialEstimator(&tv.data, 0.5 * tv.threshold);
    let thr_sq = tv.threshold * tv.threshold;
    let essential = |s: &RelState| hat(&s.1) * s.0.matrix();
    let (e_w, e_o) = (essential(winner), essential(other));
    let shared: Vec<bool> = (0..tv.data.len())
        .map(|k| est.residual_sq(&e_w, k) < thr_sq && est.residual_sq(&e_o, k) < thr_sq)
        .collect();
    let (x1, x2) = tv.rays();
    let anywhere = RecoverConfig {
        far_distance: f64::INFINITY,
    };
    let in_front = |s: &RelState| {
        best_by_chirality(&[(s.0, s.1)], &x1, &x2, &shared, &anywhere).map_or(0, |(_, n)| n)
    };
    4 * in_front(winner) < 3 * in_front(other)
}

/// Of two tied candidates (sorted by cost), puts first the one whose rotation is closest to
/// the least-squares rotation-only fit that explains most correspondences.
fn prefer_rotation_prior(tv: &TwoView, sel: &Selection, refined: &mut [Candidate]) {
    let mut starts = vec![refined[0].0 .0, refined[1].0 .0];
    starts.extend(homography_rotation(sel));
    let Some(r_inf) = starts
        .into_iter()
        .map(|r| refine_rotation(&tv.data, r, tv.transfer_threshold()))
        .max_by_key(|(_, inl)| inl.len())
        .map(|(r, _)| r)
    else {
        return;
    };
    let q_inf = UnitQuaternion::from_rotation_matrix(&r_inf);
    let dist = |s: &RelState| UnitQuaternion::from_rotation_matrix(&s.0).angle_to(&q_inf);
    if dist(&refined[1].0) < dist(&refined[0].0) {
        refined.swap(0, 1);
    }
}
