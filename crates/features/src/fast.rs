//! FAST-9 corners: 16-pixel Bresenham circle of radius 3, a contiguous arc of at least 9
//! pixels all brighter than `I(p) + t` or all darker than `I(p) - t`.
//!
//! The corner score is the largest threshold at which the pixel is still a corner:
//! `score = max over 9-arcs A of max(min_{q in A} (I(q) - I(p)), min_{q in A} (I(p) - I(q))) - 1`,
//! so a pixel is a corner at threshold `t` iff `score >= t`. Detection runs in two passes per
//! grid cell (threshold fallback): `fast_threshold` everywhere, then `min_fast_threshold` in
//! the cells where the first pass found nothing; then a 3x3 non-maximum suppression on the score.

use crate::pyramid::Plane;

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
    pub score: u8,
}

/// Index offsets of the circle for a row stride.
fn circle_offsets(stride: usize) -> [isize; 16] {
    CIRCLE.map(|(dx, dy)| dy * stride as isize + dx)
}

/// Score of the pixel at index `c` (see the module docs); negative when no 9-arc differs at all.
#[inline]
fn corner_score(data: &[u8], c: usize, offsets: &[isize; 16]) -> i16 {
    let v = data[c] as i16;
    let mut d = [0i16; 32];
    for (k, off) in offsets.iter().enumerate() {
        let q = data[(c as isize + off) as usize] as i16 - v;
        d[k] = q;
        d[k + 16] = q;
    }
    // Sliding min / max over windows of 9 by doubling: 2, 4, 8, then 8 + 1.
    let mut mn = [0i16; 24];
    let mut mx = [0i16; 24];
    for k in 0..24 {
        mn[k] = d[k].min(d[k + 1]);
        mx[k] = d[k].max(d[k + 1]);
    }
    for k in 0..20 {
        mn[k] = mn[k].min(mn[k + 2]);
        mx[k] = mx[k].max(mx[k + 2]);
    }
    let (mut bright, mut dark) = (i16::MIN, i16::MIN);
    for k in 0..16 {
        let lo = mn[k].min(mn[k + 4]).min(d[k + 8]);
        let hi = mx[k].max(mx[k + 4]).max(d[k + 8]);
        bright = bright.max(lo);
        dark = dark.max(-hi);
    }
    bright.max(dark) - 1
}

/// Pixels per block of the quick test.
const LANES: usize = 16;

/// Quick rejection for pixels `x..x + 16` of a row: a 9-arc contains at least one pixel of
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
        u128::from_ne_bytes(*bright) | u128::from_ne_bytes(*dark) != 0
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

/// [`quick_test`] for a last block of `len < 16` pixels, one pixel at a time.
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
/// the score of every corner into `scores` (same layout as the image) and counting corners.
pub(crate) fn detect_into(img: &Plane, region: Rect, threshold: u8, scores: &mut [u8]) -> usize {
    let w = img.width;
    let data = &img.data;
    let offsets = circle_offsets(w);
    let n = region.x1.saturating_sub(region.x0);
    if n == 0 {
        return 0;
    }
    let t = threshold.max(1);
    let mut found = 0;
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
            let mask = if len == LANES {
                quick_test(centre, &ring, x, t)
            } else {
                quick_test_tail(centre, &ring, x, len, t)
            };
            let mut m = mask;
            while m != 0 {
                let j = m.trailing_zeros() as usize;
                m &= m - 1;
                let c = base + x + j;
                let score = corner_score(data, c, &offsets);
                if score >= t as i16 {
                    scores[c] = score.min(255) as u8;
                    found += 1;
                }
            }
            x += len;
        }
    }
    found
}

/// Cell side in level pixels for the threshold fallback grid (as ORB-SLAM).
pub(crate) const CELL: usize = 30;

/// FAST with per-cell threshold fallback and 3x3 non-maximum suppression over `region`.
pub(crate) fn detect(img: &Plane, region: Rect, threshold: u8, min_threshold: u8) -> Vec<Corner> {
    let mut scores = vec![0u8; img.width * img.height];
    if region.x1 <= region.x0 || region.y1 <= region.y0 {
        return Vec::new();
    }
    detect_into(img, region, threshold, &mut scores);
    if min_threshold < threshold {
        for cy in (region.y0..region.y1).step_by(CELL) {
            for cx in (region.x0..region.x1).step_by(CELL) {
                let cell = Rect {
                    x0: cx,
                    y0: cy,
                    x1: (cx + CELL).min(region.x1),
                    y1: (cy + CELL).min(region.y1),
                };
                let empty = (cell.y0..cell.y1).all(|y| {
                    scores[y * img.width + cell.x0..y * img.width + cell.x1]
                        .iter()
                        .all(|&s| s == 0)
                });
                if empty {
                    detect_into(img, cell, min_threshold, &mut scores);
                }
            }
        }
    }
    suppress(&scores, img.width, region)
}

/// 3x3 non-maximum suppression: keeps a corner whose score beats the neighbours before it
/// in raster order strictly and the ones after it or equally (one survivor per plateau).
fn suppress(scores: &[u8], w: usize, region: Rect) -> Vec<Corner> {
    let mut out = Vec::new();
    for y in region.y0..region.y1 {
        let (up, row, down) = (
            &scores[(y - 1) * w..y * w],
            &scores[y * w..(y + 1) * w],
            &scores[(y + 1) * w..(y + 2) * w],
        );
        for x in region.x0..region.x1 {
            let s = row[x];
            if s == 0 {
                continue;
            }
            let earlier = s > up[x - 1] && s > up[x] && s > up[x + 1] && s > row[x - 1];
            let later = s >= row[x + 1] && s >= down[x - 1] && s >= down[x] && s >= down[x + 1];
            if earlier && later {
                out.push(Corner {
                    x: x as u32,
                    y: y as u32,
                    score: s,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark square on a bright background: its 4 convex corners are FAST corners.
    fn square(w: usize) -> Plane {
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
        Plane {
            width: w,
            height: w,
            data,
        }
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
            // Contrast is 160 grey levels, the score is the largest passing threshold.
            assert!(c.score >= 100, "{c:?}");
        }
    }

    #[test]
    fn score_is_the_largest_threshold_that_still_detects() {
        let img = square(40);
        let region = Rect {
            x0: 3,
            y0: 3,
            x1: 37,
            y1: 37,
        };
        let mut scores = vec![0u8; 1600];
        detect_into(&img, region, 1, &mut scores);
        let (i, &s) = scores.iter().enumerate().max_by_key(|(_, &s)| s).unwrap();
        let mut again = vec![0u8; 1600];
        detect_into(&img, region, s, &mut again);
        assert_eq!(again[i], s);
        let mut none = vec![0u8; 1600];
        detect_into(&img, region, s + 1, &mut none);
        assert_eq!(none[i], 0);
    }
}
