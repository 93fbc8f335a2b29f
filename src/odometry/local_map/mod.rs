//! The local map of the feature trackers (`mono`, `stereo`): a window of recent keyframes and
//! the points they observe, each point with its representative descriptor and its
//! observations; [`MapSearch`] locates a frame in it.
//!
//! - Tracking uses every point observed by a keyframe of the window (the covisible set of the
//!   current keyframe), not only the last keyframe's. A point is matched with its
//!   representative descriptor and with the one it was last found with, the closer of the two
//!   kept, and matches are one to one between points and keypoints.
//! - A new keyframe adds observations to the points it tracked and gets new points: a stereo
//!   keyframe from its own stereo matches ([`LocalMap::add_point`]), a monocular one by
//!   triangulating its unassigned features matched to those of the previous keyframes (DLT,
//!   checked for cheirality, parallax and reprojection error); then the map refines the structure: each point
//!   observed by two or more window keyframes is moved to minimise
//!   `sum_k |pi(K T_ck_w P) - u_k|^2 / s_k^2` by Levenberg-Marquardt from a Gauss-Newton step
//!   (poses fixed, `s_k` the observation's noise scale).
//! - Culling drops points found in under a quarter of the frames that should have seen them,
//!   points that no longer fit their observations, and points no window keyframe observes.

use std::collections::{HashMap, VecDeque};

use nalgebra::{Isometry3, Matrix3, Point3, Vector2, Vector3};
use vofront_core::Camera;
use vofront_features::{match_descriptors, Descriptor, Feature, Features, Match, MatchConfig};
use vofront_geometry::triangulate::{parallax_deg, triangulate_dlt};
use vofront_robust::{levenberg_marquardt, LmConfig, LmError};

use crate::odometry::feature_pixel;

mod adjust;
mod locate;
mod point_views;
#[cfg(test)]
mod tests;

pub(crate) use adjust::Adjusted;
pub(crate) use locate::{MapSearch, WIDE_WINDOW_FACTOR};
use point_views::{PointViews, POINT_LM};

/// Identifier of a map point.
pub(crate) type PointId = usize;

/// A triangulated point.
#[derive(Debug, Clone)]
pub(crate) struct MapPoint {
    /// World position (map units).
    pub position: Point3<f64>,
    /// The observation's descriptor with the smallest total distance to the others.
    pub descriptor: Descriptor,
    /// Pyramid level of that observation.
    pub level: u8,
    /// Its descriptor in the newest frame that tracked it (a PnP inlier there), matched by
    /// tracking beside `descriptor`: a near point changes its look within a few frames, and
    /// the next frame sees it most like the last one did (ORB-SLAM2 tracks the last frame
    /// first for this reason).
    pub recent: Option<Descriptor>,
    /// Distance from that observation's camera centre to the point, map units: a camera at
    /// another distance `d` sees it about `log(distance / d) / log(scale_factor)` levels
    /// higher ([`predicted_level`]).
    pub distance: f64,
    /// `(keyframe id, feature index)` of every observation.
    pub observations: Vec<(usize, u32)>,
    /// Covariance of `position` (world frame, map units squared) when known: a stereo
    /// point's depth noise along its ray, kept through structure refinement (an upper
    /// bound then); `None` for triangulated points.
    pub covariance: Option<Matrix3<f64>>,
    /// Frames in whose image the point was predicted.
    pub visible: u32,
    /// Frames in which it was matched and a PnP inlier.
    pub found: u32,
}

/// A keyframe of the window.
#[derive(Debug, Clone)]
pub(crate) struct MapKeyframe {
    /// Unique, increasing id.
    pub id: usize,
    /// Index of the frame it was made from (frames given to the tracker, from 0).
    pub frame: usize,
    /// Camera-to-world pose.
    pub t_wc: Isometry3<f64>,
    /// Its ORB features.
    pub features: Features,
    /// The map point of each feature.
    pub point_of: Vec<Option<PointId>>,
    /// Column of each feature in the right image of a rectified stereo rig, pixels (`None`:
    /// not matched; empty for a monocular keyframe).
    pub right: Vec<Option<f64>>,
}

impl MapKeyframe {
    /// Camera centre in the world.
    pub fn centre(&self) -> Point3<f64> {
        Point3::from(self.t_wc.translation.vector)
    }
}

/// Thresholds of map maintenance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MapRules {
    /// Keyframes kept in the window.
    pub window: usize,
    /// Keyframes before the newest one that new points are triangulated against.
    pub triangulation_neighbours: usize,
    /// Largest reprojection error of a point in any observation, pixels.
    pub max_reprojection_px: f64,
    /// Smallest parallax of a new point, degrees.
    pub min_point_parallax_deg: f64,
}

/// Keyframes and points; see the module documentation.
#[derive(Debug, Clone, Default)]
pub(crate) struct LocalMap {
    /// Window of keyframes, oldest first.
    pub keyframes: VecDeque<MapKeyframe>,
    /// The points by id.
    pub points: HashMap<PointId, MapPoint>,
    next_point: PointId,
    next_keyframe: usize,
}

/// Smallest `found / visible` of a point seen at least [`CULL_MIN_VISIBLE`] times.
const CULL_MIN_FOUND_RATIO: f64 = 0.25;
/// Predictions before the found ratio is judged.
const CULL_MIN_VISIBLE: u32 = 4;

impl LocalMap {
    /// The position of every point, world frame (map units).
    pub fn world_points(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        self.points.values().map(|p| p.position)
    }

    /// The newest keyframe.
    pub fn last(&self) -> Option<&MapKeyframe> {
        self.keyframes.back()
    }

    /// Distance between the camera centres of the two newest keyframes (map units); `None`
    /// with fewer than two.
    pub fn baseline(&self) -> Option<f64> {
        let n = self.keyframes.len();
        let (a, b) = (
            self.keyframes.get(n.checked_sub(2)?)?,
            self.keyframes.get(n - 1)?,
        );
        Some((a.centre() - b.centre()).norm())
    }

    /// Adds a keyframe made from frame `frame` with no points yet; returns its index in the
    /// window.
    pub fn push_keyframe(
        &mut self,
        t_wc: Isometry3<f64>,
        features: Features,
        frame: usize,
    ) -> usize {
        let n = features.len();
        self.keyframes.push_back(MapKeyframe {
            id: self.next_keyframe,
            frame,
            t_wc,
            features,
            point_of: vec![None; n],
            right: Vec::new(),
        });
        self.next_keyframe += 1;
        self.keyframes.len() - 1
    }

    /// A new point at `position` observed by `(window index, feature)` pairs (the first gives
    /// its descriptor), returned; nothing without observations.
    pub fn add_point(
        &mut self,
        position: Point3<f64>,
        observed: &[(usize, u32)],
    ) -> Option<PointId> {
        let &(k0, f0) = observed.first()?;
        let id = self.next_point;
        self.next_point += 1;
        let kf0 = &self.keyframes[k0];
        let mut point = MapPoint {
            position,
            descriptor: kf0.features.descriptors()[f0 as usize],
            level: kf0.features.levels()[f0 as usize],
            recent: None,
            distance: (position - kf0.centre()).norm(),
            observations: Vec::with_capacity(observed.len()),
            covariance: None,
            visible: 1,
            found: 1,
        };
        for &(k, f) in observed {
            let kf = &mut self.keyframes[k];
            kf.point_of[f as usize] = Some(id);
            point.observations.push((kf.id, f));
        }
        self.points.insert(id, point);
        Some(id)
    }

    /// Records that `point` is observed by feature `f` of the keyframe at window index `k`.
    pub fn observe(&mut self, point: PointId, k: usize, f: u32) {
        let kf = &mut self.keyframes[k];
        if kf.point_of[f as usize].is_some() {
            return;
        }
        if let Some(p) = self.points.get_mut(&point) {
            kf.point_of[f as usize] = Some(point);
            p.observations.push((kf.id, f));
        }
    }

    /// Window index of keyframe `id`.
    pub fn index_of(&self, id: usize) -> Option<usize> {
        let first = self.keyframes.front()?.id;
        let k = id.checked_sub(first)?;
        (k < self.keyframes.len()).then_some(k)
    }

    /// Points observed by a window keyframe, as a feature list for matching (positions: the
    /// points' predicted pixels under `t_cw`, NaN when not in front; levels: the pyramid level
    /// each is expected at from that camera, [`predicted_level`] with the ORB `scale_factor`),
    /// their world positions and the point id of each entry. A point tracked since its
    /// representative descriptor was chosen has a second entry right after the first, with its
    /// [`MapPoint::recent`] descriptor (the locator keeps the closer of the two matches).
    /// Every point predicted inside the `width x height` image counts as visible.
    pub fn local_points(
        &mut self,
        camera: &Camera,
        t_cw: &Isometry3<f64>,
        size: (usize, usize),
        scale_factor: f32,
    ) -> (Features, Vec<Option<Point3<f64>>>, Vec<PointId>) {
        let (query, positions, ids) = self.project_points(camera, t_cw, size, scale_factor);
        let mut counted = None;
        for (id, x) in ids.iter().zip(query.xs()) {
            if counted == Some(id) {
                continue;
            }
            counted = Some(id);
            if let (true, Some(p)) = (x.is_finite(), self.points.get_mut(id)) {
                p.visible += 1;
            }
        }
        (query, positions, ids)
    }

    /// The covariance of each point of `ids` ([`MapPoint::covariance`]; `None` for a point
    /// without one or no longer in the map), index-aligned with `ids`.
    pub fn covariances(&self, ids: &[PointId]) -> Vec<Option<Matrix3<f64>>> {
        ids.iter()
            .map(|id| self.points.get(id).and_then(|p| p.covariance))
            .collect()
    }

    /// [`Self::local_points`] without counting the points as visible (a trial location).
    pub fn project_points(
        &self,
        camera: &Camera,
        t_cw: &Isometry3<f64>,
        (width, height): (usize, usize),
        scale_factor: f32,
    ) -> (Features, Vec<Option<Point3<f64>>>, Vec<PointId>) {
        let centre = t_cw.inverse() * Point3::origin();
        let mut sorted: Vec<PointId> = self.points.keys().copied().collect();
        sorted.sort_unstable();
        let mut query = Features::default();
        let mut positions = Vec::with_capacity(sorted.len());
        let mut ids = Vec::with_capacity(sorted.len());
        for id in sorted {
            let p = &self.points[&id];
            let x = t_cw * p.position;
            let uv = (x.z > 0.0)
                .then(|| camera.project(&x.coords))
                .flatten()
                .filter(|u| u.x >= 0.0 && u.y >= 0.0 && u.x < width as f64 && u.y < height as f64);
            let recent = p.recent.filter(|d| uv.is_some() && *d != p.descriptor);
            let (u, v) = uv.map_or((f32::NAN, f32::NAN), |u| (u.x as f32, u.y as f32));
            let level = predicted_level(p, (p.position - centre).norm(), scale_factor);
            for descriptor in std::iter::once(p.descriptor).chain(recent) {
                // Windowed matching reads only positions, levels and descriptors of the query.
                query.push(Feature {
                    x: u,
                    y: v,
                    level,
                    scale: 1.0,
                    angle: 0.0,
                    response: 0.0,
                    descriptor,
                });
                positions.push(Some(p.position));
                ids.push(id);
            }
        }
        (query, positions, ids)
    }

    /// The PnP inliers of a location as `(match, point, position)`: `matches[i]` (query = a
    /// local point's index in `ids`, train = a feature of `current`) with its position
    /// `world[i]`, kept where `inliers[i]`; each of their points is marked found and takes the
    /// descriptor it was found with as its [`MapPoint::recent`].
    pub fn keep_inliers(
        &mut self,
        current: &Features,
        matches: &[Match],
        world: &[Point3<f64>],
        inliers: &[bool],
        ids: &[PointId],
    ) -> Vec<(Match, PointId, Point3<f64>)> {
        let tracked: Vec<(Match, PointId, Point3<f64>)> = matches
            .iter()
            .zip(world)
            .zip(inliers)
            .filter(|(_, inlier)| **inlier)
            .map(|((m, p), _)| (*m, ids[m.query as usize], *p))
            .collect();
        for (m, id, _) in &tracked {
            if let Some(p) = self.points.get_mut(id) {
                p.found += 1;
                p.recent = Some(current.descriptors()[m.train as usize]);
            }
        }
        tracked
    }

    /// Triangulates new points between the newest keyframe and up to `rules.triangulation_
    /// neighbours` before it, from features of both that have no point yet.
    pub fn triangulate_new(&mut self, camera: &Camera, matching: &MatchConfig, rules: &MapRules) {
        let Some(newest) = self.keyframes.len().checked_sub(1) else {
            return;
        };
        let first = newest.saturating_sub(rules.triangulation_neighbours);
        for other in (first..newest).rev() {
            let free = |kf: &MapKeyframe| -> Vec<u32> {
                (0..kf.features.len() as u32)
                    .filter(|&f| kf.point_of[f as usize].is_none())
                    .collect()
            };
            let (a, b) = (&self.keyframes[other], &self.keyframes[newest]);
            let (free_a, free_b) = (free(a), free(b));
            let da: Vec<Descriptor> = free_a
                .iter()
                .map(|&f| a.features.descriptors()[f as usize])
                .collect();
            let db: Vec<Descriptor> = free_b
                .iter()
                .map(|&f| b.features.descriptors()[f as usize])
                .collect();
            let t_ba = b.t_wc.inverse() * a.t_wc;
            let mut new_points = Vec::new();
            for m in match_descriptors(&da, &db, matching) {
                let (fa, fb) = (free_a[m.query as usize], free_b[m.train as usize]);
                let (ua, ub) = (
                    feature_pixel(&a.features, fa),
                    feature_pixel(&b.features, fb),
                );
                let sigmas = (level_sigma(&a.features, fa), level_sigma(&b.features, fb));
                if let Some(x_a) = triangulate_pair(camera, &t_ba, (&ua, &ub), sigmas, rules) {
                    new_points.push((a.t_wc * x_a, fa, fb));
                }
            }
            for (p, fa, fb) in new_points {
                self.add_point(p, &[(other, fa), (newest, fb)]);
            }
        }
    }

    /// Structure-only refinement and culling (see the module documentation), then drops the
    /// oldest keyframes beyond `rules.window` and the points no remaining keyframe observes.
    pub fn maintain(&mut self, camera: &Camera, rules: &MapRules) {
        while self.keyframes.len() > rules.window {
            self.keyframes.pop_front();
        }
        let first = self.keyframes.front().map_or(0, |k| k.id);
        let mut dropped = Vec::new();
        for (&id, p) in self.points.iter_mut() {
            p.observations.retain(|(k, _)| *k >= first);
            let judged = p.visible >= CULL_MIN_VISIBLE;
            if p.observations.is_empty()
                || (judged && (p.found as f64) < CULL_MIN_FOUND_RATIO * p.visible as f64)
            {
                dropped.push(id);
            }
        }
        for id in dropped {
            self.remove_point(id);
        }
        let ids: Vec<PointId> = self.points.keys().copied().collect();
        for id in ids {
            if !self.refine_point(camera, id, rules.max_reprojection_px) {
                self.remove_point(id);
            }
        }
        for id in self.points.keys().copied().collect::<Vec<_>>() {
            self.update_descriptor(id);
        }
    }

    /// Unlinks the observation of `point` by feature `f` of keyframe `kid` (an outlier).
    pub fn unobserve(&mut self, point: PointId, kid: usize, f: u32) {
        if let Some(p) = self.points.get_mut(&point) {
            p.observations.retain(|&o| o != (kid, f));
        }
        if let Some(k) = self.index_of(kid) {
            let slot = &mut self.keyframes[k].point_of[f as usize];
            if *slot == Some(point) {
                *slot = None;
            }
        }
    }

    /// Removes a point and its keyframe links.
    pub fn remove_point(&mut self, id: PointId) {
        let Some(p) = self.points.remove(&id) else {
            return;
        };
        for (kid, f) in p.observations {
            if let Some(k) = self.index_of(kid) {
                self.keyframes[k].point_of[f as usize] = None;
            }
        }
    }

    /// Observations of `id` in the window: pose `T_cw`, pixel and its noise scale.
    fn views(&self, id: PointId) -> Vec<(Isometry3<f64>, Vector2<f64>, f64)> {
        self.points.get(&id).map_or_else(Vec::new, |p| {
            p.observations
                .iter()
                .filter_map(|&(kid, f)| {
                    let kf = &self.keyframes[self.index_of(kid)?];
                    let pixel = feature_pixel(&kf.features, f);
                    Some((kf.t_wc.inverse(), pixel, level_sigma(&kf.features, f)))
                })
                .collect()
        })
    }

    /// Levenberg-Marquardt ([`levenberg_marquardt`] on [`PointViews`], poses fixed) on the
    /// point's reprojection errors, each divided by its noise scale `s`, when it has two or
    /// more views; false when a view does not see it at the start or at a trial point (as
    /// Gauss-Newton dropped a point that left a view), or when the result is behind a camera
    /// or off by more than `max_px s` in a view.
    fn refine_point(&mut self, camera: &Camera, id: PointId, max_px: f64) -> bool {
        let views = self.views(id);
        let Some(p) = self.points.get_mut(&id) else {
            return false;
        };
        let mut x = p.position;
        if views.len() >= 2 {
            let mut problem = PointViews::new(camera, &views);
            let cfg = LmConfig {
                min_valid: views.len(),
                ..POINT_LM
            };
            x = match levenberg_marquardt(&mut problem, x, &cfg) {
                Ok(fit) => fit.state,
                Err(LmError::TooFewResiduals { .. }) => return false,
                // A singular system: keep the last accepted point.
                Err(LmError::Solve(_)) => problem.at,
            };
            if problem.lost {
                return false;
            }
        }
        let fits = views.iter().all(|(t_cw, u, sigma)| {
            let c = t_cw * x;
            c.z > 0.0
                && camera
                    .project(&c.coords)
                    .is_some_and(|q| (q - u).norm() < max_px * sigma)
        });
        if fits {
            p.position = x;
        }
        fits
    }

    /// Sets the point's descriptor to the observation's with the least total Hamming distance
    /// to the others (the medoid).
    fn update_descriptor(&mut self, id: PointId) {
        let Some(p) = self.points.get(&id) else {
            return;
        };
        let obs: Vec<(Descriptor, u8, f64)> = p
            .observations
            .iter()
            .filter_map(|&(kid, f)| {
                let kf = &self.keyframes[self.index_of(kid)?];
                Some((
                    kf.features.descriptors()[f as usize],
                    kf.features.levels()[f as usize],
                    (p.position - kf.centre()).norm(),
                ))
            })
            .collect();
        let best = obs
            .iter()
            .min_by_key(|(d, ..)| obs.iter().map(|(o, ..)| d.hamming(o)).sum::<u32>());
        if let (Some(&(d, level, distance)), Some(p)) = (best, self.points.get_mut(&id)) {
            p.descriptor = d;
            p.level = level;
            p.distance = distance;
        }
    }
}

/// The pyramid level at which a camera at distance `d` from point `p` sees it: the level of
/// its descriptor's observation moved by `round(log(p.distance / d) / log(scale_factor))`
/// (nearer is larger, so higher), within `0..=31` (ORB's level range).
pub(crate) fn predicted_level(p: &MapPoint, d: f64, scale_factor: f32) -> u8 {
    let shift = (p.distance / d).ln() / f64::from(scale_factor).ln();
    let level = f64::from(p.level) + shift;
    if level.is_finite() {
        level.round().clamp(0.0, 31.0) as u8
    } else {
        p.level
    }
}

/// Noise scale of feature `f`'s position: its pyramid level's scale (a keypoint of level `k`
/// is located to about `scale_factor^k` pixels).
pub(crate) fn level_sigma(features: &Features, f: u32) -> f64 {
    f64::from(features.scales()[f as usize])
}

/// The point (camera-a frame) seen at pixel `ua` in camera a and `ub` in camera b (noise
/// scales `sa`, `sb`), with `T_ba` known: DLT, kept when in front of both, reprojecting within
/// `max_reprojection_px` times the noise scale in each and with enough parallax.
pub(crate) fn triangulate_pair(
    camera: &Camera,
    t_ba: &Isometry3<f64>,
    (ua, ub): (&Vector2<f64>, &Vector2<f64>),
    (sa, sb): (f64, f64),
    rules: &MapRules,
) -> Option<Point3<f64>> {
    let (na, nb) = (
        camera.pixel_to_normalized(ua)?,
        camera.pixel_to_normalized(ub)?,
    );
    let (fa, fb) = (Vector3::new(na.x, na.y, 1.0), Vector3::new(nb.x, nb.y, 1.0));
    let x_a = triangulate_dlt(t_ba, &fa, &fb)?;
    let x_b = t_ba * x_a;
    let reprojects = |p: &Point3<f64>, u: &Vector2<f64>, s: f64| {
        p.z > 0.0
            && camera
                .project(&p.coords)
                .is_some_and(|q| (q - u).norm() < rules.max_reprojection_px * s)
    };
    (reprojects(&x_a, ua, sa)
        && reprojects(&x_b, ub, sb)
        && parallax_deg(t_ba, &x_a) >= rules.min_point_parallax_deg)
        .then_some(x_a)
}
