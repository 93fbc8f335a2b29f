//! Locating a frame in the local map ([`MapSearch`]), and the late location of the frames an
//! initialisation waited through.

use nalgebra::{Isometry3, Point3};
use vofront_features::Features;

use super::MonoTracker;
use crate::odometry::late::Waiting;
use crate::odometry::local_map::{LocalMap, MapSearch};
use crate::odometry::{FrameEstimate, FrameQuality, Located, TrackStatus};

/// The message of a frame located after the initialisation it waited for.
const LATE_MESSAGE: &str = "located once the map was initialised (waited for parallax)";

impl MonoTracker {
    /// Locates `current` in the map's points from the prediction `predicted` (`T_wc`) with
    /// the tracker's windows ([`MapSearch::locate`]).
    pub(super) fn locate_in_map(
        &self,
        query: &Features,
        positions: &[Option<Point3<f64>>],
        current: &Features,
        predicted: Isometry3<f64>,
    ) -> Located {
        let search = MapSearch {
            camera: &self.camera,
            matching: &self.cfg.matching,
            pnp: &self.cfg.pnp,
            window_px: self.cfg.window_px,
            relocate_window_px: self.cfg.relocate_window_px,
            min_inliers: self.cfg.min_inliers,
        };
        search.locate(query, positions, None, current, predicted)
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
