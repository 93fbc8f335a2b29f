//! Step 3 of the pipeline, pose recovery: the four factorisations of `E` (or up to eight of
//! `H`) are triangulated on the model's inliers and the one with most points in front of both
//! cameras and closer than the far limit is kept ([`select_by_chirality`]).

use nalgebra::{Rotation3, Vector3};

use super::prepare::{TwoView, MIN_CORRESPONDENCES};
use super::rotation::{homography_rotation, nearest_rotation};
use super::select::Selection;
use super::types::Model;
use crate::error::GeometryError;
use crate::essential::{decompose_essential, select_by_chirality, PoseRecovery};
use crate::homography::{decompose_homography, HomographyDecomposition};

/// The recovered motions of the selected model.
pub(super) struct Recovery {
    /// The model the motion comes from.
    pub model: Model,
    /// The selected model's motion.
    pub selected: Option<PoseRecovery>,
    /// When the homography was selected, the essential matrix's own motion, which competes with
    /// it after refinement (near-planar scenes: the homography's decomposition may pick the
    /// wrong twin).
    pub essential: Option<PoseRecovery>,
    /// The rotation the homography implies when it was selected (a rotation, or the nearest
    /// rotation to `H`).
    pub rotation: Option<Rotation3<f64>>,
}

impl Recovery {
    /// The selected motion, when it has at least five good points.
    pub fn selected(&self) -> Option<&PoseRecovery> {
        supported(self.selected.as_ref())
    }

    /// The essential matrix's competing motion, when it has at least five good points.
    pub fn competing(&self) -> Option<&PoseRecovery> {
        supported(self.essential.as_ref())
    }

    /// Neither motion has enough points in front of both cameras.
    pub fn has_no_motion(&self) -> bool {
        self.selected().is_none() && self.competing().is_none()
    }

    /// Starting rotations of the rotation-only fit, in order of preference: the homography's
    /// rotation when it was selected, the rotation nearest to the homography, the selected
    /// motion's rotation, and the two rotations of the essential matrix.
    pub fn rotation_starts(&self, sel: &Selection) -> Vec<Rotation3<f64>> {
        let mut starts: Vec<Rotation3<f64>> = self.rotation.into_iter().collect();
        starts.extend(homography_rotation(sel));
        starts.extend(
            self.selected()
                .map(|r| r.pose.rotation.to_rotation_matrix()),
        );
        if let Some(e) = &sel.essential {
            starts.extend(decompose_essential(&e.model).iter().step_by(2).map(|c| c.0));
        }
        starts
    }
}

/// `rec` when it has at least five good points.
fn supported(rec: Option<&PoseRecovery>) -> Option<&PoseRecovery> {
    rec.filter(|r| r.good >= MIN_CORRESPONDENCES)
}

/// Recovers the motion of the preferred model (the homography when the score ratio says so
/// and it decomposes, else the essential matrix); [`GeometryError::NoModel`] when neither
/// model was found.
pub(super) fn recover_motion(tv: &TwoView, sel: &Selection) -> Result<Recovery, GeometryError> {
    let (b1, b2) = tv.rays();
    let rec_cfg = tv.recover_config();
    let chirality = |candidates: &[(Rotation3<f64>, Vector3<f64>)], inliers: &[bool]| {
        select_by_chirality(candidates, &b1, &b2, inliers, &rec_cfg)
    };
    let mut out = Recovery {
        model: Model::Essential,
        selected: None,
        essential: None,
        rotation: None,
    };
    if let Some(h) = sel.preferred_homography(tv.cfg.homography_ratio) {
        out.model = Model::Homography;
        match decompose_homography(&h.model.h) {
            HomographyDecomposition::Motion(c) => {
                let rt: Vec<_> = c.iter().map(|(r, t, _)| (*r, *t)).collect();
                out.selected = chirality(&rt, &h.inliers);
                out.rotation = Some(nearest_rotation(&h.model.h));
            }
            HomographyDecomposition::Rotation(r) => out.rotation = Some(r),
            HomographyDecomposition::Degenerate => out.model = Model::Essential,
        }
    }
    let essential = sel.essential.as_ref();
    if out.model == Model::Essential {
        let e = essential.ok_or(GeometryError::NoModel {
            best: 0,
            need: MIN_CORRESPONDENCES,
        })?;
        out.selected = chirality(&decompose_essential(&e.model), &e.inliers);
    } else if let Some(e) = essential {
        out.essential = chirality(&decompose_essential(&e.model), &e.inliers);
    }
    Ok(out)
}
