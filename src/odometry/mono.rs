//! Monocular feature tracker: two-view initialisation, triangulated map points, PnP tracking.
//!
//! 1. Initialisation: the first frame is the reference; each later frame is matched to it and
//!    [`estimate_relative_pose`] runs (essential or homography); once the median parallax and
//!    the number of triangulated points suffice, the points (in units of that first baseline,
//!    which fixes the arbitrary scale) become the map and the frame the first keyframe.
//! 2. Tracking: keyframe features that carry a world point are matched to the current frame
//!    around their predicted positions `pi(K T_cw' P_w)`, and PnP RANSAC with robust refinement
//!    gives `T_cw`; `T_wc = T_cw^-1`.
//! 3. New keyframes carry the tracked points over and triangulate new ones from keyframe
//!    features that had none, with both poses known (DLT, checked for cheirality, parallax and
//!    reprojection error).
//! 4. When PnP fails the frame is lost and initialisation starts again from it, placed at the
//!    motion model's guess; the new map has its own scale.

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
            keyframe: KeyframePolicy {
                max_relative_translation: 0.05,
                ..KeyframePolicy::default()
            },
            max_reprojection_px: 2.0,
            min_point_parallax_deg: 0.5,
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
}

/// Frames an initialisation waits for parallax before taking a newer reference.
const MAX_INIT_FRAMES: usize = 30;

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
    ) -> Result<(Keyframe, FrameQuality), String> {
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
        let rel = estimate_relative_pose(&x1, &x2, &self.camera, &self.cfg.relative)
            .map_err(|e| e.to_string())?;
        if rel.low_parallax || rel.parallax_deg < self.cfg.min_init_parallax_deg {
            return Err(format!(
                "initialising: parallax {:.2} deg",
                rel.parallax_deg
            ));
        }
        if rel.triangulated < self.cfg.min_init_points {
            return Err(format!(
                "initialising: {} points triangulated, {} needed",
                rel.triangulated, self.cfg.min_init_points
            ));
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
                self.state = State::Initialising {
                    reference: current,
                    t_wc: predicted,
                    frames: 0,
                };
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
        let keyframe = self.cfg.keyframe.needs_keyframe(&view);
        let mut quality = FrameQuality {
            inliers: fit.inlier_count,
            inlier_ratio: fit.inlier_count as f64 / matches.len().max(1) as f64,
            rmse: fit.rmse_px,
            iterations: fit.iterations,
            covariance_trace: fit.covariance.map(|c| c.trace()),
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

impl Tracker for MonoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        let start = Instant::now();
        let predicted = self.motion.predict().unwrap_or_else(Isometry3::identity);
        let current = match self.orb.detect_and_describe(&frame.image) {
            Ok(f) => f,
            Err(e) => {
                return self.estimate(
                    predicted,
                    TrackStatus::Lost,
                    FrameQuality::default(),
                    Some(e.to_string()),
                )
            }
        };
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
                    self.estimate(
                        predicted,
                        TrackStatus::Lost,
                        FrameQuality::default(),
                        Some("initialising".into()),
                    )
                }
            }
            State::Initialising {
                reference,
                t_wc,
                frames,
            } => match self.initialise(&reference, &t_wc, &current) {
                Ok((kf, quality)) => {
                    let status = if self.initialised_once {
                        TrackStatus::Reinitialised
                    } else {
                        TrackStatus::Ok
                    };
                    self.initialised_once = true;
                    let pose = kf.t_wc;
                    self.motion.update(pose);
                    self.motion.reset_velocity();
                    self.state = State::Tracking(kf);
                    self.estimate(
                        pose,
                        status,
                        FrameQuality {
                            ms: ms_since(start),
                            ..quality
                        },
                        None,
                    )
                }
                Err(why) => {
                    self.state = if frames >= MAX_INIT_FRAMES {
                        State::Initialising {
                            reference: current,
                            t_wc: predicted,
                            frames: 0,
                        }
                    } else {
                        State::Initialising {
                            reference,
                            t_wc,
                            frames: frames + 1,
                        }
                    };
                    let quality = FrameQuality {
                        ms: ms_since(start),
                        ..FrameQuality::default()
                    };
                    self.estimate(predicted, TrackStatus::Lost, quality, Some(why))
                }
            },
            tracking @ State::Tracking(_) => {
                self.state = tracking;
                self.track_keyframe(current, predicted, start)
            }
        }
    }
}
