//! Monocular feature tracker: two-view initialisation, triangulated map points, PnP tracking.
//!
//! 1. Initialisation: the first frame with enough features is the reference; each later frame
//!    is matched to it and [`estimate_relative_pose`] runs (essential or homography); once the
//!    median parallax and the number of triangulated points suffice, the points (in units of
//!    that first baseline, which fixes the arbitrary scale) become the map and the frame the
//!    first keyframe. A rotation-dominant start keeps waiting for parallax; a frame with too
//!    few features is skipped (never made the reference), and a reference that no longer
//!    matches the current frame is replaced by it.
//! 2. Tracking: keyframe features that carry a world point are matched to the current frame
//!    around their predicted positions `pi(K T_cw' P_w)`, and PnP RANSAC with robust refinement
//!    gives `T_cw`; `T_wc = T_cw^-1`.
//! 3. Keyframes are decided without metric units: a new one is taken when the median parallax
//!    of the tracked points between the keyframe and the current camera centres,
//!    `angle(P - C_kf, P - C_cur)`, reaches `keyframe_parallax_deg`, when the tracked ratio
//!    (PnP inliers over the keyframe's points) falls under the policy's `min_overlap`, or on
//!    the policy's rotation and residual tests. New keyframes carry the tracked points over and
//!    triangulate new ones from keyframe features that had none, with both poses known (DLT,
//!    checked for cheirality, parallax and reprojection error).
//! 4. When PnP fails the frame is lost and initialisation starts again (from that frame if it
//!    has enough features), placed at the motion model's guess. The new map's scale is matched
//!    to the lost one: points of the last keyframe matched by descriptor to the new map's
//!    points give `s = median(|P_old - C_ref| / |P_new - C_ref|)` about the new reference camera
//!    `C_ref`; when too few match the frame's message says the segment is not joined.

use std::time::Instant;

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use vofront_features::{match_descriptors, Features, Match, MatchConfig, Orb, OrbConfig};
use vofront_geometry::pnp::PnpConfig;
use vofront_geometry::triangulate::{parallax_deg, triangulate_dlt};
use vofront_geometry::{estimate_relative_pose, Camera, RelativePoseConfig};

use super::keyframe::{KeyframePolicy, KeyframeView};
use super::motion::ConstantVelocity;
use super::{
    feature_pixel, ms_since, FrameEstimate, FrameQuality, Located, PointLocator, TrackStatus,
    Tracker,
};
use crate::dataset::Frame;

/// Settings of [`MonoTracker`].
#[derive(Debug, Clone)]
pub struct MonoConfig {
    /// ORB settings.
    pub orb: OrbConfig,
    /// Matching filters.
    pub matching: MatchConfig,
    /// Search radius around predicted positions, pixels.
    pub window_px: f32,
    /// Two-view estimation used for initialisation.
    pub relative: RelativePoseConfig,
    /// PnP RANSAC and refinement.
    pub pnp: PnpConfig,
    /// Fewest triangulated points to accept an initialisation.
    pub min_init_points: usize,
    /// Smallest median parallax to accept an initialisation, degrees.
    pub min_init_parallax_deg: f64,
    /// Fewest PnP inliers for a tracked frame.
    pub min_inliers: usize,
    /// When to take a new keyframe.
    pub keyframe: KeyframePolicy,
    /// Largest reprojection error of a new point in either view, pixels.
    pub max_reprojection_px: f64,
    /// Smallest parallax of a new point, degrees.
    pub min_point_parallax_deg: f64,
    /// Median parallax of the tracked points against the keyframe that triggers a new
    /// keyframe, degrees.
    pub keyframe_parallax_deg: f64,
    /// Frames an initialisation waits for parallax before taking a newer reference.
    pub max_init_frames: usize,
    /// Fewest old-map points matched to the new map to join their scales after a loss.
    pub min_scale_matches: usize,
}

impl Default for MonoConfig {
    fn default() -> Self {
        Self {
            orb: OrbConfig {
                n_features: 1500,
                ..OrbConfig::default()
            },
            matching: MatchConfig {
                ratio: Some(0.8),
                ..MatchConfig::default()
            },
            window_px: 24.0,
            relative: RelativePoseConfig::default(),
            pnp: PnpConfig::default(),
            min_init_points: 80,
            min_init_parallax_deg: 1.0,
            min_inliers: 25,
            // Map units mean nothing in monocular: keyframes by parallax and tracked ratio.
            keyframe: KeyframePolicy {
                max_relative_translation: f64::INFINITY,
                min_overlap: 0.5,
                ..KeyframePolicy::default()
            },
            max_reprojection_px: 2.0,
            min_point_parallax_deg: 0.5,
            keyframe_parallax_deg: 1.0,
            max_init_frames: 30,
            min_scale_matches: 12,
        }
    }
}

/// A frame whose features (some with a world point) later frames are matched against.
struct Keyframe {
    features: Features,
    points: Vec<Option<Point3<f64>>>,
    t_wc: Isometry3<f64>,
    first_residual: Option<f64>,
}

impl Keyframe {
    fn with_points(&self) -> usize {
        self.points.iter().flatten().count()
    }

    /// Median depth of the map points in this keyframe's camera.
    fn median_depth(&self) -> f64 {
        let t_cw = self.t_wc.inverse();
        let mut z: Vec<f64> = self.points.iter().flatten().map(|p| (t_cw * p).z).collect();
        crate::robust::median_in_place(&mut z).unwrap_or(1.0)
    }
}

/// Median over points `P` of the parallax angle `angle(P - c1, P - c2)`, degrees (0 without
/// points).
fn median_parallax_deg<'a>(
    c1: &Point3<f64>,
    c2: &Point3<f64>,
    points: impl Iterator<Item = &'a Point3<f64>>,
) -> f64 {
    let mut angles: Vec<f64> = points
        .map(|p| (p - c1).angle(&(p - c2)).to_degrees())
        .collect();
    crate::robust::median_in_place(&mut angles).unwrap_or(0.0)
}

/// Why an initialisation attempt failed, and whether its reference is still worth waiting on.
struct InitFailure {
    why: String,
    /// False when the reference no longer matches the current frame well enough to ever
    /// initialise: it is then replaced.
    keep_reference: bool,
}

enum State {
    /// Nothing seen yet, or just lost.
    Empty,
    /// Waiting for enough parallax against `reference`.
    Initialising {
        reference: Features,
        t_wc: Isometry3<f64>,
        frames: usize,
    },
    /// Tracking against a keyframe.
    Tracking(Keyframe),
}

/// Monocular ORB tracker with an arbitrary but consistent scale (per initialisation).
pub struct MonoTracker {
    cfg: MonoConfig,
    orb: Orb,
    camera: Camera,
    state: State,
    motion: ConstantVelocity,
    initialised_once: bool,
    /// The last keyframe before tracking was lost: its points set the scale of the next map.
    lost_map: Option<Keyframe>,
}

impl MonoTracker {
    /// A tracker for frames of `camera`; fails on an invalid ORB configuration.
    pub fn new(camera: Camera, cfg: MonoConfig) -> Result<Self, vofront_features::FeatureError> {
        let orb = Orb::new(cfg.orb.clone())?;
        Ok(Self {
            cfg,
            orb,
            camera,
            state: State::Empty,
            motion: ConstantVelocity::default(),
            initialised_once: false,
            lost_map: None,
        })
    }

    fn estimate(
        &self,
        pose_wc: Isometry3<f64>,
        status: TrackStatus,
        quality: FrameQuality,
        message: Option<String>,
    ) -> FrameEstimate {
        FrameEstimate {
            pose_wc,
            status,
            quality,
            message,
        }
    }

    /// Tries to initialise the map from `reference` (at `t_w1`) and `current`.
    fn initialise(
        &self,
        reference: &Features,
        t_w1: &Isometry3<f64>,
        current: &Features,
    ) -> Result<(Keyframe, FrameQuality), InitFailure> {
        let lost = |why: String| InitFailure {
            why,
            keep_reference: false,
        };
        let matches = match_descriptors(
            &reference.descriptors,
            &current.descriptors,
            &self.cfg.matching,
        );
        let x1: Vec<_> = matches
            .iter()
            .map(|m| feature_pixel(reference, m.query))
            .collect();
        let x2: Vec<_> = matches
            .iter()
            .map(|m| feature_pixel(current, m.train))
            .collect();
        if matches.len() < self.cfg.min_init_points {
            return Err(lost(format!(
                "initialising: {} matches to the reference, {} needed",
                matches.len(),
                self.cfg.min_init_points
            )));
        }
        let rel = estimate_relative_pose(&x1, &x2, &self.camera, &self.cfg.relative)
            .map_err(|e| lost(format!("initialising: {e}")))?;
        let wait = |why: String| InitFailure {
            why,
            keep_reference: true,
        };
        if rel.low_parallax || rel.parallax_deg < self.cfg.min_init_parallax_deg {
            return Err(wait(format!(
                "initialising: parallax {:.2} deg",
                rel.parallax_deg
            )));
        }
        if rel.triangulated < self.cfg.min_init_points {
            return Err(wait(format!(
                "initialising: {} points triangulated, {} needed",
                rel.triangulated, self.cfg.min_init_points
            )));
        }
        let mut points = vec![None; current.len()];
        for (m, p) in matches.iter().zip(&rel.points) {
            if let Some(p) = p {
                points[m.train as usize] = Some(t_w1 * p);
            }
        }
        let t_wc = t_w1 * rel.pose.inverse();
        let quality = FrameQuality {
            inliers: rel.inlier_count,
            inlier_ratio: rel.inlier_count as f64 / matches.len().max(1) as f64,
            keyframe: true,
            ..FrameQuality::default()
        };
        Ok((
            Keyframe {
                features: current.clone(),
                points,
                t_wc,
                first_residual: None,
            },
            quality,
        ))
    }

    /// Scale `s` that brings `kf` (a new map initialised from the reference camera at `t_w1`)
    /// to the units of `old`: the median of `|P_old - C_ref| / |P_new - C_ref|` over old
    /// points matched by descriptor to new ones; `None` when fewer than `min_scale_matches`.
    fn scale_to(&self, old: &Keyframe, kf: &Keyframe, t_w1: &Isometry3<f64>) -> Option<f64> {
        let matches = match_descriptors(
            &old.features.descriptors,
            &kf.features.descriptors,
            &self.cfg.matching,
        );
        let c = Point3::from(t_w1.translation.vector);
        let mut ratios: Vec<f64> = matches
            .iter()
            .filter_map(|m| {
                let (p_old, p_new) = (old.points[m.query as usize]?, kf.points[m.train as usize]?);
                let r = (p_old - c).norm() / (p_new - c).norm();
                r.is_finite().then_some(r)
            })
            .collect();
        if ratios.len() < self.cfg.min_scale_matches {
            return None;
        }
        crate::robust::median_in_place(&mut ratios).filter(|s| *s > 0.0)
    }

    /// `kf` with its points and pose scaled by `s` about the reference camera `t_w1`:
    /// `P <- T_w1 (s T_w1^-1 P)`, and the translation of `T_w1^-1 T_wc` times `s`.
    fn rescale(kf: &mut Keyframe, t_w1: &Isometry3<f64>, s: f64) {
        let t_1w = t_w1.inverse();
        for p in kf.points.iter_mut().flatten() {
            *p = t_w1 * Point3::from((t_1w * *p).coords * s);
        }
        let mut t_1c = t_1w * kf.t_wc;
        t_1c.translation.vector *= s;
        kf.t_wc = t_w1 * t_1c;
    }

    /// World points for `current`'s features at `t_wc`: tracked inliers keep their point, and
    /// keyframe features without a point are triangulated against the keyframe.
    fn next_keyframe(
        &self,
        kf: &Keyframe,
        current: Features,
        inliers: &[(Match, Point3<f64>)],
        t_wc: Isometry3<f64>,
    ) -> Keyframe {
        let mut points = vec![None; current.len()];
        for (m, p) in inliers {
            points[m.train as usize] = Some(*p);
        }
        let t_cur_kf = t_wc.inverse() * kf.t_wc;
        let candidates = match_descriptors(
            &kf.features.descriptors,
            &current.descriptors,
            &self.cfg.matching,
        );
        for m in &candidates {
            if kf.points[m.query as usize].is_some() || points[m.train as usize].is_some() {
                continue;
            }
            let (u1, u2) = (
                feature_pixel(&kf.features, m.query),
                feature_pixel(&current, m.train),
            );
            let (Some(n1), Some(n2)) = (
                self.camera.pixel_to_normalized(&u1),
                self.camera.pixel_to_normalized(&u2),
            ) else {
                continue;
            };
            let (f1, f2) = (Vector3::new(n1.x, n1.y, 1.0), Vector3::new(n2.x, n2.y, 1.0));
            let Some(x_kf) = triangulate_dlt(&t_cur_kf, &f1, &f2) else {
                continue;
            };
            let x_cur = t_cur_kf * x_kf;
            let reprojects = |p: &Point3<f64>, u: &Vector2<f64>| {
                self.camera
                    .project(&p.coords)
                    .is_some_and(|q| (q - u).norm() < self.cfg.max_reprojection_px)
            };
            if reprojects(&x_kf, &u1)
                && reprojects(&x_cur, &u2)
                && parallax_deg(&t_cur_kf, &x_kf) >= self.cfg.min_point_parallax_deg
            {
                points[m.train as usize] = Some(kf.t_wc * x_kf);
            }
        }
        Keyframe {
            features: current,
            points,
            t_wc,
            first_residual: None,
        }
    }

    fn track_keyframe(
        &mut self,
        current: Features,
        predicted: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let State::Tracking(kf) = &self.state else {
            return self.estimate(
                predicted,
                TrackStatus::Lost,
                FrameQuality::default(),
                Some("not tracking".into()),
            );
        };
        let locator = PointLocator {
            camera: &self.camera,
            matching: &self.cfg.matching,
            window_px: self.cfg.window_px,
            pnp: &self.cfg.pnp,
            min_inliers: self.cfg.min_inliers,
        };
        let Located {
            matches,
            points: world,
            fit,
        } = locator.locate(&kf.features, &kf.points, &current, predicted.inverse());
        let fit = match fit {
            Ok(fit) => fit,
            Err(why) => {
                if let State::Tracking(kf) = std::mem::replace(&mut self.state, State::Empty) {
                    self.lost_map = Some(kf);
                }
                if current.len() >= self.cfg.min_init_points {
                    self.state = State::Initialising {
                        reference: current,
                        t_wc: predicted,
                        frames: 0,
                    };
                }
                self.motion.reset_velocity();
                let quality = FrameQuality {
                    ms: ms_since(start),
                    ..FrameQuality::default()
                };
                return self.estimate(predicted, TrackStatus::Lost, quality, Some(why));
            }
        };
        let t_wc = fit.pose.inverse();
        self.motion.update(t_wc);
        let inliers: Vec<(Match, Point3<f64>)> = matches
            .iter()
            .zip(&world)
            .zip(&fit.inliers)
            .filter(|(_, inlier)| **inlier)
            .map(|((m, p), _)| (*m, *p))
            .collect();
        let first_residual = kf.first_residual.unwrap_or(fit.rmse_px);
        let view = KeyframeView {
            t_cur_kf: fit.pose * kf.t_wc,
            median_depth: kf.median_depth(),
            overlap: fit.inlier_count as f64 / kf.with_points().max(1) as f64,
            residual: fit.rmse_px,
            first_residual,
        };
        let parallax = median_parallax_deg(
            &Point3::from(kf.t_wc.translation.vector),
            &Point3::from(t_wc.translation.vector),
            inliers.iter().map(|(_, p)| p),
        );
        let keyframe =
            parallax >= self.cfg.keyframe_parallax_deg || self.cfg.keyframe.needs_keyframe(&view);
        let mut quality = FrameQuality {
            inliers: fit.inlier_count,
            inlier_ratio: fit.inlier_count as f64 / matches.len().max(1) as f64,
            rmse: fit.rmse_px,
            iterations: fit.iterations,
            covariance_trace: fit.covariance.trace(),
            keyframe,
            ms: 0.0,
        };
        let next = if keyframe {
            Some(self.next_keyframe(kf, current, &inliers, t_wc))
        } else {
            None
        };
        match (next, &mut self.state) {
            (Some(new_kf), state) => *state = State::Tracking(new_kf),
            (None, State::Tracking(kf)) => kf.first_residual = Some(first_residual),
            (None, _) => {}
        }
        quality.ms = ms_since(start);
        self.estimate(t_wc, TrackStatus::Ok, quality, None)
    }
}

impl MonoTracker {
    /// The map `kf` initialised from the reference at `t_w1` becomes the tracked map, its
    /// scale joined to the lost map's where they overlap.
    fn start_map(
        &mut self,
        mut kf: Keyframe,
        t_w1: &Isometry3<f64>,
        quality: FrameQuality,
        start: Instant,
    ) -> FrameEstimate {
        let (status, message) = if self.initialised_once {
            let joined = self
                .lost_map
                .take()
                .and_then(|old| self.scale_to(&old, &kf, t_w1));
            match joined {
                Some(s) => {
                    Self::rescale(&mut kf, t_w1, s);
                    (
                        TrackStatus::Reinitialised,
                        Some(format!("new map, scale {s:.3} joined to the lost one")),
                    )
                }
                None => (
                    TrackStatus::Reinitialised,
                    Some("new map, scale not joined to the lost one (segment break)".into()),
                ),
            }
        } else {
            (TrackStatus::Ok, None)
        };
        self.initialised_once = true;
        let pose = kf.t_wc;
        self.motion.update(pose);
        self.motion.reset_velocity();
        self.state = State::Tracking(kf);
        let quality = FrameQuality {
            ms: ms_since(start),
            ..quality
        };
        self.estimate(pose, status, quality, message)
    }

    /// A frame that cannot serve the initialisation: reported lost, the state is untouched.
    fn skipped(&self, predicted: Isometry3<f64>, why: String, start: Instant) -> FrameEstimate {
        let quality = FrameQuality {
            ms: ms_since(start),
            ..FrameQuality::default()
        };
        self.estimate(predicted, TrackStatus::Lost, quality, Some(why))
    }
}

impl Tracker for MonoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        let start = Instant::now();
        let predicted = self.motion.predict().unwrap_or_else(Isometry3::identity);
        let current = match self.orb.detect_and_describe(&frame.image) {
            Ok(f) => f,
            Err(e) => return self.skipped(predicted, e.to_string(), start),
        };
        let tracking = matches!(self.state, State::Tracking(_));
        if !tracking && current.len() < self.cfg.min_init_points {
            // A featureless frame can neither start nor serve an initialisation: skip it.
            let why = format!(
                "initialising: {} features, {} needed (frame skipped)",
                current.len(),
                self.cfg.min_init_points
            );
            return self.skipped(predicted, why, start);
        }
        match std::mem::replace(&mut self.state, State::Empty) {
            State::Empty => {
                let first = !self.initialised_once && self.motion.predict().is_none();
                self.state = State::Initialising {
                    reference: current,
                    t_wc: predicted,
                    frames: 0,
                };
                if first {
                    // The first frame defines the world frame: it is tracked by definition.
                    self.motion.update(predicted);
                    let quality = FrameQuality {
                        keyframe: true,
                        ms: ms_since(start),
                        ..FrameQuality::default()
                    };
                    self.estimate(predicted, TrackStatus::Ok, quality, None)
                } else {
                    self.skipped(predicted, "initialising: new reference".into(), start)
                }
            }
            State::Initialising {
                reference,
                t_wc,
                frames,
            } => match self.initialise(&reference, &t_wc, &current) {
                Ok((kf, quality)) => self.start_map(kf, &t_wc, quality, start),
                Err(failure) => {
                    self.state = if failure.keep_reference && frames < self.cfg.max_init_frames {
                        State::Initialising {
                            reference,
                            t_wc,
                            frames: frames + 1,
                        }
                    } else {
                        State::Initialising {
                            reference: current,
                            t_wc: predicted,
                            frames: 0,
                        }
                    };
                    self.skipped(predicted, failure.why, start)
                }
            },
            tracking @ State::Tracking(_) => {
                self.state = tracking;
                self.track_keyframe(current, predicted, start)
            }
        }
    }
}
