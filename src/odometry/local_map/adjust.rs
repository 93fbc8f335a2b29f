//! Local bundle adjustment of the window, shared by the monocular and stereo trackers.
//!
//! The window's keyframe poses `T_cw` and every point observed by two or more of them are
//! refined together on robust reprojection errors by [`vofront_geometry::bundle`]: cost
//! `sum_o s^2 rho(|r_o| / s)` with `r_o` the pixel error `pi(T_i P_j) - u_o` (and, for a
//! stereo observation, the right column's error: ORB-SLAM2's `(u_l, v_l, u_r)` residual), each
//! divided by its keypoint's level scale, the points eliminated by the Schur complement. The
//! oldest keyframes are held fixed (the gauge). Observations beyond the adjustment's
//! chi-square gate are unlinked from their points; points left with no observation are
//! removed.

use vofront_core::Camera;
use vofront_geometry::bundle::{bundle_adjust, BundleConfig, BundleProblem, Observation};

use super::{level_sigma, LocalMap, PointId};
use crate::odometry::feature_pixel;

/// What one local adjustment did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Adjusted {
    /// Points refined.
    pub points: usize,
    /// Observations unlinked as outliers.
    pub culled: usize,
    /// Reprojection rmse of the final solve, pixels.
    pub rmse_px: f64,
}

impl LocalMap {
    /// Runs the local bundle adjustment (see the module documentation) with the
    /// `cfg.fixed_poses` oldest keyframes held and writes the refined poses and points back;
    /// with a stereo `baseline` (metres), the features with a right column
    /// (`MapKeyframe::right`) are stereo observations. `None` (map
    /// unchanged) when the window has no free keyframe, the adjustment fails (too few
    /// observations, a degenerate system) or it would unlink more than half of the newest
    /// keyframe's observations.
    pub fn adjust_window(
        &mut self,
        camera: &Camera,
        baseline: Option<f64>,
        cfg: &BundleConfig,
    ) -> Option<Adjusted> {
        if self.keyframes.len() <= cfg.fixed_poses {
            return None;
        }
        let mut ids: Vec<PointId> = self
            .points
            .iter()
            .filter(|(_, p)| p.observations.len() >= 2)
            .map(|(&id, _)| id)
            .collect();
        ids.sort_unstable();
        let mut problem = BundleProblem {
            camera: *camera,
            poses: self.keyframes.iter().map(|k| k.t_wc.inverse()).collect(),
            points: ids.iter().map(|id| self.points[id].position).collect(),
            observations: Vec::new(),
            baseline,
        };
        // (point id, keyframe id, feature) of each observation, in the problem's order.
        let mut links = Vec::new();
        for (j, id) in ids.iter().enumerate() {
            for &(kid, f) in &self.points[id].observations {
                let Some(pose) = self.index_of(kid) else {
                    continue;
                };
                let kf = &self.keyframes[pose];
                let features = &kf.features;
                problem.observations.push(Observation {
                    pose,
                    point: j,
                    pixel: feature_pixel(features, f),
                    sigma: level_sigma(features, f),
                    right: baseline.and(kf.right.get(f as usize).copied().flatten()),
                });
                links.push((*id, kid, f));
            }
        }
        let report = bundle_adjust(&mut problem, cfg).ok()?;
        // The newest keyframe was accepted on its PnP consensus: an adjustment that calls most
        // of its observations outliers contradicts the evidence that made it (a collapsed
        // gate, a degenerate window) and is not applied.
        let newest = self.keyframes.back().map(|k| k.id);
        let of_newest = |o: &usize| Some(links[*o].1) == newest;
        let newest_links = (0..links.len()).filter(of_newest).count();
        let newest_culled = report.culled.iter().filter(|o| of_newest(o)).count();
        if 2 * newest_culled > newest_links {
            return None;
        }
        for (kf, t_cw) in self.keyframes.iter_mut().zip(&problem.poses) {
            kf.t_wc = t_cw.inverse();
        }
        for (id, position) in ids.iter().zip(&problem.points) {
            if let Some(p) = self.points.get_mut(id) {
                p.position = *position;
            }
        }
        for &o in &report.culled {
            let (id, kid, f) = links[o];
            self.unobserve(id, kid, f);
            if self
                .points
                .get(&id)
                .is_some_and(|p| p.observations.is_empty())
            {
                self.remove_point(id);
            }
        }
        Some(Adjusted {
            points: ids.len(),
            culled: report.culled.len(),
            rmse_px: report.rmse_px,
        })
    }
}
