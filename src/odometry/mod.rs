//! Sequence odometry: trackers that follow a camera through a dataset, frame by frame.
//!
//! Every tracker aligns each new frame to its current keyframe, starting from the
//! constant-velocity prediction ([`motion`]), decides when to take a new keyframe
//! ([`keyframe`]), and reports the camera pose `T_wc` (camera-to-world, first frame at the
//! origin) with a [`TrackStatus`], [`FrameQuality`] scores and the [`Quality`] record of the
//! estimate behind the pose ([`FrameEstimate::pose_quality`]: SE(3) for [`direct`] and
//! [`direct_stereo`], PnP for
//! [`feature_rgbd`] and [`stereo`], PnP or the initialising two-view pose for [`mono`]). The status agrees with
//! the verdict: a `failed` estimate loses the frame, an `unreliable` one is
//! [`TrackStatus::Unreliable`], never plain [`TrackStatus::Ok`]. [`run`] drives a tracker over a
//! [`crate::dataset::Dataset`] and collects the trajectory.
//!
//! - [`direct`]: RGB-D photometric SE(3) alignment to the keyframe;
//! - [`feature_rgbd`]: ORB matched to the keyframe, 3D points from its depth, PnP RANSAC;
//! - [`mono`]: monocular ORB: two-view initialisation, triangulated points, PnP tracking;
//! - [`stereo`]: ORB on a rectified stereo pair, metric points at once, PnP tracking;
//! - [`direct_stereo`]: photometric SE(3) alignment to keyframes with depth from the stereo
//!   disparity (metric);
//! - [`direct_mono`]: sparse photometric SE(3) alignment to keyframes whose points carry
//!   inverse-depth filters refined by epipolar search (monocular, scale arbitrary).
//!
//! What every sequential tracker may need besides its own alignment lives here too, crate-
//! private: `coast` (the motion model keeps its velocity through up to ten lost frames, then
//! holds still), `lost` (the map tracking was lost on, with the step length then: each later
//! frame is first relocated in it before the tracker restarts) and `late` (the frames waited
//! through before a map exists, located later on the way between the reference and the
//! current pose: [`Tracker::pending`] and [`Tracker::revised`]). [`mono`] uses all three; the
//! RGB-D trackers restart at once on a failure ([`motion`]'s velocity dropped), with nothing
//! to wait for or relocate in.

mod coast;
pub mod direct;
pub mod direct_mono;
pub mod direct_stereo;
pub mod feature_rgbd;
pub mod graph;
pub mod keyframe;
mod late;
mod local_map;
mod lost;
pub mod mono;
pub mod motion;
pub mod observe;
pub mod redraw;
pub mod registry;
#[cfg(feature = "rerun")]
pub mod rerun_log;
pub mod run;
pub mod sink;
pub mod stereo;

use std::collections::HashMap;
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Point3, Vector2};
use vofront_core::Camera;
use vofront_features::{match_descriptors, match_windowed, Features, Match, MatchConfig};
use vofront_geometry::pnp::{solve_pnp_ransac_with_point_covariances, PnpConfig, PnpResult};
use vofront_robust::{Quality, Reason, Verdict};

use crate::dataset::Frame;
use motion::ConstantVelocity;
use observe::FrameDetails;

/// How tracking of one frame went; the JSON spelling is [`TrackStatus::as_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TrackStatus {
    /// Aligned to the keyframe, with an `ok` verdict.
    Ok,
    /// Could not be aligned; the pose is the motion model's guess and is not part of the
    /// trajectory.
    Lost,
    /// Tracking restarted at this frame after being lost: a new keyframe placed at the motion
    /// model's guess, so the trajectory continues but may have jumped.
    Reinitialised,
    /// Aligned to the keyframe, but the estimate's verdict is `unreliable` (its reasons are in
    /// [`FrameEstimate::pose_quality`] and the message): the pose is in the trajectory, to be
    /// used with its covariance or not at all.
    Unreliable,
}

impl TrackStatus {
    /// Lower-case name used in the per-frame CSV.
    pub fn as_str(self) -> &'static str {
        match self {
            TrackStatus::Ok => "ok",
            TrackStatus::Lost => "lost",
            TrackStatus::Reinitialised => "reinitialised",
            TrackStatus::Unreliable => "unreliable",
        }
    }
}

/// Quality scores of one frame's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct FrameQuality {
    /// Inlier residuals (pixels for direct, correspondences for feature trackers).
    pub inliers: usize,
    /// Inliers over valid residuals.
    pub inlier_ratio: f64,
    /// Residual RMSE (grey levels for direct, pixels for feature trackers).
    pub rmse: f64,
    /// Optimisation iterations (all levels).
    pub iterations: usize,
    /// Trace of the 6x6 pose covariance (m^2 + rad^2); smaller is more certain. `None` when
    /// the covariance is unknown (never 0 for "unknown").
    pub covariance_trace: Option<f64>,
    /// This frame became a keyframe.
    pub keyframe: bool,
    /// Time spent on the frame, milliseconds.
    pub ms: f64,
}

impl FrameQuality {
    /// The scores of a photometric SE(3) alignment `fit` (inliers counted among its valid
    /// pixels), on a frame that took `ms` milliseconds and became a keyframe when `keyframe`.
    pub(crate) fn of_se3(fit: &vofront_direct::Se3Result, keyframe: bool, ms: f64) -> Self {
        Self {
            inliers: (fit.inlier_ratio * fit.valid_pixels as f64).round() as usize,
            inlier_ratio: fit.inlier_ratio,
            rmse: fit.rmse,
            iterations: fit.iterations.iter().sum(),
            covariance_trace: fit.covariance.map(|c| c.trace()),
            keyframe,
            ms,
        }
    }

    /// The scores of a PnP location `fit` among `matches` candidate matches (`keyframe` false
    /// and `ms` 0, for the caller to set).
    pub(crate) fn of_pnp(fit: &PnpResult, matches: usize) -> Self {
        Self {
            inliers: fit.inlier_count(),
            inlier_ratio: fit.inlier_count() as f64 / matches.max(1) as f64,
            rmse: fit.rmse_px,
            iterations: fit.iterations,
            covariance_trace: fit.covariance.map(|c| c.trace()),
            keyframe: false,
            ms: 0.0,
        }
    }
}

/// A tracker's answer for one frame (`Serialize`: `pose_wc` is
/// `{"rotation": [qi, qj, qk, qw], "translation": [x, y, z]}`, nalgebra's layout).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FrameEstimate {
    /// Camera-to-world pose `T_wc`.
    pub pose_wc: Isometry3<f64>,
    /// How tracking went.
    pub status: TrackStatus,
    /// Quality scores.
    pub quality: FrameQuality,
    /// Why the frame was lost, if it was (or why its estimate is unreliable).
    pub message: Option<String>,
    /// The quality record of the estimate behind the pose (SE(3), PnP or two-view); `None`
    /// when there is none: lost frames and frames that (re)start tracking at a guess.
    pub pose_quality: Option<Quality>,
}

/// Lower-case names of the reasons of `q`, joined by `;` (empty when there are none).
pub fn reasons_text(q: &Quality) -> String {
    q.reasons
        .iter()
        .map(|r| r.name())
        .collect::<Vec<_>>()
        .join(";")
}

/// Follows a camera through consecutive frames.
///
/// A tracker may answer some frames late: a monocular tracker waiting for parallax reports
/// the frames it waits through lost, then locates them in the map it initialises. While
/// [`pending`](Tracker::pending) is `p > 0`, the estimates of the last `p` frames tracked may
/// still be replaced; [`revised`](Tracker::revised) hands the replacements over after the
/// `track` call that made them. A caller writing estimates as it goes holds pending frames
/// back ([`run_with`](run::run_with) does); one that ignores both methods only misses the
/// late answers.
pub trait Tracker {
    /// Estimates the pose of the next frame.
    fn track(&mut self, frame: &Frame) -> FrameEstimate;

    /// How many of the most recent frames tracked (the last one included) may still have
    /// their estimates replaced; 0 (the default) for a tracker that never revises.
    fn pending(&self) -> usize {
        0
    }

    /// Replacements made by the last `track` call for frames that were pending before it,
    /// oldest first, each with its position counted back from the last frame tracked (1: the
    /// frame before it; `quality.ms` is the late work's time alone); the list is handed over
    /// once. Empty by default.
    fn revised(&mut self) -> Vec<(usize, FrameEstimate)> {
        Vec::new()
    }

    /// True when every frame must carry its right image ([`Frame::right`]): the run then
    /// loads frames with [`Dataset::load_stereo`](crate::dataset::Dataset::load_stereo).
    /// False by default.
    fn needs_right(&self) -> bool {
        false
    }

    /// Starts (`true`) or stops keeping the [`FrameDetails`] of each frame tracked, for
    /// [`details`](Tracker::details). Off until asked, so that a run without an observer does
    /// no extra work; a tracker with nothing to show ignores it (the default).
    fn keep_details(&mut self, _keep: bool) {}

    /// The details of the last frame tracked, while kept ([`keep_details`](Tracker::keep_details));
    /// `None` by default.
    fn details(&self) -> Option<&FrameDetails> {
        None
    }
}

use crate::error::VoError;
pub(crate) use crate::{pipeline::feature_pixel, timing::ms_since};

/// What every keyframe tracker keeps between frames: its keyframe `K`, the constant-velocity
/// prior, and whether tracking has started (so a restart can be told from the first frame).
pub(crate) struct KeyframeSlot<K> {
    /// The keyframe new frames are aligned to; `None` after a failed restart.
    pub keyframe: Option<K>,
    /// The motion prior.
    pub motion: ConstantVelocity,
    started: bool,
}

impl<K> Default for KeyframeSlot<K> {
    fn default() -> Self {
        Self {
            keyframe: None,
            motion: ConstantVelocity::default(),
            started: false,
        }
    }
}

impl<K> KeyframeSlot<K> {
    /// The motion model's `T_wc` for the next frame (the origin before the first frame).
    pub fn predict(&self) -> Isometry3<f64> {
        self.motion.predict().unwrap_or_else(Isometry3::identity)
    }

    /// Starts over at `t_wc` with the keyframe `made` from the current frame (or why it could
    /// not be made, which makes the frame lost). The velocity that led to the failure is
    /// dropped either way.
    pub fn restart(
        &mut self,
        made: Result<K, VoError>,
        t_wc: Isometry3<f64>,
        why: String,
        start: Instant,
    ) -> FrameEstimate {
        let status = if self.started {
            TrackStatus::Reinitialised
        } else {
            TrackStatus::Ok
        };
        let estimate = match made {
            Ok(kf) => {
                self.keyframe = Some(kf);
                self.started = true;
                self.motion.update(t_wc);
                FrameEstimate::started(t_wc, status, why, start)
            }
            Err(e) => {
                self.keyframe = None;
                FrameEstimate::lost(t_wc, format!("{why}; {e}"), start)
            }
        };
        self.motion.reset_velocity();
        estimate
    }
}

impl FrameEstimate {
    /// A frame that (re)starts tracking as a new keyframe at `pose_wc`; `why` tracking had to
    /// restart is kept as the message of a [`TrackStatus::Reinitialised`] frame.
    pub(crate) fn started(
        pose_wc: Isometry3<f64>,
        status: TrackStatus,
        why: String,
        start: Instant,
    ) -> Self {
        let quality = FrameQuality {
            keyframe: true,
            inlier_ratio: 1.0,
            ms: ms_since(start),
            ..FrameQuality::default()
        };
        let message = (status == TrackStatus::Reinitialised).then_some(why);
        Self {
            pose_wc,
            status,
            quality,
            message,
            pose_quality: None,
        }
    }

    /// This estimate with the quality record `q` of the estimate behind its pose, the status
    /// made to agree with the verdict: a tracked-ok frame whose verdict is not `ok` becomes
    /// [`TrackStatus::Unreliable`] with the reasons as its message (trackers lose the frame on
    /// a `failed` verdict before they get here; [`Verdict::Failed`] is reported unreliable at
    /// best, never ok).
    pub fn judged(mut self, q: Quality) -> Self {
        if self.status == TrackStatus::Ok && q.verdict != Verdict::Ok {
            self.status = TrackStatus::Unreliable;
            self.message
                .get_or_insert_with(|| format!("{}: {}", q.verdict, reasons_text(&q)));
        }
        self.pose_quality = Some(q);
        self
    }

    /// The estimate with its pose quality flagged `reason` (the status follows the new
    /// verdict; `why` becomes the message when there was none). An estimate without a pose
    /// quality is only marked `unreliable` when it was `ok`.
    pub(crate) fn flagged(mut self, reason: Reason, why: String) -> Self {
        self.message.get_or_insert(why);
        match self.pose_quality.take() {
            Some(mut q) => {
                q.flag(reason);
                self.judged(q)
            }
            None => {
                if self.status == TrackStatus::Ok {
                    self.status = TrackStatus::Unreliable;
                }
                self
            }
        }
    }

    /// A lost frame, reported at the motion model's guess `pose_wc`.
    pub(crate) fn lost(pose_wc: Isometry3<f64>, why: String, start: Instant) -> Self {
        let quality = FrameQuality {
            ms: ms_since(start),
            ..FrameQuality::default()
        };
        Self {
            pose_wc,
            status: TrackStatus::Lost,
            quality,
            message: Some(why),
            pose_quality: None,
        }
    }
}

/// How a feature tracker locates a frame against keyframe features that carry 3D points.
pub(crate) struct PointLocator<'a> {
    /// The camera of every frame.
    pub camera: &'a Camera,
    /// Matching filters.
    pub matching: &'a MatchConfig,
    /// Search radius around each predicted position, pixels.
    pub window_px: f32,
    /// PnP RANSAC and refinement.
    pub pnp: &'a PnpConfig,
    /// Fewest PnP inliers for the frame to count as located.
    pub min_inliers: usize,
}

/// The matches a frame was located with and the PnP result (or why it failed).
pub(crate) struct Located {
    /// Keyframe feature (query) to current feature (train), only for features with a point.
    pub matches: Vec<Match>,
    /// The point of each match, in the frame the prior maps from.
    pub points: Vec<Point3<f64>>,
    /// The pixel noise of each match's current keypoint (its pyramid level's scale), pixels:
    /// the sigmas PnP weighted the match with.
    pub sigmas: Vec<f64>,
    /// The covariance of each match's point (`None`: exact), as PnP weighted it.
    pub covariances: Vec<Option<Matrix3<f64>>>,
    /// `T_cur_from`: the points' frame into the current camera.
    pub fit: Result<PnpResult, VoError>,
}

/// Makes `matches` (sorted by query) one to one between points and keypoints, keeping the
/// match of smallest descriptor distance (the first on a tie): of the matches of consecutive
/// query entries with the same point (one point matched by several descriptors:
/// [`LocalMap::local_points`](local_map::LocalMap::local_points)), and of the matches of one
/// current keypoint (two points seen at one pixel are one observation, not two).
fn one_match_per_point_and_keypoint(matches: &mut Vec<Match>, points: &[Option<Point3<f64>>]) {
    let same_point = |a: &Match, b: &Match| {
        b.query == a.query + 1 && points[a.query as usize] == points[b.query as usize]
    };
    let mut kept: Vec<Match> = Vec::with_capacity(matches.len());
    for m in matches.drain(..) {
        match kept.last_mut() {
            Some(last) if same_point(last, &m) => {
                if m.distance < last.distance {
                    *last = m;
                }
            }
            _ => kept.push(m),
        }
    }
    let mut best: HashMap<u32, (u32, u32)> = HashMap::with_capacity(kept.len());
    for m in &kept {
        let entry = best.entry(m.train).or_insert((m.distance, m.query));
        if m.distance < entry.0 {
            *entry = (m.distance, m.query);
        }
    }
    kept.retain(|m| best.get(&m.train).is_some_and(|&(_, q)| q == m.query));
    *matches = kept;
}

impl PointLocator<'_> {
    /// Matches keyframe features carrying a point `P` to `current` within `window_px` of
    /// `pi(K prior P)` (by brute force when that finds fewer than `2 min_inliers`), then
    /// estimates `T_cur_from` by PnP from the guess `prior`; a PnP pose whose verdict is
    /// `failed` is no location. With `covariances` (index-aligned with `points`), the points'
    /// own noise weighs their residuals ([`solve_pnp_ransac_with_point_covariances`]).
    pub fn locate(
        &self,
        kf: &Features,
        points: &[Option<Point3<f64>>],
        covariances: Option<&[Option<Matrix3<f64>>]>,
        current: &Features,
        prior: Isometry3<f64>,
    ) -> Located {
        let predicted: Vec<(f32, f32)> = points
            .iter()
            .map(|p| {
                p.and_then(|p| self.camera.project(&(prior * p).coords))
                    .map_or((f32::NAN, f32::NAN), |u| (u.x as f32, u.y as f32))
            })
            .collect();
        let mut matches = match_windowed(
            kf,
            &predicted,
            current,
            self.window_px,
            Some(1),
            self.matching,
        )
        .unwrap_or_default();
        if matches.len() < 2 * self.min_inliers {
            matches = match_descriptors(kf.descriptors(), current.descriptors(), self.matching);
        }
        matches.retain(|m| points[m.query as usize].is_some());
        one_match_per_point_and_keypoint(&mut matches, points);
        let world: Vec<Point3<f64>> = matches
            .iter()
            .filter_map(|m| points[m.query as usize])
            .collect();
        let pixels: Vec<Vector2<f64>> = matches
            .iter()
            .map(|m| feature_pixel(current, m.train))
            .collect();
        // A keypoint of pyramid level k is located to about scale_factor^k pixels.
        let sigmas: Vec<f64> = matches
            .iter()
            .map(|m| f64::from(current.scales()[m.train as usize]))
            .collect();
        // Without covariances every point is exact, which is the pixel-only solve.
        let point_covariances: Vec<Option<Matrix3<f64>>> = matches
            .iter()
            .map(|m| covariances.and_then(|c| c.get(m.query as usize).copied().flatten()))
            .collect();
        let fit = solve_pnp_ransac_with_point_covariances(
            &world,
            &pixels,
            &sigmas,
            &point_covariances,
            self.camera,
            Some(prior),
            self.pnp,
        )
        .map_err(VoError::from)
        .and_then(|fit| {
            if fit.quality.verdict == Verdict::Failed {
                Err(VoError::Rejected {
                    what: "PnP",
                    reasons: reasons_text(&fit.quality),
                })
            } else if fit.inlier_count() >= self.min_inliers {
                Ok(fit)
            } else {
                Err(VoError::TooFew {
                    what: "PnP inliers",
                    got: fit.inlier_count(),
                    need: self.min_inliers,
                })
            }
        });
        Located {
            matches,
            points: world,
            sigmas,
            covariances: point_covariances,
            fit,
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;
    use vofront_features::Match;

    use super::one_match_per_point_and_keypoint;

    fn m(query: u32, train: u32, distance: u32) -> Match {
        Match {
            query,
            train,
            distance,
        }
    }

    /// Entries 0 and 1 are one point (two descriptors), 2 and 3 two points; the closer match
    /// of the point and of keypoint 5 is kept, and a match alone on both sides stays.
    #[test]
    fn matches_become_one_to_one_by_the_smallest_distance() {
        let a = Some(Point3::new(0.0, 0.0, 5.0));
        let points = [
            a,
            a,
            Some(Point3::new(1.0, 0.0, 5.0)),
            Some(Point3::new(2.0, 0.0, 5.0)),
        ];
        let mut matches = vec![m(0, 4, 30), m(1, 9, 12), m(2, 5, 20), m(3, 5, 8)];
        one_match_per_point_and_keypoint(&mut matches, &points);
        assert_eq!(matches, [m(1, 9, 12), m(3, 5, 8)]);

        // Two different points at adjacent entries are not merged; ties keep the first.
        let mut matches = vec![m(2, 6, 10), m(3, 7, 10), m(0, 7, 10)];
        matches.sort_by_key(|x| x.query);
        one_match_per_point_and_keypoint(&mut matches, &points);
        assert_eq!(matches, [m(0, 7, 10), m(2, 6, 10)]);
    }
}
