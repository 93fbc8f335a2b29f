//! Windowed matching for frame-to-frame tracking: each query is compared only with the train
//! features within `radius` level-0 pixels of its predicted position (and optionally within
//! `level_tolerance` pyramid levels of its own level), then filtered like
//! [`crate::match_descriptors`].

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::matching::{Knn2, Match, MatchConfig};
use crate::{FeatureError, Features};

/// Train features bucketed on a square grid of side `cell` pixels.
struct Grid {
    x0: f32,
    y0: f32,
    cell: f32,
    cols: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c`.
    starts: Vec<usize>,
    items: Vec<u32>,
}

impl Grid {
    fn new(xs: &[f32], ys: &[f32], cell: f32) -> Self {
        let finite = |v: &&f32| v.is_finite();
        let min = |v: &[f32]| {
            v.iter()
                .filter(finite)
                .fold(f32::INFINITY, |a, &b| a.min(b))
        };
        let max = |v: &[f32]| {
            v.iter()
                .filter(finite)
                .fold(f32::NEG_INFINITY, |a, &b| a.max(b))
        };
        let (x0, y0) = (min(xs), min(ys));
        let (x0, y0) = if x0.is_finite() { (x0, y0) } else { (0.0, 0.0) };
        let span = |lo: f32, hi: f32| {
            if hi >= lo {
                ((hi - lo) / cell) as usize + 1
            } else {
                1
            }
        };
        let (cols, rows) = (span(x0, max(xs)), span(y0, max(ys)));
        let mut grid = Self {
            x0,
            y0,
            cell,
            cols,
            rows,
            starts: vec![0; cols * rows + 1],
            items: Vec::with_capacity(xs.len()),
        };
        let cells: Vec<Option<usize>> = xs
            .iter()
            .zip(ys)
            .map(|(&x, &y)| grid.cell_of(x, y))
            .collect();
        for c in cells.iter().flatten() {
            grid.starts[c + 1] += 1;
        }
        for c in 0..cols * rows {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut fill = grid.starts.clone();
        grid.items = vec![0; grid.starts[cols * rows]];
        for (i, c) in cells.iter().enumerate() {
            if let Some(c) = c {
                grid.items[fill[*c]] = i as u32;
                fill[*c] += 1;
            }
        }
        grid
    }

    fn cell_of(&self, x: f32, y: f32) -> Option<usize> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let c = ((x - self.x0) / self.cell).floor();
        let r = ((y - self.y0) / self.cell).floor();
        (c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows)
            .then(|| r as usize * self.cols + c as usize)
    }

    /// Calls `f` on every item whose cell overlaps the square `[x - r, x + r] x [y - r, y + r]`.
    fn visit(&self, x: f32, y: f32, r: f32, mut f: impl FnMut(u32)) {
        let lo = |v: f32, o: f32| (((v - r - o) / self.cell).floor().max(0.0)) as usize;
        let hi = |v: f32, o: f32, n: usize| {
            let h = ((v + r - o) / self.cell).floor();
            if h < 0.0 {
                None
            } else {
                Some((h as usize).min(n - 1))
            }
        };
        let (Some(c1), Some(r1)) = (hi(x, self.x0, self.cols), hi(y, self.y0, self.rows)) else {
            return;
        };
        for row in lo(y, self.y0)..=r1 {
            for col in lo(x, self.x0)..=c1 {
                let c = row * self.cols + col;
                self.items[self.starts[c]..self.starts[c + 1]]
                    .iter()
                    .for_each(|&i| f(i));
            }
        }
    }
}

/// Matches each query feature `i` to the train features within `radius` level-0 pixels of
/// `predicted[i]` (Euclidean), and, if `level_tolerance` is `Some(k)`, whose pyramid level
/// differs by at most `k`. The nearest candidate is kept under `cfg` (ratio test against the
/// second nearest in the window, maximum distance; cross-check: the query must also be the
/// nearest among the queries whose window contains that train feature). Queries with a
/// non-finite prediction are skipped. Sorted by query index.
///
/// ```
/// use vofront_features::{match_windowed, Descriptor, Features, MatchConfig};
/// let f = |x: f32, d: u64| {
///     Features::new(vec![x], vec![10.0], vec![0], vec![1.0], vec![0.0], vec![1.0], vec![Descriptor([d, 0, 0, 0])])
///         .unwrap()
/// };
/// let m = match_windowed(&f(10.0, 1), &[(52.0, 10.0)], &f(50.0, 3), 5.0, None, &MatchConfig::default())
///     .unwrap();
/// assert_eq!((m[0].query, m[0].train, m[0].distance), (0, 0, 1));
/// ```
pub fn match_windowed(
    query: &Features,
    predicted: &[(f32, f32)],
    train: &Features,
    radius: f32,
    level_tolerance: Option<u8>,
    cfg: &MatchConfig,
) -> Result<Vec<Match>, FeatureError> {
    if predicted.len() != query.len() {
        return Err(FeatureError::LengthMismatch {
            expected: query.len(),
            got: predicted.len(),
        });
    }
    if !(radius.is_finite() && radius >= 0.0) {
        return Err(FeatureError::InvalidRadius(radius));
    }
    if query.is_empty() || train.is_empty() {
        return Ok(Vec::new());
    }
    let grid = Grid::new(train.xs(), train.ys(), radius.max(8.0));
    let r2 = radius * radius;
    let candidates = |q: usize, mut f: Box<dyn FnMut(u32, u32) + '_>| {
        let (px, py) = predicted[q];
        if !(px.is_finite() && py.is_finite()) {
            return;
        }
        let level = query.levels()[q];
        grid.visit(px, py, radius, |t| {
            let ti = t as usize;
            let (dx, dy) = (train.xs()[ti] - px, train.ys()[ti] - py);
            let level_ok = level_tolerance.is_none_or(|k| train.levels()[ti].abs_diff(level) <= k);
            if dx * dx + dy * dy <= r2 && level_ok {
                f(t, query.descriptors()[q].hamming(&train.descriptors()[ti]));
            }
        });
    };
    let knn: Vec<Knn2> = (0..query.len())
        .into_par_iter()
        .map(|q| {
            let mut k = Knn2::NONE;
            candidates(q, Box::new(|t, d| k.offer(t, d)));
            k
        })
        .collect();
    // Reverse nearest query per train feature, packed as (distance << 32 | query) so that
    // `fetch_min` keeps the smallest distance and then the smallest query index.
    let reverse: Option<Vec<AtomicU64>> = cfg.cross_check.then(|| {
        let best: Vec<AtomicU64> = (0..train.len()).map(|_| AtomicU64::new(u64::MAX)).collect();
        (0..query.len()).into_par_iter().for_each(|q| {
            candidates(
                q,
                Box::new(|t, d| {
                    best[t as usize].fetch_min(((d as u64) << 32) | q as u64, Ordering::Relaxed);
                }),
            );
        });
        best
    });
    Ok(knn
        .iter()
        .enumerate()
        .filter(|(_, k)| k.accepted(cfg))
        .filter(|(q, k)| {
            reverse.as_ref().is_none_or(|r| {
                r[k.best as usize].load(Ordering::Relaxed) & 0xffff_ffff == *q as u64
            })
        })
        .map(|(q, k)| Match {
            query: q as u32,
            train: k.best,
            distance: k.best_distance,
        })
        .collect())
}
