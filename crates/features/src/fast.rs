//! FAST-9 corners: 16-pixel Bresenham circle of radius 3, a contiguous arc of at least 9
//! pixels all brighter than `I(p) + t` or all darker than `I(p) - t`.
//!
//! The corner score, used only for non-maximum suppression (Harris ranks the survivors), is
//! the sum of absolute differences to the centre over the brighter or darker circle pixels.
//! Detection runs in two passes per
//! grid cell (threshold fallback): `fast_threshold` everywhere, then `min_fast_threshold` in
//! the cells where the first pass found nothing; then a 3x3 non-maximum suppression on the score.

use vofront_image::Image;

/// Circle offsets `(dx, dy)`, clockwise from the top.
const CIRCLE: [(isize, isize); 16] = [
    (0, -3),
    (1, -3),
    (2, -2),
    (3, -1),
    (3, 0),
    (3, 1),
    (2, 2),
    (1, 3),
    (0, 3),
    (-1, 3),
    (-2, 2),
    (-3, 1),
    (-3, 0),
    (-3, -1),
    (-2, -2),
    (-1, -3),
];

/// An axis-aligned pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

/// A FAST corner at integer level coordinates with its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Corner {
    pub x: u32,
    pub y: u32,
    pub score: u16,
}

/// Index offsets of the circle for a row stride.
fn circle_offsets(stride: usize) -> [isize; 16] {
    CIRCLE.map(|(dx, dy)| dy * stride as isize + dx)
}

/// The exact FAST-9 test at threshold `t` and the corner score. 16-bit masks of the
/// brighter (`> I + t`) and darker (`< I - t`) circle pixels are searched for a run of 9 set
/// bits (with wrap-around) by shifting and AND-ing. The score of a corner is
/// `max(sum_bright (I(q) - I(p)), sum_dark (I(p) - I(q)))` over the polarity that has an arc
/// (Rosten and Drummond's sum of absolute differences), `None` if not a corner.
#[inline(always)]
fn corner_score(data: &[u8], c: usize, offsets: &[isize; 16], t: u8) -> Option<u16> {
    let v = data[c];
    let (hi, lo) = (v.saturating_add(t), v.saturating_sub(t));
    let ring: [u8; 16] = std::array::from_fn(|k| data[(c as isize + offsets[k]) as usize]);
    let (mut bright, mut dark) = (0u32, 0u32);
    for (k, &p) in ring.iter().enumerate() {
        bright |= ((p > hi) as u32) << k;
        dark |= ((p < lo) as u32) << k;
    }
    // Over the brighter pixels, sum (p - v) = sum sat(p - hi) + t * count, and likewise for
    // the darker ones: saturating byte differences that vectorize.
    let over: u16 = ring.iter().map(|&p| p.saturating_sub(hi) as u16).sum();
    let under: u16 = ring.iter().map(|&p| lo.saturating_sub(p) as u16).sum();
    let sum_bright = over + t as u16 * bright.count_ones() as u16;
    let sum_dark = under + t as u16 * dark.count_ones() as u16;
    let arc9 = |m: u32| {
        let m = m | (m << 16);
        let a = m & (m >> 1);
        let a = a & (a >> 2);
        let a = a & (a >> 4);
        a & (m >> 8) & 0xffff != 0
    };
    match (arc9(bright), arc9(dark)) {
        (false, false) => None,
        (true, false) => Some(sum_bright),
        (false, true) => Some(sum_dark),
        (true, true) => Some(sum_bright.max(sum_dark)),
    }
}

/// Pixels per block of the quick test.
const LANES: usize = 32;

/// Quick rejection for pixels `x..x + LANES` of a row: a 9-arc contains at least one pixel of
/// every antipodal pair `(k, k + 8)`, so a corner needs that for all 8 pairs, all brighter
/// than `I + t` or all darker than `I - t`. Fixed-size, branch-free lanes that LLVM keeps in
/// vector registers; the pairs `(0, 8)` and `(4, 12)` are tried first to skip empty blocks.
/// Returns a bit mask of the surviving pixels.
#[inline(always)]
fn quick_test(centre: &[u8], ring: &[&[u8]; 16], x: usize, t: u8) -> u32 {
    let block =
        |s: &[u8]| -> [u8; LANES] { s[x..x + LANES].try_into().expect("block of LANES pixels") };
    let v = block(centre);
    let hi: [u8; LANES] = std::array::from_fn(|i| v[i].saturating_add(t));
    let lo: [u8; LANES] = std::array::from_fn(|i| v[i].saturating_sub(t));
    let mut bright = [0xffu8; LANES];
    let mut dark = [0xffu8; LANES];
    let pair = |k: usize, bright: &mut [u8; LANES], dark: &mut [u8; LANES]| {
        let (a, b) = (block(ring[k]), block(ring[k + 8]));
        for i in 0..LANES {
            let br = (a[i] > hi[i]) | (b[i] > hi[i]);
            let dk = (a[i] < lo[i]) | (b[i] < lo[i]);
            bright[i] &= 0u8.wrapping_sub(br as u8);
            dark[i] &= 0u8.wrapping_sub(dk as u8);
        }
    };
    let any = |bright: &[u8; LANES], dark: &[u8; LANES]| {
        bright.iter().zip(dark).fold(0u8, |acc, (b, d)| acc | b | d) != 0
    };
    pair(0, &mut bright, &mut dark);
    pair(4, &mut bright, &mut dark);
    if !any(&bright, &dark) {
        return 0;
    }
    for k in [2, 6, 1, 3, 5, 7] {
        pair(k, &mut bright, &mut dark);
    }
    let mut mask = 0u32;
    for i in 0..LANES {
        mask |= (((bright[i] | dark[i]) != 0) as u32) << i;
    }
    mask
}

/// The exact FAST-9 test and score (as [`corner_score`]) of the pixels `x..x + LANES` of a
/// row, computed for the whole block in byte and 16-bit lanes: per circle pixel `k`, lanes
/// `bright_k = I_k > I + t` and `dark_k = I_k < I - t`; a 9-arc starting at `k` is the AND of
/// `k..k + 9` (mod 16), built from ANDs of runs of 2, 4 and 8. Returns the scores (valid in the
/// lanes that are corners) and the bit mask of the corners.
#[inline(always)]
fn full_test(centre: &[u8], ring: &[&[u8]; 16], x: usize, t: u8) -> ([u16; LANES], u32) {
    let block =
        |s: &[u8]| -> [u8; LANES] { s[x..x + LANES].try_into().expect("block of LANES pixels") };
    let v = block(centre);
    let hi: [u8; LANES] = std::array::from_fn(|i| v[i].saturating_add(t));
    let lo: [u8; LANES] = std::array::from_fn(|i| v[i].saturating_sub(t));
    let mut bright = [[0u8; LANES]; 16];
    let mut dark = [[0u8; LANES]; 16];
    // Sums of (I_k - I) over the brighter pixels and (I - I_k) over the darker ones, as
    // saturating differences to the thresholds plus `t` per pixel counted (the counts are
    // accumulated as byte flags 0xff = -1, subtracted).
    let mut sum_bright = [0u16; LANES];
    let mut sum_dark = [0u16; LANES];
    let mut count_bright = [0u8; LANES];
    let mut count_dark = [0u8; LANES];
    for k in 0..16 {
        let r = block(ring[k]);
        for i in 0..LANES {
            let (b, d) = (r[i] > hi[i], r[i] < lo[i]);
            bright[k][i] = 0u8.wrapping_sub(b as u8);
            dark[k][i] = 0u8.wrapping_sub(d as u8);
            count_bright[i] = count_bright[i].wrapping_sub(bright[k][i]);
            count_dark[i] = count_dark[i].wrapping_sub(dark[k][i]);
            sum_bright[i] += r[i].saturating_sub(hi[i]) as u16;
            sum_dark[i] += lo[i].saturating_sub(r[i]) as u16;
        }
    }
    for i in 0..LANES {
        sum_bright[i] += t as u16 * count_bright[i] as u16;
        sum_dark[i] += t as u16 * count_dark[i] as u16;
    }
    let (arc_bright, arc_dark) = (arc9(&bright), arc9(&dark));
    let mut out = [0u16; LANES];
    let mut mask = 0u32;
    for i in 0..LANES {
        let sb = if arc_bright[i] != 0 { sum_bright[i] } else { 0 };
        let sd = if arc_dark[i] != 0 { sum_dark[i] } else { 0 };
        out[i] = sb.max(sd);
        mask |= (((arc_bright[i] | arc_dark[i]) != 0) as u32) << i;
    }
    (out, mask)
}

/// Lanes where the 16 circle flags `m[k]` (0 or 0xff) hold a run of 9 (with wrap-around):
/// runs of 2, 4 and 8 by AND-ing shifted copies, then the 9th pixel.
#[inline(always)]
fn arc9(m: &[[u8; LANES]; 16]) -> [u8; LANES] {
    let run8 = and_shifted::<4>(&and_shifted::<2>(&and_shifted::<1>(m)));
    let mut any = [0u8; LANES];
    for k in 0..16 {
        for i in 0..LANES {
            any[i] |= run8[k][i] & m[(k + 8) & 15][i];
        }
    }
    any
}

/// `out[k] = m[k] & m[(k + STEP) mod 16]`, lane by lane.
#[inline(always)]
fn and_shifted<const STEP: usize>(m: &[[u8; LANES]; 16]) -> [[u8; LANES]; 16] {
    let mut out = [[0u8; LANES]; 16];
    for k in 0..16 {
        for i in 0..LANES {
            out[k][i] = m[k][i] & m[(k + STEP) & 15][i];
        }
    }
    out
}

/// [`quick_test`] for a row shorter than `LANES` pixels, one pixel at a time.
fn quick_test_tail(centre: &[u8], ring: &[&[u8]; 16], x: usize, len: usize, t: u8) -> u32 {
    let mut mask = 0u32;
    for i in 0..len {
        let v = centre[x + i];
        let (hi, lo) = (v.saturating_add(t), v.saturating_sub(t));
        let (mut bright, mut dark) = (true, true);
        for k in 0..8 {
            let (a, b) = (ring[k][x + i], ring[k + 8][x + i]);
            bright &= a > hi || b > hi;
            dark &= a < lo || b < lo;
        }
        mask |= ((bright || dark) as u32) << i;
    }
    mask
}

/// Runs FAST at `threshold` (>= 1) over `region` (at least 3 px inside the image), writing
/// the score of every corner into `scores` (same layout as the image) and appending the
/// pixel indices of the corners, in raster order, to `corners`.
pub(crate) fn detect_into(
    img: &Image<u8>,
    region: Rect,
    threshold: u8,
    scores: &mut [u16],
    corners: &mut Vec<usize>,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { detect_into_avx2(img, region, threshold, scores, corners) };
            return;
        }
    }
    detect_into_generic(img, region, threshold, scores, corners);
}

/// [`detect_into`] compiled for AVX2 (32-pixel blocks in one register).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn detect_into_avx2(
    img: &Image<u8>,
    region: Rect,
    threshold: u8,
    scores: &mut [u16],
    corners: &mut Vec<usize>,
) {
    detect_into_generic(img, region, threshold, scores, corners);
}

/// The portable body of [`detect_into`]; inlined into each target-feature variant.
#[inline(always)]
fn detect_into_generic(
    img: &Image<u8>,
    region: Rect,
    threshold: u8,
    scores: &mut [u16],
    corners: &mut Vec<usize>,
) {
    let w = img.width();
    let data = img.data();
    let offsets = circle_offsets(w);
    let n = region.x1.saturating_sub(region.x0);
    if n == 0 {
        return;
    }
    let t = threshold.max(1);
    for y in region.y0..region.y1 {
        let base = y * w + region.x0;
        let row = |off: isize| {
            let s = (base as isize + off) as usize;
            &data[s..s + n]
        };
        let centre = row(0);
        let ring: [&[u8]; 16] = std::array::from_fn(|k| row(offsets[k]));
        let mut x = 0;
        while x < n {
            let len = LANES.min(n - x);
            if n < LANES {
                let mut m = quick_test_tail(centre, &ring, x, len, t);
                while m != 0 {
                    let j = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let c = base + x + j;
                    if let Some(score) = corner_score(data, c, &offsets, t) {
                        scores[c] = score;
                        corners.push(c);
                    }
                }
                x += len;
                continue;
            }
            // The last partial block tests the full block ending at the row end and keeps
            // the pixels not tested yet.
            let start = if len == LANES { x } else { n - LANES };
            let skip = LANES - len;
            let quick = quick_test(centre, &ring, start, t) >> skip;
            if quick != 0 {
                let (block_scores, corner_mask) = full_test(centre, &ring, start, t);
                let mut m = (corner_mask >> skip) & quick;
                while m != 0 {
                    let j = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let c = base + x + j;
                    // A score is at least 9 (t + 1) > 0, so 0 marks "no corner".
                    scores[c] = block_scores[j + skip];
                    corners.push(c);
                }
            }
            x += len;
        }
    }
}

/// Cell side in level pixels for the threshold fallback grid (ORB-SLAM uses 30; 32 fills
/// whole quick-test blocks).
pub(crate) const CELL: usize = 32;

/// FAST with per-cell threshold fallback and 3x3 non-maximum suppression over `region`.
pub(crate) fn detect(
    img: &Image<u8>,
    region: Rect,
    threshold: u8,
    min_threshold: u8,
) -> Vec<Corner> {
    if region.x1 <= region.x0 || region.y1 <= region.y0 {
        return Vec::new();
    }
    let w = img.width();
    let mut scores = vec![0u16; w * img.height()];
    let mut corners = Vec::new();
    detect_into(img, region, threshold, &mut scores, &mut corners);
    if min_threshold < threshold {
        let cols = (region.x1 - region.x0).div_ceil(CELL);
        let rows = (region.y1 - region.y0).div_ceil(CELL);
        let mut filled = vec![false; cols * rows];
        for &c in &corners {
            let (x, y) = (c % w - region.x0, c / w - region.y0);
            filled[(y / CELL) * cols + x / CELL] = true;
        }
        for (cell, _) in filled.iter().enumerate().filter(|(_, &f)| !f) {
            let (cx, cy) = (
                region.x0 + (cell % cols) * CELL,
                region.y0 + (cell / cols) * CELL,
            );
            let rect = Rect {
                x0: cx,
                y0: cy,
                x1: (cx + CELL).min(region.x1),
                y1: (cy + CELL).min(region.y1),
            };
            detect_into(img, rect, min_threshold, &mut scores, &mut corners);
        }
    }
    suppress(&scores, w, &corners)
}

/// 3x3 non-maximum suppression of the `corners` (pixel indices at least 1 px inside the
/// image): keeps a corner whose score beats the neighbours before it in raster order strictly
/// and the ones after it or equally (one survivor per plateau). Output in raster order.
fn suppress(scores: &[u16], w: usize, corners: &[usize]) -> Vec<Corner> {
    let mut out: Vec<Corner> = corners
        .iter()
        .filter(|&&c| {
            let s = scores[c];
            let (up, down) = (c - w, c + w);
            // `&`, not `&&`: eight comparisons without a branch each (most corners are not
            // maxima, and which comparison fails first is unpredictable).
            let earlier = (s > scores[up - 1])
                & (s > scores[up])
                & (s > scores[up + 1])
                & (s > scores[c - 1]);
            let later = (s >= scores[c + 1])
                & (s >= scores[down - 1])
                & (s >= scores[down])
                & (s >= scores[down + 1]);
            earlier & later
        })
        .map(|&c| Corner {
            x: (c % w) as u32,
            y: (c / w) as u32,
            score: scores[c],
        })
        .collect();
    // Only the threshold fallback's cells come out of raster order.
    if !out.windows(2).all(|p| (p[0].y, p[0].x) <= (p[1].y, p[1].x)) {
        out.sort_unstable_by_key(|c| (c.y, c.x));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark square on a bright background: its 4 convex corners are FAST corners.
    fn square(w: usize) -> Image<u8> {
        let data = (0..w * w)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (10..30).contains(&x) && (10..30).contains(&y) {
                    40
                } else {
                    200
                }
            })
            .collect();
        Image::new(w, w, data).unwrap()
    }

    #[test]
    fn finds_square_corners_and_nothing_on_flat_or_straight_edges() {
        let img = square(40);
        let region = Rect {
            x0: 3,
            y0: 3,
            x1: 37,
            y1: 37,
        };
        let corners = detect(&img, region, 20, 7);
        assert_eq!(corners.len(), 4, "{corners:?}");
        for c in &corners {
            // FAST fires within a few pixels of a sharp corner; NMS keeps one per corner.
            let near = |v: u32| v.abs_diff(10) <= 3 || v.abs_diff(29) <= 3;
            assert!(near(c.x) && near(c.y), "{c:?}");
            // Contrast is 160 grey levels over at least 9 circle pixels.
            assert!(c.score >= 9 * 160, "{c:?}");
        }
    }

    #[test]
    fn threshold_and_score_follow_contrast() {
        // A single bright pixel of contrast 50 on a flat background: a corner below
        // threshold 50 only, scored 16 * 50 (all circle pixels darker by 50).
        let mut img = Image::new(9, 9, vec![100; 81]).unwrap();
        img.data_mut()[40] = 150;
        let region = Rect {
            x0: 4,
            y0: 4,
            x1: 5,
            y1: 5,
        };
        let mut scores = vec![0u16; 81];
        let mut corners = Vec::new();
        detect_into(&img, region, 49, &mut scores, &mut corners);
        assert_eq!((corners.clone(), scores[40]), (vec![40], 800));
        corners.clear();
        detect_into(&img, region, 50, &mut [0u16; 81], &mut corners);
        assert!(corners.is_empty());
    }

    #[test]
    fn dispatched_and_portable_paths_agree() {
        // A pseudo-random image: plenty of corners at threshold 10, rows not a multiple of 32.
        let (w, h) = (97, 61);
        let mut s = 12345u32;
        let data = (0..w * h)
            .map(|_| {
                s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (s >> 24) as u8
            })
            .collect();
        let img = Image::new(w, h, data).unwrap();
        let region = Rect {
            x0: 3,
            y0: 3,
            x1: w - 3,
            y1: h - 3,
        };
        let run = |f: fn(&Image<u8>, Rect, u8, &mut [u16], &mut Vec<usize>)| {
            let (mut scores, mut corners) = (vec![0u16; w * h], Vec::new());
            f(&img, region, 10, &mut scores, &mut corners);
            (scores, corners)
        };
        let (a, b) = (run(detect_into), run(detect_into_generic));
        assert!(a.1.len() > 100);
        assert_eq!(a, b);
    }

    #[test]
    fn block_test_agrees_with_the_per_pixel_test() {
        // Pseudo-random pixels with small contrast: corners of both polarities, both arcs.
        let (w, h) = (LANES + 6, 9);
        let mut s = 777u32;
        let data: Vec<u8> = (0..w * h)
            .map(|_| {
                s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                100 + (s >> 27) as u8 * 4
            })
            .collect();
        let offsets = circle_offsets(w);
        let mut corners = 0;
        for y in 3..h - 3 {
            let ring: [&[u8]; 16] = std::array::from_fn(|k| {
                let start = (y * w + 3) as isize + offsets[k];
                &data[start as usize..]
            });
            let (scores, mask) = full_test(&data[y * w + 3..], &ring, 0, 10);
            for (i, &got) in scores.iter().enumerate() {
                let want = corner_score(&data, y * w + 3 + i, &offsets, 10);
                assert_eq!(mask >> i & 1 == 1, want.is_some(), "y {y} i {i}");
                if let Some(score) = want {
                    assert_eq!(got, score, "y {y} i {i}");
                    corners += 1;
                }
            }
        }
        assert!(corners > 10, "{corners}");
    }

    #[test]
    fn an_arc_of_8_is_not_a_corner_but_9_is() {
        for (arc, want) in [(8usize, false), (9, true)] {
            let mut img = Image::new(9, 9, vec![100; 81]).unwrap();
            for &(dx, dy) in CIRCLE.iter().cycle().skip(5).take(arc) {
                img.data_mut()[((4 + dy) * 9 + 4 + dx) as usize] = 200;
            }
            let offsets = circle_offsets(9);
            assert_eq!(
                corner_score(img.data(), 40, &offsets, 20).is_some(),
                want,
                "{arc}"
            );
        }
    }
}
