//! Reference pixels of a 2D alignment level: those whose central-difference gradient
//! `(gx, gy) = ((I(x+1) - I(x-1)) / 2, (I(y+1) - I(y-1)) / 2)` is at least a threshold, with
//! their grey levels and gradients, in structure-of-arrays form.

use nalgebra::{Matrix3, Vector3};

use vofront_image::Image;

/// Reference pixels of one level, structure of arrays.
#[derive(Debug, Default)]
pub(super) struct RefPixels {
    pub(super) x: Vec<f32>,
    pub(super) y: Vec<f32>,
    pub(super) value: Vec<f32>,
    pub(super) gx: Vec<f32>,
    pub(super) gy: Vec<f32>,
}

impl RefPixels {
    /// Interior pixels `(x, y)` of `img` with `gx^2 + gy^2 >= threshold^2` and `keep(x, y)`;
    /// when more than `max_pixels` qualify by their gradient, only those with the largest
    /// gradients (about `max_pixels`: the threshold is raised to the matching quantile of every
    /// 8th pixel's squared gradient), before `keep` is asked.
    pub(super) fn select(
        img: &Image<f32>,
        threshold: f32,
        max_pixels: usize,
        keep: impl Fn(f32, f32) -> bool,
    ) -> Self {
        let (w, h) = img.size();
        let mut out = RefPixels::default();
        if w < 3 || h < 3 {
            return out;
        }
        // Squared central-difference gradients, row-major; -inf on the border (never selected,
        // whatever the threshold).
        let mut g2 = vec![f32::NEG_INFINITY; w * h];
        for y in 1..h - 1 {
            let (up, row, down) = (img.row(y - 1), img.row(y), img.row(y + 1));
            for (((o, (r, l)), d), u) in g2[y * w + 1..(y + 1) * w - 1]
                .iter_mut()
                .zip(row[2..].iter().zip(&row[..w - 2]))
                .zip(&down[1..w - 1])
                .zip(&up[1..w - 1])
            {
                let (gx, gy) = (0.5 * (r - l), 0.5 * (d - u));
                *o = gx * gx + gy * gy;
            }
        }
        let mut t2 = threshold * threshold;
        let count = g2.iter().filter(|&&g| g >= t2).count();
        if count > max_pixels && max_pixels > 0 {
            let mut sample: Vec<f32> = g2.iter().step_by(8).copied().filter(|&g| g >= t2).collect();
            if !sample.is_empty() {
                let k = sample.len() - (max_pixels / 8).clamp(1, sample.len());
                let (_, cut, _) = sample.select_nth_unstable_by(k, f32::total_cmp);
                t2 = t2.max(*cut);
            }
        }
        let d = img.data();
        for (i, _) in g2.iter().enumerate().filter(|(_, &g)| g >= t2) {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if !keep(x, y) {
                continue;
            }
            out.x.push(x);
            out.y.push(y);
            out.value.push(d[i]);
            out.gx.push(0.5 * (d[i + 1] - d[i - 1]));
            out.gy.push(0.5 * (d[i + w] - d[i - w]));
        }
        out
    }

    pub(super) fn len(&self) -> usize {
        self.x.len()
    }
}

/// Whether `h` maps pixel `(x, y)` at least `margin` pixels inside the bilinear footprint of a
/// `width x height` target (`0 <= u < width - 1`, the same for `v`): the `keep` of
/// [`RefPixels::select`] that fixes a level's pixels, so that the set of residuals stays the
/// same while the level's steps move the warp by less than `margin`.
pub(super) fn maps_inside(
    h: &Matrix3<f64>,
    width: usize,
    height: usize,
    margin: f64,
) -> impl Fn(f32, f32) -> bool + '_ {
    let (u_end, v_end) = (width as f64 - 1.0 - margin, height as f64 - 1.0 - margin);
    move |x, y| {
        let p = h * Vector3::new(f64::from(x), f64::from(y), 1.0);
        let (u, v) = (p.x / p.z, p.y / p.z);
        u >= margin && v >= margin && u < u_end && v < v_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels of a selection as `(x, y, value, gx, gy)`.
    fn rows(px: &RefPixels) -> Vec<(f32, f32, f32, f32, f32)> {
        (0..px.len())
            .map(|i| (px.x[i], px.y[i], px.value[i], px.gx[i], px.gy[i]))
            .collect()
    }

    /// A shift by 3.5 px to the right keeps the pixels with `x + 3.5` at least 2 px inside
    /// the 20 px wide footprint (`x + 3.5 < 17`, i.e. `x <= 13`), every row alike, with their
    /// values and gradients.
    #[test]
    fn maps_inside_keeps_the_pixels_mapped_inside_the_margin() {
        let data = (0..20 * 10).map(|i| ((i * 37) % 101) as f32).collect();
        let img = Image::new(20, 10, data).unwrap();
        let all = rows(&RefPixels::select(&img, 0.0, 0, |_, _| true));
        let shift = Matrix3::new(1.0, 0.0, 3.5, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let kept = rows(&RefPixels::select(
            &img,
            0.0,
            0,
            maps_inside(&shift, 20, 10, 2.0),
        ));
        let expected: Vec<_> = all
            .iter()
            .copied()
            .filter(|&(x, y, ..)| x <= 13.0 && (2.0..=6.0).contains(&y))
            .collect();
        assert_eq!(kept, expected);
        assert!(kept.len() < all.len());
    }
}
