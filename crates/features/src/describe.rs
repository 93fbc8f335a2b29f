//! Orientation by intensity centroid and steered BRIEF (rBRIEF) descriptors.
//!
//! Orientation: with moments `m_pq = sum x^p y^q I(x, y)` over the disc of radius
//! [`HALF_PATCH`] around the keypoint (offsets `x` right, `y` down, unsmoothed level image),
//! `theta = atan2(m_01, m_10)` radians.
//!
//! Descriptor: each pattern pair `(p1, p2)` of [`BIT_PATTERN_31`] is rotated by `theta`,
//! `p' = round(R(theta) p)`, and bit `i` is `I_s(k + p1') < I_s(k + p2')` on the level image
//! smoothed by a 7x7 Gaussian (sigma 2), as in OpenCV's ORB.

use crate::descriptor::Descriptor;
use crate::pattern::BIT_PATTERN_31;
use vofront_image::Image;

/// Radius in level pixels of the orientation disc (patch size 31).
pub(crate) const HALF_PATCH: usize = 15;

/// Smallest distance of a keypoint to the level border for orientation and a rotated pattern:
/// the pattern reaches `13 sqrt 2 < 18.4` px, rounded to at most 18; the disc reaches 15.
pub(crate) const MIN_BORDER: usize = 19;

/// Half-width of each row of the orientation disc: `umax[v]` for `v = 0..=HALF_PATCH`, made
/// symmetric in `u` and `v` so the disc is invariant to 90-degree rotations.
fn disc_rows() -> [usize; HALF_PATCH + 1] {
    let r = HALF_PATCH as f64;
    let mut umax = [0usize; HALF_PATCH + 1];
    let vmax = (r * std::f64::consts::FRAC_1_SQRT_2 + 1.0).floor() as usize;
    let vmin = (r * std::f64::consts::FRAC_1_SQRT_2).ceil() as usize;
    for (v, u) in umax.iter_mut().enumerate().take(vmax + 1) {
        *u = (r * r - (v * v) as f64).sqrt().round() as usize;
    }
    let mut v0 = 0;
    for v in (vmin..=HALF_PATCH).rev() {
        while umax[v0] == umax[v0 + 1] {
            v0 += 1;
        }
        umax[v] = v0;
        v0 += 1;
    }
    umax
}

/// Orientations (radians) and steered BRIEF descriptors of the keypoints `points` (level
/// pixels, at least [`MIN_BORDER`] px inside): orientation on `img`, BRIEF on `smoothed`.
pub(crate) fn describe(
    img: &Image<u8>,
    smoothed: &Image<u8>,
    points: &[(usize, usize)],
    umax: &[usize; HALF_PATCH + 1],
) -> (Vec<f32>, Vec<Descriptor>) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { describe_avx2(img, smoothed, points, umax) };
        }
    }
    describe_generic(img, smoothed, points, umax)
}

/// [`describe`] compiled for AVX2 (8-lane pattern rotation with 32-bit products).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn describe_avx2(
    img: &Image<u8>,
    smoothed: &Image<u8>,
    points: &[(usize, usize)],
    umax: &[usize; HALF_PATCH + 1],
) -> (Vec<f32>, Vec<Descriptor>) {
    describe_generic(img, smoothed, points, umax)
}

/// The portable body of [`describe`]; inlined into each target-feature variant (plain loops,
/// as iterator folds would not be inlined).
#[inline(always)]
fn describe_generic(
    img: &Image<u8>,
    smoothed: &Image<u8>,
    points: &[(usize, usize)],
    umax: &[usize; HALF_PATCH + 1],
) -> (Vec<f32>, Vec<Descriptor>) {
    let disc = Disc::new(umax);
    let mut angles = Vec::with_capacity(points.len());
    let mut descriptors = Vec::with_capacity(points.len());
    for &(x, y) in points {
        let angle = orientation(img, x, y, &disc);
        angles.push(angle);
        descriptors.push(brief(smoothed, x, y, angle));
    }
    (angles, descriptors)
}

/// Columns of a disc row read at once: `x - DISC_ROW / 2 .. x + DISC_ROW / 2`.
const DISC_ROW: usize = 32;

/// The orientation disc as per-column weights on fixed rows of [`DISC_ROW`] pixels: for row
/// offset `v` (0..=[`HALF_PATCH`], applied above and below) and column `u - 16`, `du` is
/// the column offset and `dv` is `v`, both zero outside the disc.
pub(crate) struct Disc {
    du: [[i32; DISC_ROW]; HALF_PATCH + 1],
    dv: [[i32; DISC_ROW]; HALF_PATCH + 1],
}

impl Disc {
    /// The weights of the disc whose row `v` spans `-umax[v]..=umax[v]`.
    pub(crate) fn new(umax: &[usize; HALF_PATCH + 1]) -> Self {
        let mut disc = Self {
            du: [[0; DISC_ROW]; HALF_PATCH + 1],
            dv: [[0; DISC_ROW]; HALF_PATCH + 1],
        };
        for (v, &half) in umax.iter().enumerate() {
            for u in 0..DISC_ROW {
                let du = u as i32 - (DISC_ROW / 2) as i32;
                if du.unsigned_abs() as usize <= half {
                    disc.du[v][u] = du;
                    disc.dv[v][u] = v as i32;
                }
            }
        }
        disc
    }
}

/// Orientation `atan2(m_01, m_10)` in radians of the keypoint at `(x, y)`, which must be at
/// least `HALF_PATCH + 1` px inside the image (rows are read 16 px left and 15 px right).
#[inline(always)]
pub(crate) fn orientation(img: &Image<u8>, x: usize, y: usize, disc: &Disc) -> f32 {
    let w = img.width();
    let row = |start: usize| -> [i32; DISC_ROW] {
        let s: &[u8; DISC_ROW] = img.data()[start..start + DISC_ROW]
            .try_into()
            .expect("DISC_ROW pixels");
        s.map(i32::from)
    };
    let left = y * w + x - DISC_ROW / 2;
    // |moment| <= 15 * 255 * 709 pixels < 2^22: i32 sums are exact. Row 0 counts once.
    let mut m10 = [0i32; DISC_ROW];
    let mut m01 = [0i32; DISC_ROW];
    let centre = row(left);
    for i in 0..DISC_ROW {
        m10[i] += disc.du[0][i] * centre[i];
    }
    for v in 1..=HALF_PATCH {
        let (below, above) = (row(left + v * w), row(left - v * w));
        for i in 0..DISC_ROW {
            m10[i] += disc.du[v][i] * (below[i] + above[i]);
            m01[i] += disc.dv[v][i] * (below[i] - above[i]);
        }
    }
    let (m10, m01): (i32, i32) = (m10.iter().sum(), m01.iter().sum());
    (m01 as f32).atan2(m10 as f32)
}

/// The steered BRIEF descriptor of the keypoint at `(x, y)` with orientation `angle` radians,
/// on the smoothed level image; the keypoint must be at least [`MIN_BORDER`] px inside.
#[inline(always)]
pub(crate) fn brief(smoothed: &Image<u8>, x: usize, y: usize, angle: f32) -> Descriptor {
    let w = smoothed.width() as i32;
    let d = smoothed.data();
    let centre = y * smoothed.width() + x;
    let (s, c) = angle.sin_cos();
    let pattern = pattern_points();
    // Rounded rotated offsets of all 512 points as index offsets, in one vectorizable pass.
    let mut offsets = [0i32; 512];
    for ((o, &px), &py) in offsets.iter_mut().zip(&pattern.0).zip(&pattern.1) {
        *o = round(px * s + py * c) * w + round(px * c - py * s);
    }
    let at = |off: i32| d[(centre as isize + off as isize) as usize];
    let mut lanes = [0u64; 4];
    for (lane, pairs) in lanes.iter_mut().zip(offsets.chunks_exact(128)) {
        let mut bits = 0u64;
        for (b, o) in pairs.chunks_exact(2).enumerate() {
            bits |= ((at(o[0]) < at(o[1])) as u64) << b;
        }
        *lane = bits;
    }
    Descriptor(lanes)
}

/// The 512 points of [`BIT_PATTERN_31`] (pair `i` is points `2i`, `2i + 1`) as x and y arrays.
fn pattern_points() -> &'static ([f32; 512], [f32; 512]) {
    static POINTS: std::sync::OnceLock<([f32; 512], [f32; 512])> = std::sync::OnceLock::new();
    POINTS.get_or_init(|| {
        let mut xs = [0f32; 512];
        let mut ys = [0f32; 512];
        for (i, p) in BIT_PATTERN_31.iter().enumerate() {
            xs[2 * i] = p[0] as f32;
            ys[2 * i] = p[1] as f32;
            xs[2 * i + 1] = p[2] as f32;
            ys[2 * i + 1] = p[3] as f32;
        }
        (xs, ys)
    })
}

/// Nearest integer of `v` (`|v| < 2^22`), halves to even like OpenCV's `cvRound`: adding
/// `1.5 * 2^23` leaves the rounded integer in the low mantissa bits. Unlike `f32::round` or a
/// saturating `as` cast this is a plain add and subtract, so the pattern loop vectorizes.
#[inline(always)]
fn round(v: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0;
    (v + MAGIC).to_bits() as i32 - MAGIC.to_bits() as i32
}

/// Orientation disc rows, computed once.
pub(crate) fn umax() -> [usize; HALF_PATCH + 1] {
    disc_rows()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magic_rounding_is_round_half_even() {
        for (v, want) in [
            (0.4f32, 0),
            (0.5, 0),
            (1.5, 2),
            (-1.5, -2),
            (-0.6, -1),
            (18.38, 18),
            (-18.5, -18),
        ] {
            assert_eq!(round(v), want, "{v}");
        }
    }

    #[test]
    fn dispatched_and_portable_describe_agree() {
        let w = 64;
        let img = crate::pyramid::noise_plane(w, 4242);
        let points: Vec<(usize, usize)> = (19..45).map(|i| (i, 63 - i)).collect();
        let u = umax();
        let got = describe(&img, &img, &points, &u);
        assert_eq!(got, describe_generic(&img, &img, &points, &u));
        assert_eq!(got.1.len(), points.len());
        // Different patches give different descriptors.
        assert!(got.1.windows(2).all(|d| d[0] != d[1]));
    }

    #[test]
    fn disc_weights_give_the_moments_of_the_disc() {
        let w = 40;
        let img = crate::pyramid::noise_plane(w, 31);
        let u = umax();
        for (x, y) in [(17, 17), (20, 22), (23, 18)] {
            let (mut m10, mut m01) = (0i64, 0i64);
            for dv in -15i64..=15 {
                let half = u[dv.unsigned_abs() as usize] as i64;
                for du in -half..=half {
                    let p = img.data()[(y as i64 + dv) as usize * w + (x as i64 + du) as usize];
                    m10 += du * p as i64;
                    m01 += dv * p as i64;
                }
            }
            let want = (m01 as f32).atan2(m10 as f32);
            assert_eq!(orientation(&img, x, y, &Disc::new(&u)), want, "({x}, {y})");
        }
    }

    #[test]
    fn disc_is_symmetric_and_round() {
        let u = umax();
        assert_eq!(u[0], 15);
        assert!(u.windows(2).all(|w| w[0] >= w[1]));
        // Symmetry: the number of rows with half-width >= k equals umax[k] + 1.
        for k in 0..=HALF_PATCH {
            let rows = u.iter().filter(|&&h| h >= k).count();
            assert_eq!(rows, u[k] + 1, "k {k}");
        }
    }

    #[test]
    fn orientation_points_to_the_bright_side() {
        let w = 41;
        for (dx, dy, want) in [
            (1i32, 0i32, 0.0f32),
            (0, 1, 90.0),
            (-1, 0, 180.0),
            (0, -1, -90.0),
        ] {
            let data = (0..w * w)
                .map(|i| {
                    let (x, y) = ((i % w) as i32 - 20, (i / w) as i32 - 20);
                    (100 + 5 * (dx * x + dy * y)) as u8
                })
                .collect();
            let img = Image::new(w, w, data).unwrap();
            let a = orientation(&img, 20, 20, &Disc::new(&umax())).to_degrees();
            let diff = (a - want + 540.0).rem_euclid(360.0) - 180.0;
            assert!(diff.abs() < 0.5, "{a} vs {want}");
        }
    }
}
