//! Locating a frame in the local map: the matching passes of tracking, shared by the feature
//! trackers.

use nalgebra::{Isometry3, Matrix3, Point3};
use vofront_core::Camera;
use vofront_features::{Features, MatchConfig};
use vofront_geometry::pnp::{PnpConfig, PnpResult};

use crate::odometry::{Located, PointLocator};
use crate::robust::median_in_place;

/// Search window of the retry after a failed tracking attempt (and of relocation into a lost
/// map), in units of [`MapSearch::window_px`].
pub(crate) const WIDE_WINDOW_FACTOR: f32 = 4.0;

/// Whether `again` located the frame with more PnP inliers than `first`.
fn more_inliers(again: &Located, first: &PnpResult) -> bool {
    again
        .fit
        .as_ref()
        .is_ok_and(|fit| fit.inlier_count() > first.inlier_count())
}

/// Median over the inlier `points` of `fit` of `|pi(T_cw P) - pi(T_fit P)|`, pixels: how far
/// the located pose moved the points from where the prediction `t_cw` put them (`None`
/// without a projectable inlier).
fn median_shift_px(
    camera: &Camera,
    points: &[Point3<f64>],
    fit: &PnpResult,
    t_cw: &Isometry3<f64>,
) -> Option<f64> {
    let mut shifts: Vec<f64> = points
        .iter()
        .zip(&fit.inliers)
        .filter(|(_, &inlier)| inlier)
        .filter_map(|(p, _)| {
            let predicted = camera.project(&(t_cw * p).coords)?;
            let found = camera.project(&(fit.pose * p).coords)?;
            Some((predicted - found).norm())
        })
        .collect();
    median_in_place(&mut shifts)
}

/// How a feature tracker searches its local map for the current frame.
pub(crate) struct MapSearch<'a> {
    /// The camera of every frame.
    pub camera: &'a Camera,
    /// Matching filters.
    pub matching: &'a MatchConfig,
    /// PnP RANSAC and refinement.
    pub pnp: &'a PnpConfig,
    /// Search radius around each predicted position, pixels.
    pub window_px: f32,
    /// Search radius of the last pass around the located pose, pixels (`None`: no such pass).
    pub relocate_window_px: Option<f32>,
    /// Fewest PnP inliers for the frame to count as located.
    pub min_inliers: usize,
}

impl MapSearch<'_> {
    /// Locates `current` in the map's points (`query`, `positions`:
    /// [`LocalMap::local_points`](super::LocalMap::local_points)) from the prediction
    /// `predicted` (`T_wc`): matched within `window_px`, then once more within
    /// [`WIDE_WINDOW_FACTOR`] times it if that fails (a motion change the prediction missed,
    /// such as the start of a turn, moves the points out of the window); when the located pose
    /// moved the points by half the window or more, matched again within the window around it
    /// (the first matches were those the window let through, part of the right ones); then the
    /// points are matched again within `relocate_window_px` of the located pose, which takes
    /// fewer wrong candidates and loses fewer right ones to the ratio test. Each later location
    /// replaces the one before when it has more inliers. `covariances`, index-aligned with
    /// `positions`, are the points' own noise ([`PointLocator::locate`]).
    pub fn locate(
        &self,
        query: &Features,
        positions: &[Option<Point3<f64>>],
        covariances: Option<&[Option<Matrix3<f64>>]>,
        current: &Features,
        predicted: Isometry3<f64>,
    ) -> Located {
        let locate = |window_px: f32, prior: Isometry3<f64>| {
            let locator = PointLocator {
                camera: self.camera,
                matching: self.matching,
                window_px,
                pnp: self.pnp,
                min_inliers: self.min_inliers,
            };
            locator.locate(query, positions, covariances, current, prior)
        };
        let mut located = locate(self.window_px, predicted.inverse());
        if located.fit.is_err() {
            located = locate(self.window_px * WIDE_WINDOW_FACTOR, predicted.inverse());
        }
        // A pose that moved the points by half the window or more was found from the matches
        // the window let through, which can be a part of the right ones biased towards the
        // prediction; matched again within the window around it, they are all inside.
        if let Ok(first) = &located.fit {
            let moved = median_shift_px(self.camera, &located.points, first, &predicted.inverse());
            if moved.is_some_and(|px| px >= 0.5 * f64::from(self.window_px)) {
                let again = locate(self.window_px, first.pose);
                if more_inliers(&again, first) {
                    located = again;
                }
            }
        }
        if let (Some(radius), Ok(first)) = (self.relocate_window_px, &located.fit) {
            let again = locate(radius, first.pose);
            if more_inliers(&again, first) {
                located = again;
            }
        }
        located
    }
}
