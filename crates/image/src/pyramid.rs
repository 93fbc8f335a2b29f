//! Factor-2 image pyramids: level `l + 1` is [`Image::pyr_down`] of level `l`, so that pixel
//! `x_l` of level `l` sits at `x_0 = 2^l x_l` of level 0 and intrinsics scale as `f / 2^l`.

use crate::buffer::Image;

impl Image<f32> {
    /// Levels `1..levels` of the pyramid of `self` (as [`Pyramid::new`] builds them, without
    /// copying `self`): each level is [`Image::pyr_down`] of the previous one, stopping before a
    /// side would drop below `min_side`.
    pub fn coarser_levels(&self, levels: usize, min_side: usize) -> Vec<Image<f32>> {
        let mut out: Vec<Image<f32>> = Vec::with_capacity(levels.saturating_sub(1));
        while out.len() + 1 < levels.max(1) {
            let last = out.last().unwrap_or(self);
            if last.width().div_ceil(2) < min_side || last.height().div_ceil(2) < min_side {
                break;
            }
            out.push(last.pyr_down());
        }
        out
    }
}

/// A Gaussian-like image pyramid: `levels[0]` is the input, each next level half the size.
#[derive(Debug, Clone, PartialEq)]
pub struct Pyramid {
    /// Finest first.
    pub levels: Vec<Image<f32>>,
}

impl Pyramid {
    /// Up to `levels` levels (at least 1), stopping before a side would drop below `min_side`.
    pub fn new(base: Image<f32>, levels: usize, min_side: usize) -> Self {
        let coarse = base.coarser_levels(levels, min_side);
        Self {
            levels: std::iter::once(base).chain(coarse).collect(),
        }
    }
}
