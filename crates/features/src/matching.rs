//! Brute-force Hamming matching: k-nearest (k = 2) with Lowe's ratio test, optional mutual
//! (cross-check) filter and a maximum distance, parallel over queries with rayon.
//!
//! The inner loop is `popcount(q XOR t)` over four 64-bit lanes. The default x86-64 target has
//! no `popcnt` instruction, so on x86-64 the same loop is also compiled with
//! `#[target_feature(enable = "popcnt")]` and chosen at run time when the CPU has it.

use rayon::prelude::*;

use crate::Descriptor;

/// Matching filters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchConfig {
    /// Lowe ratio: keep the best match only if `d1 < ratio * d2` (`d2` = second-best distance).
    /// `None` disables the test; with a single candidate there is no `d2` and the test passes.
    pub ratio: Option<f32>,
    /// Keep a match only if the query is also the train's nearest neighbour.
    pub cross_check: bool,
    /// Largest accepted Hamming distance in bits (256 disables the limit).
    pub max_distance: u32,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            ratio: Some(0.75),
            cross_check: false,
            max_distance: 100,
        }
    }
}

/// A match of query feature `query` to train feature `train` at Hamming distance `distance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Match {
    /// Index into the query set.
    pub query: u32,
    /// Index into the train set.
    pub train: u32,
    /// Hamming distance in bits.
    pub distance: u32,
}

/// The two nearest train descriptors of one query.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Knn2 {
    /// Index of the nearest train descriptor (`u32::MAX` if the train set is empty).
    pub best: u32,
    /// Its distance (`u32::MAX` if none).
    pub best_distance: u32,
    /// Distance of the second nearest (`u32::MAX` if the train set has fewer than two).
    pub second_distance: u32,
}

impl Knn2 {
    /// No neighbour yet.
    pub const NONE: Knn2 = Knn2 {
        best: u32::MAX,
        best_distance: u32::MAX,
        second_distance: u32::MAX,
    };

    /// Offers candidate `index` at distance `d`; ties keep the earlier index.
    #[inline(always)]
    pub fn offer(&mut self, index: u32, d: u32) {
        if d < self.best_distance {
            self.second_distance = self.best_distance;
            self.best_distance = d;
            self.best = index;
        } else if d < self.second_distance {
            self.second_distance = d;
        }
    }

    /// Whether the best neighbour passes the ratio test and the distance limit.
    pub fn accepted(&self, cfg: &MatchConfig) -> bool {
        if self.best == u32::MAX || self.best_distance > cfg.max_distance {
            return false;
        }
        match cfg.ratio {
            Some(r) if self.second_distance != u32::MAX => {
                (self.best_distance as f32) < r * self.second_distance as f32
            }
            _ => true,
        }
    }
}

/// Queries per rayon task.
const CHUNK: usize = 32;

/// Nearest two train descriptors of every query (ties keep the smaller train index).
pub fn knn2(query: &[Descriptor], train: &[Descriptor]) -> Vec<Knn2> {
    let mut out = vec![Knn2::NONE; query.len()];
    out.par_chunks_mut(CHUNK)
        .zip(query.par_chunks(CHUNK))
        .for_each(|(o, q)| knn2_block(q, train, o));
    out
}

/// Matches every query to its nearest train descriptor, filtered by `cfg` (ratio test,
/// distance limit, cross-check); sorted by query index.
///
/// ```
/// use vofront_features::{match_descriptors, Descriptor, MatchConfig};
/// let a = [Descriptor([0, 0, 0, 0]), Descriptor([u64::MAX, 0, 0, 0])];
/// let b = [Descriptor([u64::MAX, 1, 0, 0]), Descriptor([0, 0, 0, 7])];
/// let m = match_descriptors(&a, &b, &MatchConfig::default());
/// assert_eq!((m[0].query, m[0].train, m[0].distance), (0, 1, 3));
/// assert_eq!((m[1].query, m[1].train, m[1].distance), (1, 0, 1));
/// ```
pub fn match_descriptors(
    query: &[Descriptor],
    train: &[Descriptor],
    cfg: &MatchConfig,
) -> Vec<Match> {
    let forward = knn2(query, train);
    let reverse = cfg.cross_check.then(|| knn2(train, query));
    forward
        .iter()
        .enumerate()
        .filter(|(_, k)| k.accepted(cfg))
        .filter(|(q, k)| {
            reverse
                .as_ref()
                .map_or(true, |r| r[k.best as usize].best == *q as u32)
        })
        .map(|(q, k)| Match {
            query: q as u32,
            train: k.best,
            distance: k.best_distance,
        })
        .collect()
}

/// kNN-2 of a block of queries against all of `train`, using `popcnt` when available.
fn knn2_block(query: &[Descriptor], train: &[Descriptor], out: &mut [Knn2]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU supports `popcnt`, checked just above.
            unsafe { knn2_block_popcnt(query, train, out) };
            return;
        }
    }
    knn2_block_generic(query, train, out);
}

/// The matching loop compiled with the `popcnt` instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
unsafe fn knn2_block_popcnt(query: &[Descriptor], train: &[Descriptor], out: &mut [Knn2]) {
    knn2_block_generic(query, train, out);
}

/// The portable matching loop; inlined into each target-feature variant.
#[inline(always)]
fn knn2_block_generic(query: &[Descriptor], train: &[Descriptor], out: &mut [Knn2]) {
    for (q, o) in query.iter().zip(out.iter_mut()) {
        let mut k = Knn2::NONE;
        for (t, d) in train.iter().enumerate() {
            k.offer(t as u32, q.hamming(d));
        }
        *o = k;
    }
}
