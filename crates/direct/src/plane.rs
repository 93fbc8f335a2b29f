//! What the direct methods take from `vofront_image` (their images are
//! [`vofront_image::Image<f32>`]: the factor-2 pyramid, gradients and bilinear taps), and the
//! value-and-gradient interpolation of the aligners that sample the current image's gradients
//! (SE(3), forward-additive translation).

pub(crate) use vofront_image::Bilinear;
pub use vofront_image::{Gradients, Pyramid};

/// The former name of [`vofront_image::Image<f32>`], kept for users' code.
#[deprecated(note = "use vofront_image::Image<f32>")]
pub type Plane = vofront_image::Image<f32>;

/// Grey level and central-difference gradient of `img` at `(u, v)`, bilinearly interpolated
/// from the four surrounding pixels (the same values as interpolating
/// [`vofront_image::Image::gradients`]),
/// without building gradient images. Needs `1 <= u, v` and `u <= w - 2`, `v <= h - 2`.
#[inline]
pub(crate) fn sample_with_gradient(img: &[f32], w: usize, h: usize, u: f32, v: f32) -> [f32; 3] {
    // Top-left tap in [1, w - 3] so that the 4x4 neighbourhood stays inside the image.
    let x0 = (u as usize).min(w - 3).max(1);
    let y0 = (v as usize).min(h - 3).max(1);
    interpolate_with_gradient(img, w, x0, y0, u - x0 as f32, v - y0 as f32)
}

/// [`sample_with_gradient`] from its bilinear taps: top-left pixel `(x0, y0)` in
/// `[1, w - 3] x [1, h - 3]` and fractions `(fx, fy)` (for callers that know the taps, such as
/// a translation's shared `floor` and fraction).
#[inline]
pub(crate) fn interpolate_with_gradient(
    img: &[f32],
    w: usize,
    x0: usize,
    y0: usize,
    fx: f32,
    fy: f32,
) -> [f32; 3] {
    let i = y0 * w + x0;
    // Rows y0 - 1 ..= y0 + 2: `r0`, `r1` cover columns x0 - 1 ..= x0 + 2, `up`, `down` x0 ..= x0 + 1
    // (fixed-size copies: one bounds check per row).
    let taps = |start: usize| -> [f32; 4] {
        img[start..start + 4]
            .try_into()
            .expect("a slice of four elements")
    };
    let pair = |start: usize| -> [f32; 2] {
        img[start..start + 2]
            .try_into()
            .expect("a slice of two elements")
    };
    let (up, r0, r1, down) = (pair(i - w), taps(i - 1), taps(i + w - 1), pair(i + 2 * w));
    let (a, b, c, d) = (r0[1], r0[2], r1[1], r1[2]);
    let (w0, w1, w2, w3) = (
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    );
    let value = w0 * a + w1 * b + w2 * c + w3 * d;
    let gx = 0.5
        * (w0 * (r0[2] - r0[0])
            + w1 * (r0[3] - r0[1])
            + w2 * (r1[2] - r1[0])
            + w3 * (r1[3] - r1[1]));
    let gy = 0.5
        * (w0 * (r1[1] - up[0])
            + w1 * (r1[2] - up[1])
            + w2 * (down[0] - r0[1])
            + w3 * (down[1] - r0[2]));
    [value, gx, gy]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Float tolerance: the same products summed in a different order.
    const TOLERANCE: f32 = 1e-3;

    #[test]
    fn on_the_fly_gradient_matches_interpolated_gradient_planes() {
        let (w, h) = (23, 17);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                100.0 + 40.0 * (0.7 * x).sin() * (0.45 * y).cos() + 3.0 * x - 2.0 * y
            })
            .collect();
        let img = vofront_image::Image::new(w, h, data).expect("valid image");
        let g = img.gradients();
        // Interior points, the lowest and highest allowed coordinates included.
        let (hi_u, hi_v) = ((w - 2) as f32, (h - 2) as f32);
        let mut points = vec![(1.0, 1.0), (hi_u, hi_v), (hi_u, 1.0), (1.0, hi_v)];
        points.extend((0..50).map(|k| {
            let t = k as f32 / 49.0;
            (1.0 + t * (hi_u - 1.0), 1.0 + (1.0 - t * t) * (hi_v - 1.0))
        }));
        for (u, v) in points {
            let [value, gx, gy] = sample_with_gradient(img.data(), w, h, u, v);
            let expected = [
                img.sample(u, v).expect("inside"),
                g.gx.sample(u, v).expect("inside"),
                g.gy.sample(u, v).expect("inside"),
            ];
            for (got, want) in [value, gx, gy].into_iter().zip(expected) {
                assert!(
                    (got - want).abs() < TOLERANCE,
                    "({u}, {v}): {got} vs {want}"
                );
            }
        }
    }
}
