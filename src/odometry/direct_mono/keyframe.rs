//! A direct monocular keyframe: its pinhole image and pose, its points (active ones carried
//! from the previous keyframe, immature ones selected in free blocks), and the sparse SE(3)
//! reference of its active points that frames are aligned to.

use std::collections::VecDeque;

use nalgebra::{Isometry3, Vector2};
use vofront_core::Pinhole;
use vofront_direct::mono::{
    active_points, refine_points, select_points, transfer_points, Candidate, EpipolarPair,
    FrameState, MonoPoint,
};
use vofront_direct::quality::intensity_mean;
use vofront_direct::Se3Reference;
use vofront_image::Image;

use super::config::DirectMonoConfig;
use crate::error::VoError;

/// A keyframe of the direct monocular tracker.
pub(super) struct MonoKeyframe {
    /// Grey levels in the pinhole geometry.
    pub image: Image<f32>,
    /// `T_wc`.
    pub t_wc: Isometry3<f64>,
    /// Brightness `I = exp(a) L + b` (the map's first keyframe has `a = b = 0`).
    pub a: f64,
    /// See `a`, grey levels.
    pub b: f64,
    pub points: Vec<MonoPoint>,
    /// The active points as an SE(3) reference.
    pub reference: Se3Reference,
    /// Active points when `reference` was built.
    pub built_with: usize,
    /// RMSE of the first frame aligned to it.
    pub first_residual: Option<f64>,
    /// Index of the frame it was made from (set by the tracker; 0 until then).
    pub frame: usize,
    /// Mean grey level of `image` ([`intensity_mean`]).
    pub mean_grey: f64,
}

/// Candidates of `image` in blocks that hold none of `taken`, each an immature point with the
/// prior `N(rho, (prior_sigma rho)^2)`.
fn immature_points(
    image: &Image<f32>,
    taken: &[MonoPoint],
    rho: f64,
    cfg: &DirectMonoConfig,
) -> Result<Vec<MonoPoint>, VoError> {
    let block = cfg.select.block.max(1);
    let (w, h) = image.size();
    let cols = w.div_ceil(block);
    let mut occupied = vec![false; cols * h.div_ceil(block)];
    let cell = |p: &Vector2<f32>| (p.y as usize / block) * cols + p.x as usize / block;
    for p in taken {
        if let Some(o) = occupied.get_mut(cell(&p.pixel)) {
            *o = true;
        }
    }
    let candidates: Vec<Candidate> = select_points(image, &cfg.select)?;
    Ok(candidates
        .iter()
        .filter(|c| !occupied.get(cell(&c.pixel)).copied().unwrap_or(true))
        .map(|c| MonoPoint::immature(c, rho, (cfg.prior_sigma * rho).powi(2)))
        .collect())
}

/// Median inverse depth of the active points (1 without any).
fn median_rho(points: &[MonoPoint], cfg: &DirectMonoConfig) -> f64 {
    let mut rhos: Vec<f64> = points
        .iter()
        .filter(|p| cfg.depth.is_active(p))
        .map(|p| p.filter.rho)
        .collect();
    crate::robust::median_in_place(&mut rhos).unwrap_or(1.0)
}

impl MonoKeyframe {
    /// A keyframe from its points; [`VoError::TooFew`] with fewer than
    /// `min_active_points` active ones.
    fn build(
        image: Image<f32>,
        (t_wc, a, b): (Isometry3<f64>, f64, f64),
        points: Vec<MonoPoint>,
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) -> Result<Self, VoError> {
        let active = active_points(&points, &cfg.depth);
        if active.len() < cfg.min_active_points {
            return Err(VoError::TooFew {
                what: "active points",
                got: active.len(),
                need: cfg.min_active_points,
            });
        }
        let reference =
            Se3Reference::from_inverse_depths(&image, pinhole, None, &active, &cfg.se3)?;
        let mean_grey = intensity_mean(&image);
        Ok(Self {
            image,
            t_wc,
            a,
            b,
            points,
            reference,
            built_with: active.len(),
            first_residual: None,
            frame: 0,
            mean_grey,
        })
    }

    /// The first keyframe of a map: the reference `image` at `t_wc` with the two-view
    /// `seeds` (pixel, inverse depth; 5% uncertain, counted as `min_updates` measurements:
    /// active at once) and immature points in
    /// the other blocks, all refined once in `current` at `t_21`.
    pub fn first(
        image: Image<f32>,
        t_wc: Isometry3<f64>,
        seeds: &[(Vector2<f32>, f64)],
        (current, t_21): (&Image<f32>, &Isometry3<f64>),
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) -> Result<Self, VoError> {
        let mut points: Vec<MonoPoint> = seeds
            .iter()
            .filter_map(|&(pixel, rho)| {
                let (x, y) = (pixel.x, pixel.y);
                let gx = 0.5 * (image.sample(x + 1.0, y)? - image.sample(x - 1.0, y)?);
                let gy = 0.5 * (image.sample(x, y + 1.0)? - image.sample(x, y - 1.0)?);
                let candidate = Candidate {
                    pixel,
                    gradient: Vector2::new(gx, gy),
                    level: 0,
                };
                let mut p = MonoPoint::immature(&candidate, rho, (0.05 * rho).powi(2));
                p.filter.updates = cfg.depth.min_updates;
                Some(p)
            })
            .collect();
        let mut rhos: Vec<f64> = seeds.iter().map(|s| s.1).collect();
        let rho = crate::robust::median_in_place(&mut rhos).unwrap_or(1.0);
        let immature = immature_points(&image, &points, rho, cfg)?;
        points.extend(immature);
        let pair = EpipolarPair {
            reference: &image,
            current,
            pinhole: &pinhole,
            t_cur_ref: t_21,
        };
        refine_points(&mut points, &pair, &cfg.depth);
        Self::build(image, (t_wc, 0.0, 0.0), points, pinhole, cfg)
    }

    /// The next keyframe: `image` at `t_wc` with brightness `(a, b)`, `t_new_old` from this
    /// one, with this keyframe's active points carried over and immature points in the free
    /// blocks.
    pub fn next(
        &self,
        image: Image<f32>,
        (t_wc, a, b): (Isometry3<f64>, f64, f64),
        t_new_old: &Isometry3<f64>,
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) -> Result<Self, VoError> {
        let border = cfg.select.border as f32;
        let mut points = transfer_points(
            &self.points,
            &cfg.depth,
            &pinhole,
            t_new_old,
            &image,
            border,
        );
        let rho = median_rho(&points, cfg);
        let immature = immature_points(&image, &points, rho, cfg)?;
        points.extend(immature);
        Self::build(image, (t_wc, a, b), points, pinhole, cfg)
    }

    /// Refines the points in `current` at `t_cur_kf`; rebuilds the reference when the active
    /// points grew by `rebuild_growth`.
    pub fn refine(
        &mut self,
        current: &Image<f32>,
        t_cur_kf: &Isometry3<f64>,
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) -> Result<(), VoError> {
        self.refine_points(current, t_cur_kf, pinhole, cfg);
        let active = active_points(&self.points, &cfg.depth);
        if active.len() as f64 >= cfg.rebuild_growth * self.built_with as f64 {
            self.reference =
                Se3Reference::from_inverse_depths(&self.image, pinhole, None, &active, &cfg.se3)?;
            self.built_with = active.len();
        }
        Ok(())
    }

    /// Searches every point in `current` at `t_cur_kf` and updates its filter.
    fn refine_points(
        &mut self,
        current: &Image<f32>,
        t_cur_kf: &Isometry3<f64>,
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) {
        let pair = EpipolarPair {
            reference: &self.image,
            current,
            pinhole: &pinhole,
            t_cur_ref: t_cur_kf,
        };
        refine_points(&mut self.points, &pair, &cfg.depth);
    }

    /// For a keyframe of the window (no longer tracked against): refines its immature points
    /// in `current` at `t_cur_kf`, and hands those that converged over to `newest` (moved
    /// into it by `T_newest_self`, [`transfer_points`]).
    pub fn hand_over(
        &mut self,
        newest: &mut MonoKeyframe,
        current: &Image<f32>,
        t_cur_kf: &Isometry3<f64>,
        pinhole: Pinhole,
        cfg: &DirectMonoConfig,
    ) {
        self.refine_points(current, t_cur_kf, pinhole, cfg);
        let (converged, immature): (Vec<MonoPoint>, Vec<MonoPoint>) =
            self.points.iter().partition(|p| cfg.depth.is_active(p));
        self.points = immature;
        let t_new_old = newest.t_wc.inverse() * self.t_wc;
        let border = cfg.select.border as f32;
        let moved = transfer_points(
            &converged,
            &cfg.depth,
            &pinhole,
            &t_new_old,
            &newest.image,
            border,
        );
        newest.points.extend(moved);
    }

    /// Keeps only the immature points (a keyframe entering the window: its active points were
    /// carried into the new keyframe).
    pub fn keep_immature(&mut self, cfg: &DirectMonoConfig) {
        self.points.retain(|p| !cfg.depth.is_active(p));
    }

    /// Its pose (`T_cw`) and brightness as a frame of the photometric bundle.
    pub fn state(&self) -> FrameState {
        FrameState {
            t_cw: self.t_wc.inverse(),
            a: self.a,
            b: self.b,
        }
    }

    /// Median depth of the active points, map units.
    pub fn median_depth(&self, cfg: &DirectMonoConfig) -> f64 {
        1.0 / median_rho(&self.points, cfg).max(1e-9)
    }
}

/// Drops the oldest keyframes of `window` (oldest first; `frame_of` gives the frame each was
/// made from) beyond the newest `keep`, except those made fewer than `young` frames before
/// `now`.
pub(super) fn prune_window<T>(
    window: &mut VecDeque<T>,
    frame_of: impl Fn(&T) -> usize,
    now: usize,
    (keep, young): (usize, usize),
) {
    while window.len() > keep
        && window
            .front()
            .is_some_and(|w| now.saturating_sub(frame_of(w)) >= young)
    {
        window.pop_front();
    }
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;

    use super::prune_window;

    /// One keyframe kept, and any made fewer than three frames ago: at one keyframe per frame
    /// the window holds two; at one per two frames, one.
    #[test]
    fn the_window_keeps_young_keyframes_beyond_its_size() {
        let mut every_frame: VecDeque<usize> = [7, 8, 9].into();
        prune_window(&mut every_frame, |f| *f, 10, (1, 3));
        assert_eq!(every_frame, VecDeque::from([8, 9]));
        let mut every_second: VecDeque<usize> = [4, 6, 8].into();
        prune_window(&mut every_second, |f| *f, 10, (1, 3));
        assert_eq!(every_second, VecDeque::from([8]));
        let mut none_young: VecDeque<usize> = [1, 2].into();
        prune_window(&mut none_young, |f| *f, 10, (0, 3));
        assert!(none_young.is_empty());
    }
}
