//! Brute-force Hamming matching: k-nearest (k = 2) with Lowe's ratio test, optional mutual
//! (cross-check) filter and a maximum distance, parallel over queries with rayon.
//!
//! The inner loop is `popcount(q XOR t)` over the four 64-bit words of a descriptor. The train
//! descriptors are stored word by word (structure of arrays), so that one query meets
//! `LANES` train descriptors at once: each lane keeps its own nearest two, merged at the end
//! (ties keep the smaller train index, as a sequential scan would). The default x86-64 target
//! has no vector popcount, so on x86-64 the same loop is also compiled with AVX-512's
//! `vpopcntq` and, failing that, with scalar `popcnt`, chosen at run time by what the CPU has.

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

/// Train descriptors per step of the inner loop: eight 64-bit words fill an AVX-512 register.
const LANES: usize = 8;

/// Train descriptors word by word: `words[k][t]` is word `k` of descriptor `t`.
struct TrainWords {
    words: [Vec<u64>; 4],
}

impl TrainWords {
    fn new(train: &[Descriptor]) -> Self {
        Self {
            words: std::array::from_fn(|k| train.iter().map(|d| d.0[k]).collect()),
        }
    }

    fn len(&self) -> usize {
        self.words[0].len()
    }

    /// Descriptor `t`, gathered from its words.
    fn descriptor(&self, t: usize) -> Descriptor {
        Descriptor(self.words.each_ref().map(|w| w[t]))
    }
}

/// Nearest two train descriptors of every query (ties keep the smaller train index).
pub fn knn2(query: &[Descriptor], train: &[Descriptor]) -> Vec<Knn2> {
    let train = TrainWords::new(train);
    let mut out = vec![Knn2::NONE; query.len()];
    out.par_chunks_mut(CHUNK)
        .zip(query.par_chunks(CHUNK))
        .for_each(|(o, q)| knn2_block(q, &train, o));
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
                .is_none_or(|r| r[k.best as usize].best == *q as u32)
        })
        .map(|(q, k)| Match {
            query: q as u32,
            train: k.best,
            distance: k.best_distance,
        })
        .collect()
}

/// kNN-2 of a block of queries against all of `train`, with the best popcount the CPU has.
fn knn2_block(query: &[Descriptor], train: &TrainWords, out: &mut [Knn2]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vpopcntdq")
        {
            // SAFETY: the CPU supports AVX-512F and VPOPCNTDQ, checked just above.
            unsafe { knn2_block_avx512(query, train, out) };
            return;
        }
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU supports `popcnt`, checked just above.
            unsafe { knn2_block_popcnt(query, train, out) };
            return;
        }
    }
    knn2_block_generic(query, train, out);
}

/// The matching loop compiled with AVX-512's vector popcount.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vpopcntdq")]
unsafe fn knn2_block_avx512(query: &[Descriptor], train: &TrainWords, out: &mut [Knn2]) {
    knn2_block_generic(query, train, out);
}

/// The matching loop compiled with the scalar `popcnt` instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
unsafe fn knn2_block_popcnt(query: &[Descriptor], train: &TrainWords, out: &mut [Knn2]) {
    knn2_block_generic(query, train, out);
}

/// The portable matching loop; inlined into each target-feature variant. Lane `l` sees the
/// train descriptors `l, l + LANES, ...` in order, keeping its nearest two branch-free; the
/// lanes are merged by [`merge_lanes`] and the last `len % LANES` offered one by one.
#[inline(always)]
fn knn2_block_generic(query: &[Descriptor], train: &TrainWords, out: &mut [Knn2]) {
    let [w0, w1, w2, w3] = &train.words;
    let full = train.len() / LANES * LANES;
    for (q, o) in query.iter().zip(out.iter_mut()) {
        let mut best = [u32::MAX; LANES];
        let mut second = [u32::MAX; LANES];
        let mut index = [u32::MAX; LANES];
        for base in (0..full).step_by(LANES) {
            let (c0, c1) = (&w0[base..base + LANES], &w1[base..base + LANES]);
            let (c2, c3) = (&w2[base..base + LANES], &w3[base..base + LANES]);
            for l in 0..LANES {
                let d = q.hamming(&Descriptor([c0[l], c1[l], c2[l], c3[l]]));
                let nearer = d < best[l];
                second[l] = if nearer { best[l] } else { second[l].min(d) };
                index[l] = if nearer { (base + l) as u32 } else { index[l] };
                best[l] = if nearer { d } else { best[l] };
            }
        }
        let mut k = merge_lanes(&best, &second, &index);
        for t in full..train.len() {
            k.offer(t as u32, q.hamming(&train.descriptor(t)));
        }
        *o = k;
    }
}

/// The nearest two over all lanes: the nearest lane's best (ties: the smaller index), and the
/// nearer of every other lane's best and every lane's second.
fn merge_lanes(best: &[u32; LANES], second: &[u32; LANES], index: &[u32; LANES]) -> Knn2 {
    let mut k = Knn2::NONE;
    for l in 0..LANES {
        if best[l] < k.best_distance || (best[l] == k.best_distance && index[l] < k.best) {
            k.second_distance = k.best_distance;
            k.best_distance = best[l];
            k.best = index[l];
        } else {
            k.second_distance = k.second_distance.min(best[l]);
        }
        k.second_distance = k.second_distance.min(second[l]);
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, Rng, SeedableRng};

    /// The nearest two by a plain sequential scan with [`Knn2::offer`].
    fn scan(q: &Descriptor, train: &[Descriptor]) -> Knn2 {
        let mut k = Knn2::NONE;
        for (t, d) in train.iter().enumerate() {
            k.offer(t as u32, q.hamming(d));
        }
        k
    }

    /// Descriptors drawn from a few bases with a few flipped bits, so that distances tie often.
    fn descriptors(rng: &mut StdRng, n: usize) -> Vec<Descriptor> {
        let bases: Vec<[u64; 4]> = (0..3)
            .map(|_| std::array::from_fn(|_| rng.random()))
            .collect();
        (0..n)
            .map(|_| {
                let mut w = bases[rng.random_range(0..bases.len())];
                for _ in 0..rng.random_range(0..4) {
                    w[rng.random_range(0..4)] ^= 1u64 << rng.random_range(0..64);
                }
                Descriptor(w)
            })
            .collect()
    }

    #[test]
    fn lanes_and_dispatch_agree_with_a_sequential_scan() {
        let mut rng = StdRng::seed_from_u64(7);
        for n_train in [0, 1, 2, 7, 8, 9, 23, 64, 301] {
            let query = descriptors(&mut rng, 45);
            let train = descriptors(&mut rng, n_train);
            let expected: Vec<Knn2> = query.iter().map(|q| scan(q, &train)).collect();
            let words = TrainWords::new(&train);
            let mut portable = vec![Knn2::NONE; query.len()];
            knn2_block_generic(&query, &words, &mut portable);
            assert_eq!(portable, expected, "portable, {n_train} train descriptors");
            assert_eq!(knn2(&query, &train), expected, "dispatched, {n_train}");
        }
    }
}
