//! Locating a frame in the local map: the matching passes of tracking, and the late location
//! of the frames an initialisation waited through.

use nalgebra::{Isometry3, Point3};
use vofront_features::Features;
use vofront_geometry::pnp::PnpResult;
use vofront_geometry::Camera;

use super::map::LocalMap;
use super::{MonoTracker, WIDE_WINDOW_FACTOR};
use crate::odometry::late::Waiting;
use crate::odometry::{FrameEstimate, FrameQuality, Located, PointLocator, TrackStatus};
use crate::robust::median_in_place;

/// The message of a frame located after the initialisation it waited for.
const LATE_MESSAGE: &str = "located once the map was initialised (waited for parallax)";

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

impl MonoTracker {
    /// Locates `current` in the map's points (`query`, `positions`: [`LocalMap::local_points`])
    /// from the prediction `predicted` (`T_wc`): matched within `window_px`, then once more
    /// within `WIDE_WINDOW_FACTOR` times it if that fails (a motion change the prediction
    /// missed, such as the start of a turn, moves the points out of the window); when the
    /// located pose moved the points by half the window or more, matched again within the
    /// window around it (the first matches were those the window let through, part of the
    /// right ones); then the points are matched again within `relocate_window_px` of the
    /// located pose, which takes fewer wrong candidates and loses fewer right ones to the
    /// ratio test. Each later location replaces the one before when it has more inliers.
    pub(super) fn locate_in_map(
        &self,
        query: &Features,
        positions: &[Option<Point3<f64>>],
        current: &Features,
        predicted: Isometry3<f64>,
    ) -> Located {
        let locate = |window_px: f32, prior: Isometry3<f64>| {
            let locator = PointLocator {
                camera: &self.camera,
                matching: &self.cfg.matching,
                window_px,
                pnp: &self.cfg.pnp,
                min_inliers: self.cfg.min_inliers,
            };
            locator.locate(query, positions, current, prior)
        };
        let mut located = locate(self.cfg.window_px, predicted.inverse());
        if located.fit.is_err() {
            located = locate(self.cfg.window_px * WIDE_WINDOW_FACTOR, predicted.inverse());
        }
        // A pose that moved the points by half the window or more was found from the matches
        // the window let through, which can be a part of the right ones biased towards the
        // prediction; matched again within the window around it, they are all inside.
        if let Ok(first) = &located.fit {
            let moved = median_shift_px(&self.camera, &located.points, first, &predicted.inverse());
            if moved.is_some_and(|px| px >= 0.5 * f64::from(self.cfg.window_px)) {
                let again = locate(self.cfg.window_px, first.pose);
                if more_inliers(&again, first) {
                    located = again;
                }
            }
        }
        if let (Some(radius), Ok(first)) = (self.cfg.relocate_window_px, &located.fit) {
            let again = locate(radius, first.pose);
            if more_inliers(&again, first) {
                located = again;
            }
        }
        located
    }

    /// The frames an initialisation waited through (`waiting`: their features, the reference
    /// being at `t_w1`), located in the new `map` whose current frame `now` is at `t_wn`: each
    /// from the pose its index places on the way between the two ([`Waiting::locate`]), as a
    /// tracked frame is. Returns `(frames back from now, estimate)` for those located; the
    /// others stay lost.
    pub(super) fn locate_waited(
        &self,
        map: &LocalMap,
        waiting: &Waiting<Features>,
        t_w1: &Isometry3<f64>,
        now: (usize, &Isometry3<f64>),
        size: (usize, usize),
    ) -> Vec<(usize, FrameEstimate)> {
        let scale_factor = self.cfg.orb.scale_factor;
        waiting.locate(t_w1, now, |features, predicted, start| {
            let (query, positions, _) =
                map.project_points(&self.camera, &predicted.inverse(), size, scale_factor);
            let located = self.locate_in_map(&query, &positions, features, predicted);
            let fit = located.fit.ok()?;
            let quality = FrameQuality::of_pnp(&fit, located.matches.len());
            let estimate = Self::estimate(
                fit.pose.inverse(),
                TrackStatus::Ok,
                quality,
                Some(LATE_MESSAGE.into()),
                start,
            );
            Some(estimate.judged(fit.quality))
        })
    }
}
