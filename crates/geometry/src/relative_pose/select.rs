//! Step 2 of the pipeline, model selection: LO-MSAC of the essential matrix and of a
//! homography, and ORB-SLAM's score ratio between them.
//!
//! With `sigma` the Sampson threshold, over all correspondences and both images,
//! `S_H = sum max(0, 5.99 - d^2 / sigma^2)` over the transfer errors and
//! `S_E = sum [d^2 / sigma^2 < 3.84] (5.99 - d^2 / sigma^2)` over the distances to the epipolar
//! lines; the homography is preferred when `S_H / (S_H + S_E) > homography_ratio`.

use nalgebra::Matrix3;

use super::correspondences::Correspondences;
use super::estimators::{EssentialEstimator, HomographyEstimator, HomographyModel};
use super::prepare::TwoView;
use super::quality::ESSENTIAL_SOLUTIONS;
use super::types::{Model, RansacIterations};
use crate::ransac::{ransac, required_iterations, RansacConfig, RansacResult};
use crate::residual::{epipolar_distances_sq, transfer_sq};

/// Chi-square (95%, 2 DoF) bound of ORB-SLAM's homography score, also its score offset.
const CHI2_2DOF: f64 = 5.99;
/// Chi-square (95%, 1 DoF) bound of ORB-SLAM's epipolar score.
const CHI2_1DOF: f64 = 3.84;
/// Lower bound on the homography's iteration budget.
const H_MIN_ITERATIONS: usize = 100;

/// The two RANSAC fits and the score ratio between them.
pub(super) struct Selection {
    /// The essential matrix's fit, if any.
    pub essential: Option<RansacResult<Matrix3<f64>>>,
    /// The homography's fit, if any.
    pub homography: Option<RansacResult<HomographyModel>>,
    /// `S_H / (S_H + S_E)` (zero when both scores are zero).
    pub ratio: f64,
    /// RANSAC iterations of each model.
    pub iterations: RansacIterations,
}

impl Selection {
    /// The homography's fit, when its score ratio exceeds `homography_ratio`.
    pub fn preferred_homography(
        &self,
        homography_ratio: f64,
    ) -> Option<&RansacResult<HomographyModel>> {
        self.homography
            .as_ref()
            .filter(|_| self.ratio > homography_ratio)
    }

    /// Hypotheses RANSAC scored: up to ten essential matrices per five-point sample, one
    /// homography per four-point sample.
    pub fn hypotheses(&self) -> f64 {
        (ESSENTIAL_SOLUTIONS * self.iterations.essential + self.iterations.homography) as f64
    }

    /// Inliers of `model`'s fit (zero when it was not found).
    pub fn support(&self, model: Model) -> usize {
        match model {
            Model::Homography => self.homography.as_ref().map_or(0, |h| h.inlier_count()),
            Model::Essential => self.essential.as_ref().map_or(0, |e| e.inlier_count()),
        }
    }
}

/// Fits both models and scores them.
pub(super) fn select_model(tv: &TwoView) -> Selection {
    let (data, cfg) = (&tv.data, tv.cfg);
    let rcfg = cfg.ransac.in_normalized_units(tv.focal);
    let hcfg = |max_iterations: usize| RansacConfig {
        threshold: tv.transfer_threshold(),
        max_iterations: max_iterations
            .max(H_MIN_ITERATIONS)
            .min(cfg.ransac.max_iterations),
        // The homography's refit is one linear fit, cheap beside the essential matrix's
        // iterative one: it refits on every inlier, so that model selection weighs a homography
        // polished on all of them.
        lo_max_inliers: usize::MAX,
        ..rcfg
    };
    // The homography's least budget runs beside the essential matrix's search (the seeded
    // sampler makes it the start of any longer run, so running it again with more iterations
    // gives what one longer run would).
    let least = hcfg(H_MIN_ITERATIONS);
    let (essential, speculative) = rayon::join(
        || ransac(&EssentialEstimator(data, 0.5 * tv.threshold), &rcfg),
        || ransac(&HomographyEstimator(data), &least),
    );
    // The homography only matters if it can compete with the essential matrix: it gets the
    // iterations that find an all-inlier 4-sample when its inlier ratio equals the essential's.
    let h_iterations = essential.as_ref().map_or(cfg.ransac.max_iterations, |e| {
        required_iterations(
            rcfg.confidence,
            e.inlier_count() as f64 / data.len() as f64,
            4,
        )
    });
    let budget = hcfg(h_iterations);
    let homography = if budget == least {
        speculative
    } else {
        ransac(&HomographyEstimator(data), &budget)
    };
    let (s_h, s_e) = model_scores(
        data,
        essential.as_ref().map(|r| &r.model),
        homography.as_ref().map(|r| &r.model),
        tv.threshold,
    );
    let ratio = if s_h + s_e > 0.0 {
        s_h / (s_h + s_e)
    } else {
        0.0
    };
    let iterations = RansacIterations {
        essential: essential.as_ref().map_or(0, |r| r.iterations),
        homography: homography.as_ref().map_or(0, |r| r.iterations),
    };
    Selection {
        essential,
        homography,
        ratio,
        iterations,
    }
}

/// ORB-SLAM scores `(S_H, S_E)` of the two models over all correspondences.
fn model_scores(
    data: &Correspondences,
    e: Option<&Matrix3<f64>>,
    h: Option<&HomographyModel>,
    sigma: f64,
) -> (f64, f64) {
    let inv_s2 = 1.0 / (sigma * sigma);
    let term = |d2: f64, bound: f64| {
        let c = d2 * inv_s2;
        if c < bound {
            CHI2_2DOF - c
        } else {
            0.0
        }
    };
    let mut s_h = 0.0;
    let mut s_e = 0.0;
    for i in 0..data.len() {
        let (p1, p2) = (data.p1(i), data.p2(i));
        if let Some(h) = h {
            let (a, b) = transfer_sq(&h.h, &h.h_inv, &p1, &p2);
            s_h += term(a, CHI2_2DOF) + term(b, CHI2_2DOF);
        }
        if let Some(e) = e {
            let (d1, d2) = epipolar_distances_sq(e, &p1, &p2);
            s_e += term(d1, CHI2_1DOF) + term(d2, CHI2_1DOF);
        }
    }
    (s_h, s_e)
}
