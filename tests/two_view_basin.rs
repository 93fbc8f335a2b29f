//! The basin check of the two-view direct SE(3) pose (`two_view::basin`): in the rendered room,
//! where the pair is well posed, the starts displaced along the optical axis reach the pose of
//! the identity start (well within the stated sigmas) and the pose stays `ok`; a fit from
//! another start that lands elsewhere, beyond `MAX_DISAGREEMENT_SIGMAS`, is counted unless it
//! is `failed`.

use nalgebra::{Isometry3, Translation3};
use vofront::fixtures::stereo::StereoSequence;
use vofront::two_view::basin::{align_from_identity, basin_disagreement_sigmas, displaced_starts};
use vofront::two_view::stereo::MAX_DISAGREEMENT_SIGMAS;
use vofront_direct::{RgbdFrame, Se3Config, Se3Reference, Se3Result};
use vofront_robust::{Reason, Verdict};

/// The room's frames 0 and `gap` with frame 0's exact depth: its reference, the current image,
/// the median depth and the truth `T_21`.
fn room_pair(gap: usize) -> (Se3Reference, vofront_image::Image<f32>, f64, Isometry3<f64>) {
    let seq = StereoSequence::room(5, gap + 1);
    let (first, second) = (seq.render(0), seq.render(gap));
    let frame = RgbdFrame::new(first.left.image, first.left.depth.clone(), &seq.camera).unwrap();
    let reference = Se3Reference::new(&frame, &Se3Config::default()).unwrap();
    let mut depths: Vec<f32> = first
        .left
        .depth
        .data()
        .iter()
        .copied()
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    depths.sort_by(f32::total_cmp);
    let median = f64::from(depths[depths.len() / 2]);
    let truth = seq.poses_wc[gap].inverse() * seq.poses_wc[0];
    (reference, second.left.image, median, truth)
}

#[test]
fn a_well_posed_pair_reaches_one_pose_from_every_start() {
    let (reference, current, median, truth) = room_pair(3);
    let cfg = Se3Config::default();
    let fit = align_from_identity(&reference, &current, median, &cfg).unwrap();
    assert!(fit.quality.is_ok(), "{:?}", fit.quality);
    let error = (fit.pose.inverse() * truth).translation.vector.norm();
    assert!(error < 0.01, "{error} m off the truth");
    let others: Vec<Se3Result> = displaced_starts(median)
        .iter()
        .map(|start| reference.align(&current, start, &cfg).unwrap())
        .collect();
    let sigmas = basin_disagreement_sigmas(&fit, &others).expect("compared");
    assert!(sigmas < 1.0, "the starts disagree by {sigmas} sigmas");
}

#[test]
fn a_fit_elsewhere_that_is_not_failed_flags_the_pose() {
    let (reference, current, median, _) = room_pair(3);
    let cfg = Se3Config::default();
    let fit = align_from_identity(&reference, &current, median, &cfg).unwrap();
    let t_sigma = fit.quality.uncertainty.translation_sigma_m.unwrap();
    let moved_by = |sigmas: f64| {
        let mut other = fit.clone();
        other.pose = Translation3::new(sigmas * t_sigma, 0.0, 0.0) * other.pose;
        other
    };
    let far = moved_by(2.0 * MAX_DISAGREEMENT_SIGMAS);
    let near = moved_by(1.0);
    let far_sigmas = basin_disagreement_sigmas(&fit, std::slice::from_ref(&far)).unwrap();
    assert!(far_sigmas > MAX_DISAGREEMENT_SIGMAS, "{far_sigmas}");
    let near_sigmas = basin_disagreement_sigmas(&fit, &[near.clone(), near]).unwrap();
    assert!(near_sigmas < 1.0, "{near_sigmas}");
    let mut failed = far;
    failed.quality.flag(Reason::TooFewPixels);
    assert_eq!(failed.quality.verdict, Verdict::Failed);
    assert_eq!(basin_disagreement_sigmas(&fit, &[failed]), None);
}
