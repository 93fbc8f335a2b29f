//! Reference pixel selection for SE(3) alignment, DSO-style: the level is cut into square
//! cells sized so that there are about `pixel_budget` of them, and each cell keeps its pixel of
//! largest gradient among those with a valid depth and `|grad I_ref| >= gradient_threshold`.
//! Level `l` (intrinsics `f / 2^l`, `c / 2^l`) takes the depth of level-0 pixel `2^l p` and
//! back-projects `P = Z K^-1 (p, 1)` into the reference camera frame (metres).

use rayon::prelude::*;

use vofront_core::Pinhole;
use vofront_image::Image;

use super::Se3Config;

/// Selected reference pixels of one level, structure of arrays.
#[derive(Debug, Clone, Default)]
pub(super) struct RefLevel {
    /// Camera-frame points, metres.
    pub(super) x: Vec<f32>,
    pub(super) y: Vec<f32>,
    pub(super) z: Vec<f32>,
    /// Grey level of the reference pixel.
    pub(super) value: Vec<f32>,
    /// Intrinsics of the level `(fx, fy, cx, cy)`.
    pub(super) k: [f32; 4],
}

impl RefLevel {
    /// An empty level with intrinsics `k`.
    pub(super) fn with_intrinsics(k: [f32; 4]) -> Self {
        Self {
            k,
            ..Self::default()
        }
    }

    /// Adds the pixel `(u, v)` of this level with depth `z` and grey level `value`, back-projected
    /// to `P = z K^-1 (u, v, 1)`.
    pub(super) fn push(&mut self, u: f32, v: f32, z: f32, value: f32) {
        let [fx, fy, cx, cy] = self.k;
        self.x.push((u - cx) / fx * z);
        self.y.push((v - cy) / fy * z);
        self.z.push(z);
        self.value.push(value);
    }

    /// The level's pixels whose pixel `(u, v)` of this level satisfies `keep`.
    pub(super) fn filtered(&self, keep: impl Fn(f32, f32) -> bool) -> Self {
        let [fx, fy, cx, cy] = self.k;
        let mut out = Self::with_intrinsics(self.k);
        for i in 0..self.x.len() {
            let (x, y, z) = (self.x[i], self.y[i], self.z[i]);
            if keep(fx * x / z + cx, fy * y / z + cy) {
                out.x.push(x);
                out.y.push(y);
                out.z.push(z);
                out.value.push(self.value[i]);
            }
        }
        out
    }
}

/// Intrinsics `(fx, fy, cx, cy) / 2^level` of pyramid level `level` (level-`l` pixel `x` sits at
/// level-0 pixel `2^l x`).
pub(super) fn level_intrinsics(p: &Pinhole, level: usize) -> [f32; 4] {
    let s = 0.5f32.powi(level as i32);
    [
        p.fx as f32 * s,
        p.fy as f32 * s,
        p.cx as f32 * s,
        p.cy as f32 * s,
    ]
}

/// Pixels of one level: per grid cell, the largest gradient with a valid depth.
pub(super) fn select_level(
    img: &Image<f32>,
    depth0: &Image<f32>,
    step: usize,
    k: [f32; 4],
    cfg: &Se3Config,
) -> RefLevel {
    let (w, h) = img.size();
    let cell = ((w * h) as f64 / cfg.pixel_budget as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let t2 = cfg.gradient_threshold * cfg.gradient_threshold;
    let depth_at = |x: usize, y: usize| {
        let z = depth0.data()[(y * step) * depth0.width() + x * step];
        (z >= cfg.min_depth && z <= cfg.max_depth).then_some(z)
    };
    let bands: Vec<RefLevel> = (1..h.saturating_sub(1))
        .step_by(cell)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|cy| {
            let mut out = RefLevel::with_intrinsics(k);
            // Per cell of the band: (g2, x, y, z) of the best pixel so far.
            let cells = (w.saturating_sub(2)).div_ceil(cell);
            let mut best: Vec<Option<(f32, usize, usize, f32)>> = vec![None; cells];
            let mut g2 = vec![0f32; w];
            for y in cy..(cy + cell).min(h - 1) {
                let (up, row, down) = (img.row(y - 1), img.row(y), img.row(y + 1));
                // Central differences, as in `Image<f32>::gradients`; g2[x] for x in 1..w-1.
                for (((o, (r, l)), d), u) in g2[1..w - 1]
                    .iter_mut()
                    .zip(row[2..].iter().zip(&row[..w - 2]))
                    .zip(&down[1..w - 1])
                    .zip(&up[1..w - 1])
                {
                    let (gx, gy) = (0.5 * (r - l), 0.5 * (d - u));
                    *o = gx * gx + gy * gy;
                }
                for (ci, b) in best.iter_mut().enumerate() {
                    let x0 = 1 + ci * cell;
                    for (x, &g) in g2.iter().enumerate().take((x0 + cell).min(w - 1)).skip(x0) {
                        if g >= t2 && b.is_none_or(|b| g > b.0) {
                            if let Some(z) = depth_at(x, y) {
                                *b = Some((g, x, y, z));
                            }
                        }
                    }
                }
            }
            for (_, x, y, z) in best.into_iter().flatten() {
                let value = img.at(x, y);
                if value.is_finite() {
                    out.push(x as f32, y as f32, z, value);
                }
            }
            out
        })
        .collect();
    let mut out = RefLevel::with_intrinsics(k);
    for band in bands {
        out.x.extend(band.x);
        out.y.extend(band.y);
        out.z.extend(band.z);
        out.value.extend(band.value);
    }
    out
}
