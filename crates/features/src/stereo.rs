//! Stereo matching of ORB features between the left and right images of a rectified pair.
//!
//! In a rectified pair a point seen at `(x_l, y)` in the left image is seen at `(x_r, y)` in
//! the right one, `x_r = x_l - d`, with the disparity `d = f b / Z > 0` (focal length `f` in
//! pixels, baseline `b` and depth `Z` in metres). [`match_stereo`], as ORB-SLAM2's stereo
//! matching, for every left feature:
//!
//! 1. takes the right features whose row band `y_r +- row_radius * scale_r` contains `y_l`,
//!    whose pyramid level is within one of the left feature's, and whose disparity
//!    `x_l - x_r` is in `[min_disparity, max_disparity]`;
//! 2. keeps the nearest by Hamming distance when it is under `max_distance` and, with a ratio
//!    test, clearly nearer than the second (repeated texture along the row is ambiguous);
//! 3. refines `x_r` to sub-pixel: the zero-mean sum of squared differences of a
//!    `(2 patch_radius + 1)^2` level-0 patch around the left feature, slid along the row of the
//!    right image over `x_r +- search_px` (a best shift at an end of the search is rejected: no
//!    clear minimum), then a 1D patch alignment from the best shift, Gauss-Newton on the column
//!    `c` of `sum_k (R(c + k) - (g L(x_l + k) + o))^2` with the gain `g` and offset `o` of the
//!    two patches (cameras with different exposure); one that leaves the pixel is rejected;
//! 4. after all features: a right feature claimed by two left ones goes to the nearer
//!    descriptor, and a match whose patch difference (RMS of the zero-mean patches at the best
//!    shift) exceeds `max_difference_ratio` times the median difference is
//!    rejected (occlusions and wrong minima).
//!
//! The result's disparity carries a relative noise scale, the left keypoint's pyramid scale
//! (the unit of [`StereoMatch::depth_sigma`]'s pixel noise), so that depth uncertainty follows
//! first-order propagation `sigma_Z = f b / d^2 sigma_d`.

use rayon::prelude::*;
use vofront_image::Image;

use crate::{FeatureError, Features};

/// Largest `search_px` accepted (the difference profile is a fixed-size array).
pub const MAX_SEARCH_PX: usize = 16;

/// Options of [`match_stereo`].
#[derive(Debug, Clone, PartialEq)]
pub struct StereoConfig {
    /// Smallest disparity accepted, pixels (`> 0`: a point at infinity has no depth).
    pub min_disparity: f32,
    /// Largest disparity accepted, pixels (nearest depth `f b / max_disparity`).
    pub max_disparity: f32,
    /// Half-height of a right feature's row band, in units of its pyramid scale (level-0
    /// pixels at level 0).
    pub row_radius: f32,
    /// Largest Hamming distance of an accepted match, bits.
    pub max_distance: u32,
    /// Ratio test: the best distance must be under `ratio` times the second best among the
    /// candidates on the row; `None` disables it.
    pub ratio: Option<f32>,
    /// Half-size of the compared patches, level-0 pixels (at most [`MAX_PATCH_RADIUS`]).
    pub patch_radius: usize,
    /// Shifts tried on either side of the descriptor match, level-0 pixels
    /// (at most [`MAX_SEARCH_PX`]).
    pub search_px: usize,
    /// A match whose patch difference exceeds this times the median difference of all
    /// matches is rejected.
    pub max_difference_ratio: f32,
}

impl Default for StereoConfig {
    /// ORB-SLAM2's choices: disparities up to 192 px, bands of +-2 pyramid pixels, Hamming
    /// distance under 75 bits, an 11x11 patch slid +-5 px, patch differences under 2.1 times the median;
    /// plus a ratio test at 0.9 against repeated texture along the row.
    fn default() -> Self {
        Self {
            min_disparity: 0.5,
            max_disparity: 192.0,
            row_radius: 2.0,
            max_distance: 75,
            ratio: Some(0.9),
            patch_radius: 5,
            search_px: 5,
            max_difference_ratio: 2.1,
        }
    }
}

impl StereoConfig {
    /// [`FeatureError::InvalidConfig`] unless `0 < min_disparity < max_disparity` (finite),
    /// `row_radius > 0`, `ratio` in `(0, 1]`, `1 <= patch_radius <=` [`MAX_PATCH_RADIUS`],
    /// `1 <= search_px <=` [`MAX_SEARCH_PX`] and `max_difference_ratio > 0`.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = FeatureError::InvalidConfig;
        if !(self.min_disparity > 0.0
            && self.max_disparity.is_finite()
            && self.min_disparity < self.max_disparity)
        {
            return Err(bad("stereo: need 0 < min_disparity < max_disparity"));
        }
        if !(self.row_radius > 0.0 && self.row_radius.is_finite()) {
            return Err(bad("stereo: row_radius must be positive"));
        }
        if let Some(r) = self.ratio {
            if !(r > 0.0 && r <= 1.0) {
                return Err(bad("stereo: ratio must be in (0, 1]"));
            }
        }
        if self.patch_radius == 0 || self.search_px == 0 || self.search_px > MAX_SEARCH_PX {
            return Err(bad(
                "stereo: need patch_radius >= 1 and 1 <= search_px <= 16",
            ));
        }
        if self.max_difference_ratio.is_nan() || self.max_difference_ratio <= 0.0 {
            return Err(bad("stereo: max_difference_ratio must be positive"));
        }
        Ok(())
    }
}

/// A left feature matched to a right one along its row.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StereoMatch {
    /// Index of the left feature.
    pub left: u32,
    /// Index of the right feature.
    pub right: u32,
    /// Hamming distance of their descriptors, bits.
    pub distance: u32,
    /// Sub-pixel column of the point in the right image, level-0 pixels.
    pub right_x: f32,
    /// `x_l - right_x`, pixels (`> 0`).
    pub disparity: f32,
    /// Relative noise scale of the disparity: the left keypoint's pyramid scale (1 at level 0).
    pub noise_scale: f32,
    /// RMS difference of the zero-mean patches at the best whole shift, grey levels.
    pub difference: f32,
}

impl StereoMatch {
    /// Depth `Z = f b / d`, metres, for `fb` = focal length (pixels) times baseline (metres).
    pub fn depth(&self, fb: f64) -> f64 {
        fb / f64::from(self.disparity)
    }

    /// First-order standard deviation of [`StereoMatch::depth`], metres:
    /// `sigma_Z = f b / d^2 * sigma_px * noise_scale`, for a disparity noise of `sigma_px`
    /// pixels at level 0.
    pub fn depth_sigma(&self, fb: f64, sigma_px: f64) -> f64 {
        let d = f64::from(self.disparity);
        fb / (d * d) * sigma_px * f64::from(self.noise_scale)
    }
}

/// Right features listed per image row: row `y` holds every right feature whose band
/// `y_r +- row_radius * scale_r` covers it.
struct RowIndex {
    /// `starts[y]..starts[y + 1]` indexes `items` for row `y`.
    starts: Vec<usize>,
    items: Vec<u32>,
}

impl RowIndex {
    fn new(right: &Features, rows: usize, row_radius: f32) -> Self {
        let band = |i: usize| -> Option<(usize, usize)> {
            let (y, r) = (right.ys()[i], row_radius * right.scales()[i]);
            if !(y.is_finite() && r.is_finite()) {
                return None;
            }
            let lo = (y - r).ceil().max(0.0) as usize;
            let hi = ((y + r).floor().max(-1.0) + 1.0) as usize;
            (lo < hi.min(rows)).then_some((lo, hi.min(rows)))
        };
        let mut starts = vec![0usize; rows + 1];
        for (lo, hi) in (0..right.len()).filter_map(band) {
            for row in lo..hi {
                starts[row + 1] += 1;
            }
        }
        for y in 0..rows {
            starts[y + 1] += starts[y];
        }
        let mut fill = starts.clone();
        let mut items = vec![0u32; starts[rows]];
        for i in 0..right.len() {
            if let Some((lo, hi)) = band(i) {
                for row in lo..hi {
                    items[fill[row]] = i as u32;
                    fill[row] += 1;
                }
            }
        }
        Self { starts, items }
    }

    fn row(&self, y: usize) -> &[u32] {
        match (self.starts.get(y), self.starts.get(y + 1)) {
            (Some(&a), Some(&b)) => &self.items[a..b],
            _ => &[],
        }
    }
}

/// Matches `left` features to `right` features of a rectified pair along their rows and
/// refines each disparity to sub-pixel on the level-0 images (see the module documentation).
/// Sorted by left index; each left and each right feature appears at most once.
///
/// [`FeatureError::InvalidConfig`] for an invalid `cfg` or images of different sizes.
pub fn match_stereo(
    left: &Features,
    right: &Features,
    left_image: &Image<u8>,
    right_image: &Image<u8>,
    cfg: &StereoConfig,
) -> Result<Vec<StereoMatch>, FeatureError> {
    cfg.validate()?;
    if left_image.size() != right_image.size() {
        return Err(FeatureError::InvalidConfig(
            "stereo: left and right images differ in size",
        ));
    }
    let index = RowIndex::new(right, left_image.height(), cfg.row_radius);
    let mut matches: Vec<StereoMatch> = (0..left.len() as u32)
        .into_par_iter()
        .filter_map(|i| {
            let (j, distance) = nearest_on_row(left, right, &index, i, cfg)?;
            let x_l = left.xs()[i as usize];
            let y = left.ys()[i as usize];
            let (right_x, difference) =
                refine(left_image, right_image, x_l, right.xs()[j as usize], y, cfg)?;
            let disparity = x_l - right_x;
            (disparity >= cfg.min_disparity && disparity <= cfg.max_disparity).then_some(
                StereoMatch {
                    left: i,
                    right: j,
                    distance,
                    right_x,
                    disparity,
                    noise_scale: left.scales()[i as usize],
                    difference,
                },
            )
        })
        .collect();
    keep_nearest_per_right(&mut matches, right.len());
    reject_high_difference(&mut matches, cfg.max_difference_ratio);
    Ok(matches)
}

/// The nearest right candidate of left feature `i` on its row and its distance, if it passes
/// the distance and ratio tests.
fn nearest_on_row(
    left: &Features,
    right: &Features,
    index: &RowIndex,
    i: u32,
    cfg: &StereoConfig,
) -> Option<(u32, u32)> {
    let i = i as usize;
    let (x_l, y_l, level) = (left.xs()[i], left.ys()[i], left.levels()[i]);
    if !(x_l.is_finite() && y_l.is_finite()) || y_l < -0.5 {
        return None;
    }
    let descriptor = &left.descriptors()[i];
    let (mut best, mut best_d, mut second_d) = (u32::MAX, u32::MAX, u32::MAX);
    for &j in index.row(y_l.round() as usize) {
        let j_us = j as usize;
        let d = x_l - right.xs()[j_us];
        if !(d >= cfg.min_disparity - 1.0 && d <= cfg.max_disparity + 1.0)
            || right.levels()[j_us].abs_diff(level) > 1
        {
            continue;
        }
        let h = descriptor.hamming(&right.descriptors()[j_us]);
        if h < best_d {
            (second_d, best_d, best) = (best_d, h, j);
        } else if h < second_d {
            second_d = h;
        }
    }
    let unambiguous = match cfg.ratio {
        Some(r) => second_d == u32::MAX || (best_d as f32) < r * second_d as f32,
        None => true,
    };
    (best != u32::MAX && best_d <= cfg.max_distance && unambiguous).then_some((best, best_d))
}

/// Sub-pixel right column of the point at the left pixel `(round(x_l), round(y))` whose
/// descriptor match is at `x_r`, and the RMS difference of the zero-mean patches at the best
/// whole shift; `None` when a patch leaves an image, the difference profile has its minimum at
/// an end of the search, or the 1D alignment does not settle within a pixel of it.
fn refine(
    left: &Image<u8>,
    right: &Image<u8>,
    x_l: f32,
    x_r: f32,
    y: f32,
    cfg: &StereoConfig,
) -> Option<(f32, f32)> {
    let (w, s) = (cfg.patch_radius as isize, cfg.search_px as isize);
    let (xl, xr, yc) = (
        x_l.round() as isize,
        x_r.round() as isize,
        y.round() as isize,
    );
    let (width, height) = (left.width() as isize, left.height() as isize);
    // Two more columns on each side of the slide for the alignment's interpolation.
    let inside = |x: isize, margin: isize| x - margin >= 0 && x + margin < width;
    if !(inside(xl, w) && inside(xr, w + s + 2) && yc - w >= 0 && yc + w < height) {
        return None;
    }
    let patch = Patch::new(left, xl as usize, yc as usize, w as usize);
    let mut profile = [f32::INFINITY; 2 * MAX_SEARCH_PX + 1];
    for k in -s..=s {
        profile[(k + s) as usize] = patch.zero_mean_ssd(right, (xr + k) as usize);
    }
    let used = &profile[..(2 * s + 1) as usize];
    let (best, &ssd) = used.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    if best == 0 || best + 1 == used.len() {
        return None;
    }
    let start = (xr + best as isize - s) as f32;
    let column = patch.align_along_row(right, start)?;
    // The column of the left pixel `xl`; the keypoint at `x_l` lies `x_l - xl` beside it.
    Some((column + (x_l - xl as f32), (ssd / patch.len()).sqrt()))
}

/// Largest `patch_radius` accepted (the patch is a fixed-size array).
pub const MAX_PATCH_RADIUS: usize = 7;

/// Side of the largest patch.
const MAX_SIDE: usize = 2 * MAX_PATCH_RADIUS + 1;

/// A square patch of the left image around `(x, y)`: `side = 2 radius + 1` rows of `side`
/// values, copied once.
struct Patch {
    y: usize,
    radius: usize,
    values: [[u8; MAX_SIDE]; MAX_SIDE],
    /// Sum of the values.
    sum: i32,
}

impl Patch {
    fn new(left: &Image<u8>, x: usize, y: usize, radius: usize) -> Self {
        let mut values = [[0u8; MAX_SIDE]; MAX_SIDE];
        let side = 2 * radius + 1;
        for (dy, out) in values.iter_mut().take(side).enumerate() {
            out[..side].copy_from_slice(&left.row(y + dy - radius)[x - radius..=x + radius]);
        }
        let sum = values[..side]
            .iter()
            .flat_map(|r| &r[..side])
            .map(|&v| i32::from(v))
            .sum();
        Self {
            y,
            radius,
            values,
            sum,
        }
    }

    fn side(&self) -> usize {
        2 * self.radius + 1
    }

    fn len(&self) -> f32 {
        (self.side() * self.side()) as f32
    }

    /// `(row of the patch, image row)` pairs.
    fn rows(&self) -> impl Iterator<Item = (&[u8], usize)> + '_ {
        let side = self.side();
        self.values[..side]
            .iter()
            .enumerate()
            .map(move |(dy, r)| (&r[..side], self.y + dy - self.radius))
    }

    /// Sum of squared differences of the zero-mean patches, the left one and the right one
    /// centred at whole column `x`: `sum (q - p)^2 - (sum q - sum p)^2 / n`.
    fn zero_mean_ssd(&self, right: &Image<u8>, x: usize) -> f32 {
        let (mut sq, mut sum_q) = (0i32, 0i32);
        for (a, y) in self.rows() {
            let b = &right.row(y)[x - self.radius..=x + self.radius];
            for (&p, &q) in a.iter().zip(b) {
                let d = i32::from(q) - i32::from(p);
                sq += d * d;
                sum_q += i32::from(q);
            }
        }
        let mean_gap = (sum_q - self.sum) as f32;
        (sq as f32 - mean_gap * mean_gap / self.len()).max(0.0)
    }

    /// The column `c` near `start` where the right patch matches the left one up to gain and
    /// offset, `R(c + k, y) ~ g L(x + k, y) + o`: Gauss-Newton on `c`, with `g` and `o` from the
    /// two patches' means and spreads at `start`; `None` unless it settles within one pixel of
    /// `start`. All samples of one step share the fraction of `c`, so each row is one linear
    /// blend of two slices.
    fn align_along_row(&self, right: &Image<u8>, start: f32) -> Option<f32> {
        let n = self.len();
        let side = self.side();
        let x0 = start as usize - self.radius;
        let (mut sum_r, mut sq_r, mut sq_l) = (0.0f32, 0.0f32, 0.0f32);
        for (a, y) in self.rows() {
            for (&p, &q) in a.iter().zip(&right.row(y)[x0..x0 + side]) {
                sum_r += f32::from(q);
                sq_r += f32::from(q) * f32::from(q);
                sq_l += f32::from(p) * f32::from(p);
            }
        }
        let (mean_l, mean_r) = (self.sum as f32 / n, sum_r / n);
        let spread_l = sq_l - mean_l * self.sum as f32;
        let spread_r = sq_r - mean_r * sum_r;
        if spread_l <= 0.0 || spread_r <= 0.0 {
            return None;
        }
        let gain = (spread_r / spread_l).sqrt();
        let offset = mean_r - gain * mean_l;
        let mut c = start;
        for _ in 0..ALIGN_ITERATIONS {
            let i = c.floor();
            let f = c - i;
            // Samples R(c + k - 1) .. R(c + k + 1) come from columns i - radius - 1 ..
            let first = i as usize - self.radius - 1;
            let (mut jr, mut jj) = (0.0f32, 0.0f32);
            for (a, y) in self.rows() {
                let row = &right.row(y)[first..first + side + 3];
                let at =
                    |k: usize| f32::from(row[k]) + f * (f32::from(row[k + 1]) - f32::from(row[k]));
                for (k, &p) in a.iter().enumerate() {
                    let r = at(k + 1) - (gain * f32::from(p) + offset);
                    let j = 0.5 * (at(k + 2) - at(k));
                    jr += j * r;
                    jj += j * j;
                }
            }
            if jj.is_nan() || jj <= 0.0 {
                return None;
            }
            let step = (-jr / jj).clamp(-0.5, 0.5);
            c += step;
            if (c - start).abs() > 1.0 {
                return None;
            }
            if step.abs() < 1e-3 {
                break;
            }
        }
        Some(c)
    }
}

/// Gauss-Newton iterations of the 1D patch alignment.
const ALIGN_ITERATIONS: usize = 8;

/// Keeps, for each right feature claimed more than once, the match with the smallest
/// descriptor distance (then the smallest patch difference); sorted by left index.
fn keep_nearest_per_right(matches: &mut Vec<StereoMatch>, n_right: usize) {
    let mut owner: Vec<Option<usize>> = vec![None; n_right];
    for (k, m) in matches.iter().enumerate() {
        let slot = &mut owner[m.right as usize];
        let better = match *slot {
            None => true,
            Some(o) => {
                let o = &matches[o];
                (m.distance, m.difference) < (o.distance, o.difference)
            }
        };
        if better {
            *slot = Some(k);
        }
    }
    let mut k = 0;
    matches.retain(|m| {
        let keep = owner[m.right as usize] == Some(k);
        k += 1;
        keep
    });
}

/// Drops the matches whose patch difference exceeds `ratio` times the median difference.
fn reject_high_difference(matches: &mut Vec<StereoMatch>, ratio: f32) {
    if matches.is_empty() {
        return;
    }
    let mut differences: Vec<f32> = matches.iter().map(|m| m.difference).collect();
    let mid = differences.len() / 2;
    let (_, median, _) = differences.select_nth_unstable_by(mid, f32::total_cmp);
    let limit = ratio * *median;
    matches.retain(|m| m.difference <= limit);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_row_index_lists_a_feature_on_every_row_of_its_band() {
        let d = crate::Descriptor([0; 4]);
        let right = Features::new(
            vec![10.0, 20.0],
            vec![5.2, 40.0],
            vec![0, 1],
            vec![1.0, 1.2],
            vec![0.0; 2],
            vec![1.0; 2],
            vec![d; 2],
        )
        .unwrap();
        let index = RowIndex::new(&right, 50, 2.0);
        // Band 5.2 +- 2 covers rows 4..=7; band 40 +- 2.4 covers 38..=42.
        let rows_of =
            |j: u32| -> Vec<usize> { (0..50).filter(|&y| index.row(y).contains(&j)).collect() };
        assert_eq!(rows_of(0), vec![4, 5, 6, 7]);
        assert_eq!(rows_of(1), vec![38, 39, 40, 41, 42]);
        assert!(index.row(60).is_empty());
    }

    /// A seeded pseudo-random texture, blurred horizontally so that difference profiles are smooth.
    fn texture(width: usize, height: usize, seed: u32) -> Image<u8> {
        let raw: Vec<u32> = (0..width * height)
            .map(|i| (i as u32 ^ seed).wrapping_mul(2_654_435_761) >> 24)
            .collect();
        let data = (0..width * height)
            .map(|i| {
                let x = i % width;
                let (a, b) = (raw[i], raw[i - x + (x + 1).min(width - 1)]);
                ((a + b) / 2) as u8
            })
            .collect();
        Image::new(width, height, data).unwrap()
    }

    #[test]
    fn an_integer_shift_is_found_exactly_and_a_far_one_is_rejected() {
        let left = texture(80, 40, 7);
        // right(x) = left(x + 6): the point at x_l is at x_l - 6 in the right image.
        let right = Image::new(
            80,
            40,
            (0..80 * 40)
                .map(|i| {
                    let (x, y) = (i % 80, i / 80);
                    left.at((x + 6).min(79), y)
                })
                .collect(),
        )
        .unwrap();
        let cfg = StereoConfig::default();
        // The descriptor match 2 px off: the slide finds the true column.
        let (x, difference) = refine(&left, &right, 40.0, 36.0, 20.0, &cfg).unwrap();
        assert!((x - 34.0).abs() < 0.01, "{x}");
        assert!(difference < 1e-3, "{difference}");
        // 5 px off with a +-5 px slide: the minimum is at the end of the search, rejected.
        assert_eq!(refine(&left, &right, 40.0, 39.0, 20.0, &cfg), None);
    }
}
