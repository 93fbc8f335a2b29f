//! The correspondences of the two-view pipeline: normalized coordinates in SoA arrays (and an
//! interleaved `f32` copy for the vectorised scoring loop). A leaf module.

use nalgebra::{Vector2, Vector3};

use crate::residual::Epipolar;

/// Normalized coordinates of the correspondences, one array per coordinate; built with
/// [`Correspondences::push`].
///
/// Invariant: the five arrays have the same length (the fields are private so that
/// [`Correspondences::push`] is the only way in and the packed copy stays in step).
#[derive(Debug, Clone, Default)]
pub struct Correspondences {
    /// `x` of image 1.
    u1: Vec<f64>,
    /// `y` of image 1.
    v1: Vec<f64>,
    /// `x` of image 2.
    u2: Vec<f64>,
    /// `y` of image 2.
    v2: Vec<f64>,
    /// The four coordinates in `f32`, interleaved per correspondence `[u1, v1, u2, v2]`, for
    /// the vectorised scoring loop (kept in step with the other arrays by [`Self::push`]).
    packed: Vec<[f32; 4]>,
}

impl Correspondences {
    /// `x` of image 1, one per correspondence.
    #[inline]
    pub fn u1(&self) -> &[f64] {
        &self.u1
    }

    /// `y` of image 1, one per correspondence.
    #[inline]
    pub fn v1(&self) -> &[f64] {
        &self.v1
    }

    /// `x` of image 2, one per correspondence.
    #[inline]
    pub fn u2(&self) -> &[f64] {
        &self.u2
    }

    /// `y` of image 2, one per correspondence.
    #[inline]
    pub fn v2(&self) -> &[f64] {
        &self.v2
    }

    /// Number of correspondences.
    pub fn len(&self) -> usize {
        self.u1.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.u1.is_empty()
    }

    /// Adds one correspondence.
    pub fn push(&mut self, a: &Vector2<f64>, b: &Vector2<f64>) {
        self.u1.push(a.x);
        self.v1.push(a.y);
        self.u2.push(b.x);
        self.v2.push(b.y);
        self.packed
            .push([a.x as f32, a.y as f32, b.x as f32, b.y as f32]);
    }

    /// Homogeneous ray `(x, y, 1)` of correspondence `i` in image 1.
    #[inline]
    pub fn ray1(&self, i: usize) -> Vector3<f64> {
        Vector3::new(self.u1[i], self.v1[i], 1.0)
    }

    /// Homogeneous ray `(x, y, 1)` of correspondence `i` in image 2.
    #[inline]
    pub fn ray2(&self, i: usize) -> Vector3<f64> {
        Vector3::new(self.u2[i], self.v2[i], 1.0)
    }

    /// Point `i` of image 1.
    #[inline]
    pub fn p1(&self, i: usize) -> Vector2<f64> {
        Vector2::new(self.u1[i], self.v1[i])
    }

    /// Point `i` of image 2.
    #[inline]
    pub fn p2(&self, i: usize) -> Vector2<f64> {
        Vector2::new(self.u2[i], self.v2[i])
    }

    /// The epipolar terms of correspondence `i` under the row-major `E`
    /// ([`crate::residual::row_major`]).
    #[inline]
    pub fn epipolar(&self, e: &[f64; 9], i: usize) -> Epipolar<f64> {
        Epipolar::new(e, self.u1[i], self.v1[i], self.u2[i], self.v2[i])
    }

    /// The four coordinates of every correspondence in `f32`, `[u1, v1, u2, v2]`.
    #[inline]
    pub(super) fn packed(&self) -> &[[f32; 4]] {
        &self.packed
    }
}
