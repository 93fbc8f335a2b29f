//! Reference pixels of a 2D alignment level: those whose central-difference gradient
//! `(gx, gy) = ((I(x+1) - I(x-1)) / 2, (I(y+1) - I(y-1)) / 2)` is at least a threshold, with
//! their grey levels and gradients, in structure-of-arrays form.

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

    pub(super) fn len(&self) -> usize {
        self.x.len()
    }
}
