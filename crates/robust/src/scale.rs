//! Robust scale estimation.
//!
//! The median absolute deviation (MAD) of Gaussian samples is `0.6745 sigma`, so
//! `sigma_hat = 1.4826 * MAD` estimates the standard deviation of the inliers while ignoring up
//! to half of the samples as outliers. Dividing residuals by `sigma_hat` lets a loss threshold
//! be written in sigmas.

/// `1 / Phi^-1(3/4)`: converts a median absolute deviation into a Gaussian sigma.
pub const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// Median of `values`, reordering them; `None` for an empty slice or any NaN.
pub fn median_in_place(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let len = values.len();
    let mid = len / 2;
    let (lower, upper, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    let upper = *upper;
    if len % 2 == 1 {
        Some(upper)
    } else {
        let lower_max = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(0.5 * (lower_max + upper))
    }
}

/// Gaussian-equivalent sigma `1.4826 * median(|r_i - median(r)|)` of `residuals`.
///
/// `None` for an empty input or NaN. Uses a scratch copy; `residuals` is left untouched.
pub fn mad_sigma(residuals: &[f64]) -> Option<f64> {
    let mut scratch = residuals.to_vec();
    let center = median_in_place(&mut scratch)?;
    for v in &mut scratch {
        *v = (*v - center).abs();
    }
    median_in_place(&mut scratch).map(|m| MAD_TO_SIGMA * m)
}

/// Gaussian-equivalent sigma `1.4826 * median(|r_i|)` for residuals whose true center is zero
/// (reprojection and photometric residuals at the right estimate).
pub fn mad_sigma_about_zero(residuals: &[f64]) -> Option<f64> {
    let mut scratch: Vec<f64> = residuals.iter().map(|r| r.abs()).collect();
    median_in_place(&mut scratch).map(|m| MAD_TO_SIGMA * m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median_in_place(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median_in_place(&mut [4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median_in_place(&mut []), None);
        assert_eq!(median_in_place(&mut [1.0, f64::NAN]), None);
    }

    #[test]
    fn mad_ignores_a_minority_of_outliers() {
        // Symmetric +-1 samples have MAD 1; three huge outliers among eleven do not move it.
        let mut r: Vec<f64> = (0..8)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        r.extend([1e6, -1e6, 1e6]);
        let s = mad_sigma_about_zero(&r).unwrap();
        assert!((s - MAD_TO_SIGMA).abs() < 1e-12, "{s}");
    }
}
