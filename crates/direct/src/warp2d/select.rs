//! Reference pixels of a 2D alignment level: those whose central-difference gradient
//! `(gx, gy) = ((I(x+1) - I(x-1)) / 2, (I(y+1) - I(y-1)) / 2)` is at least a threshold, with
//! their grey levels and gradients, in structure-of-arrays form.

use nalgebra::{Matrix3, Vector3};

use crate::plane::Plane;

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
    /// Interior pixels of `img` with `gx^2 + gy^2 >= threshold^2`; when more than
    /// `max_pixels` qualify, only those with the largest gradients (about `max_pixels`: the
    /// threshold is raised to the matching quantile of every 8th pixel's squared gradient).
    pub(super) fn select(img: &Plane, threshold: f32, max_pixels: usize) -> Self {
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
        for (i, _) in g2.iter().enumerate().filter(|(_, &g)| g >= t2) {
            let (x, y) = (i % w, i / w);
            let d = img.data();
            out.x.push(x as f32);
            out.y.push(y as f32);
            out.value.push(d[i]);
            out.gx.push(0.5 * (d[i + 1] - d[i - 1]));
            out.gy.push(0.5 * (d[i + w] - d[i - w]));
        }
        out
    }

    /// Keeps the pixels that `h` maps at least `margin` pixels inside the bilinear footprint
    /// of a `width x height` target (`0 <= u < width - 1`, the same for `v`), so that the set
    /// of residuals stays the same while a level's steps move the warp by less than `margin`.
    pub(super) fn retain_inside(
        &mut self,
        h: &Matrix3<f64>,
        width: usize,
        height: usize,
        margin: f64,
    ) {
        let inside = |x: f32, y: f32| {
            let p = h * Vector3::new(f64::from(x), f64::from(y), 1.0);
            let (u, v) = (p.x / p.z, p.y / p.z);
            u >= margin
                && v >= margin
                && u < width as f64 - 1.0 - margin
                && v < height as f64 - 1.0 - margin
        };
        let keep: Vec<bool> = self
            .x
            .iter()
            .zip(&self.y)
            .map(|(&x, &y)| inside(x, y))
            .collect();
        for column in [
            &mut self.x,
            &mut self.y,
            &mut self.value,
            &mut self.gx,
            &mut self.gy,
        ] {
            let mut k = keep.iter();
            column.retain(|_| *k.next().expect("one flag per pixel"));
        }
    }

    pub(super) fn len(&self) -> usize {
        self.x.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shift by 3.5 px to the right keeps the pixels with `x + 3.5` at least 2 px inside
    /// the 20 px wide footprint (`x + 3.5 < 17`, i.e. `x <= 13`), every row alike, with their
    /// values and gradients.
    #[test]
    fn retain_inside_keeps_the_pixels_mapped_inside_the_margin() {
        let data = (0..20 * 10).map(|i| ((i * 37) % 101) as f32).collect();
        let img = Plane::new(20, 10, data).unwrap();
        let mut px = RefPixels::select(&img, 0.0, 0);
        let all = px.len();
        let before: Vec<(f32, f32, f32)> =
            (0..all).map(|i| (px.x[i], px.y[i], px.value[i])).collect();
        let shift = Matrix3::new(1.0, 0.0, 3.5, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        px.retain_inside(&shift, 20, 10, 2.0);
        let expected: Vec<(f32, f32, f32)> = before
            .into_iter()
            .filter(|&(x, y, _)| x <= 13.0 && (2.0..=6.0).contains(&y))
            .collect();
        let kept: Vec<(f32, f32, f32)> = (0..px.len())
            .map(|i| (px.x[i], px.y[i], px.value[i]))
            .collect();
        assert_eq!(kept, expected);
        assert!(px.gx.len() == px.len() && px.gy.len() == px.len() && px.len() < all);
    }
}
