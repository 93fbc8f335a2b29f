//! The tracker's side of the windowed photometric bundle adjustment
//! ([`vofront_direct::mono::photometric_bundle`]): when a frame becomes a keyframe, the
//! outgoing keyframe's active points (hosted there) are refined jointly with the poses and
//! brightness of the last keyframes, the outgoing one and the new one; the oldest two frames
//! of the window hold the gauge (pose and scale).
//!
//! Brightness: each frame carries `(a, b)` with `I = exp(a) L + b`. A frame aligned to a
//! keyframe `(a_k, b_k)` with gain and offset `I_cur = alpha I_kf + beta` has
//! `a = a_k + ln alpha`, `b = beta + alpha b_k`.

use std::collections::VecDeque;

use nalgebra::Isometry3;
use vofront_core::Pinhole;
use vofront_direct::mono::{photometric_bundle, BundleFrame, BundlePoint, FrameState};
use vofront_direct::Se3Result;
use vofront_image::Image;

use super::config::DirectMonoConfig;
use super::keyframe::MonoKeyframe;
use crate::error::VoError;

/// A keyframe that has left tracking but still takes part in the bundle.
pub(super) struct WindowFrame {
    /// Grey levels in the pinhole geometry.
    pub image: Image<f32>,
    pub state: FrameState,
}

/// The state of a frame at `t_wc` aligned to `kf` by `fit` (module documentation).
pub(super) fn frame_state(kf: &MonoKeyframe, t_wc: &Isometry3<f64>, fit: &Se3Result) -> FrameState {
    FrameState {
        t_cw: t_wc.inverse(),
        a: kf.a + fit.a.max(1e-6).ln(),
        b: fit.b + fit.a * kf.b,
    }
}

/// At most `most` of `items`, evenly spread over their order (all of them when they are few).
fn even_share(items: Vec<usize>, most: usize) -> Vec<usize> {
    let n = items.len();
    if n <= most {
        return items;
    }
    (0..most).map(|i| items[i * n / most]).collect()
}

/// Refines `older`, `kf` and the frame `current` (state `state`) with `kf`'s active points
/// (at most `bundle_points` of them, [`even_share`]);
/// writes the refined states into `older` and `kf`, the refined inverse depths into `kf`'s
/// points (dropping the outliers), and returns the current frame's refined state.
pub(super) fn refine_window(
    older: &mut VecDeque<WindowFrame>,
    kf: &mut MonoKeyframe,
    (current, state): (&Image<f32>, FrameState),
    pinhole: Pinhole,
    cfg: &DirectMonoConfig,
) -> Result<FrameState, VoError> {
    let host = older.len();
    let kf_state = kf.state();
    let frames: Vec<BundleFrame> = older
        .iter()
        .map(|f| BundleFrame {
            image: &f.image,
            state: f.state,
        })
        .chain([
            BundleFrame {
                image: &kf.image,
                state: kf_state,
            },
            BundleFrame {
                image: current,
                state,
            },
        ])
        .collect();
    let active: Vec<usize> = (0..kf.points.len())
        .filter(|&j| cfg.depth.is_active(&kf.points[j]))
        .collect();
    let active = even_share(active, cfg.bundle_points);
    let points: Vec<BundlePoint> = active
        .iter()
        .map(|&j| BundlePoint {
            host,
            pixel: kf.points[j].pixel,
            rho: kf.points[j].filter.rho,
        })
        .collect();
    let fit = photometric_bundle(&pinhole, &frames, &points, &cfg.bundle)?;
    for (frame, refined) in older.iter_mut().zip(&fit.frames) {
        frame.state = *refined;
    }
    let refined_kf = fit.frames[host];
    kf.t_wc = refined_kf.t_cw.inverse();
    (kf.a, kf.b) = (refined_kf.a, refined_kf.b);
    let mut outlier = vec![false; kf.points.len()];
    for ((&j, &rho), &out) in active.iter().zip(&fit.rhos).zip(&fit.outlier) {
        kf.points[j].filter.rho = rho;
        outlier[j] = out;
    }
    let mut keep = outlier.iter().map(|o| !o);
    kf.points.retain(|_| keep.next().unwrap_or(true));
    Ok(fit.frames[host + 1])
}

#[cfg(test)]
mod tests {
    use super::even_share;

    #[test]
    fn an_even_share_spans_the_whole_order() {
        let items: Vec<usize> = (0..10).collect();
        assert_eq!(even_share(items.clone(), 20), items);
        assert_eq!(even_share(items.clone(), 5), vec![0, 2, 4, 6, 8]);
        assert_eq!(even_share(items.clone(), 3), vec![0, 3, 6]);
        assert!(even_share(items, 0).is_empty());
    }
}
