//! Spreading keypoints over the image with a quadtree (as ORB-SLAM's `DistributeOctTree`).
//!
//! The region is split into nodes; in rounds, every node holding more than one point is split
//! into four quadrants (empty quadrants dropped, largest nodes first) until there are at least
//! `n` nodes or no node can be split. Each node then keeps its best-response point; if there are more than
//! `n` nodes, the `n` best of those survive. Dense clusters thus cannot eat the whole budget.
//!
//! Optionally a per-cell floor goes first ([`floor_corners`], [`select`]): the best FAST corner
//! of every tile keeps its place, and the selection above fills the rest of the budget.

use crate::fast::Corner;

/// A quadtree node: a rectangle in level pixels and a range of the shared index buffer.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Node {
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
    start: usize,
    end: usize,
}

impl Node {
    fn len(&self) -> usize {
        self.end - self.start
    }
}

/// Smallest node side in pixels; nodes this small are not split further.
const MIN_NODE: f32 = 1.0;

/// Indices (into `xs`, `ys`, `responses`) of at most `n` points spread over
/// `[x0, x1) x [y0, y1)`: the `ceil(candidates * n)` best responses enter the quadtree, which
/// keeps the best response per node (`candidates <= 1` is plain best-`n` ranking). Points
/// outside the region are clamped into it. Sorted ascending.
pub(crate) fn distribute(
    xs: &[f32],
    ys: &[f32],
    responses: &[f32],
    region: (f32, f32, f32, f32),
    n: usize,
    candidates: f32,
) -> Vec<usize> {
    let count = xs.len();
    if n == 0 || count == 0 {
        return Vec::new();
    }
    if count <= n {
        return (0..count).collect();
    }
    let keep = ((n as f32 * candidates).ceil() as usize).max(n);
    if keep >= count {
        return quadtree(xs, ys, responses, region, n);
    }
    let mut best: Vec<usize> = (0..count).collect();
    best.select_nth_unstable_by(keep - 1, |&a, &b| {
        responses[b].total_cmp(&responses[a]).then(a.cmp(&b))
    });
    best.truncate(keep);
    best.sort_unstable();
    let pick = |v: &[f32]| best.iter().map(|&i| v[i]).collect::<Vec<f32>>();
    let (bx, by, br) = (pick(xs), pick(ys), pick(responses));
    quadtree(&bx, &by, &br, region, n)
        .into_iter()
        .map(|j| best[j])
        .collect()
}

/// The quadtree spread of all the given points (see the module docs).
fn quadtree(
    xs: &[f32],
    ys: &[f32],
    responses: &[f32],
    region: (f32, f32, f32, f32),
    n: usize,
) -> Vec<usize> {
    let count = xs.len();
    let (x0, y0, x1, y1) = region;
    let mut idx: Vec<usize> = (0..count).collect();
    // Roughly square root nodes: as many columns as the aspect ratio says.
    let cols = ((x1 - x0) / (y1 - y0).max(1.0)).round().max(1.0) as usize;
    let rows = ((y1 - y0) / (x1 - x0).max(1.0)).round().max(1.0) as usize;
    let mut nodes: Vec<Node> = Vec::new();
    let cw = (x1 - x0) / cols as f32;
    let ch = (y1 - y0) / rows as f32;
    let cell_of = |i: usize| {
        let c = (((xs[i] - x0) / cw) as usize).min(cols - 1);
        let r = (((ys[i] - y0) / ch) as usize).min(rows - 1);
        r * cols + c
    };
    idx.sort_by_key(|&i| cell_of(i));
    let mut start = 0;
    for cell in 0..rows * cols {
        let end = start
            + idx[start..]
                .iter()
                .take_while(|&&i| cell_of(i) == cell)
                .count();
        if end > start {
            let (c, r) = ((cell % cols) as f32, (cell / cols) as f32);
            nodes.push(Node {
                x0: x0 + c * cw,
                y0: y0 + r * ch,
                x1: x0 + (c + 1.0) * cw,
                y1: y0 + (r + 1.0) * ch,
                start,
                end,
            });
        }
        start = end;
    }
    // Rounds of splitting every splittable node, largest first, as ORB-SLAM does: the tree
    // deepens evenly, so sparse areas get isolated while dense ones are still being split.
    while nodes.len() < n {
        nodes.sort_by(|a, b| b.len().cmp(&a.len()).then(a.start.cmp(&b.start)));
        let mut next = Vec::with_capacity(nodes.len() * 2);
        let mut total = nodes.len();
        let mut split_any = false;
        for node in nodes {
            let splittable =
                node.len() > 1 && node.x1 - node.x0 >= MIN_NODE && node.y1 - node.y0 >= MIN_NODE;
            if !splittable || total >= n {
                next.push(node);
                continue;
            }
            let children = split(node, &mut idx, xs, ys);
            total += children.len() - 1;
            next.extend(children);
            split_any = true;
        }
        nodes = next;
        if !split_any {
            break;
        }
    }
    let done = nodes;
    let mut best: Vec<usize> = done
        .iter()
        .map(|node| {
            idx[node.start..node.end]
                .iter()
                .copied()
                .max_by(|&a, &b| responses[a].total_cmp(&responses[b]).then(b.cmp(&a)))
                .expect("nodes are never empty")
        })
        .collect();
    if best.len() > n {
        best.sort_by(|&a, &b| responses[b].total_cmp(&responses[a]).then(a.cmp(&b)));
        best.truncate(n);
    }
    best.sort_unstable();
    best
}

/// Splits `node` into its non-empty quadrants, reordering its index range.
fn split(node: Node, idx: &mut [usize], xs: &[f32], ys: &[f32]) -> Vec<Node> {
    let mx = 0.5 * (node.x0 + node.x1);
    let my = 0.5 * (node.y0 + node.y1);
    let slice = &mut idx[node.start..node.end];
    let top = partition(slice, |i| ys[i] < my);
    let left_top = partition(&mut slice[..top], |i| xs[i] < mx);
    let left_bottom = partition(&mut slice[top..], |i| xs[i] < mx);
    let s = node.start;
    [
        (node.x0, node.y0, mx, my, s, s + left_top),
        (mx, node.y0, node.x1, my, s + left_top, s + top),
        (node.x0, my, mx, node.y1, s + top, s + top + left_bottom),
        (mx, my, node.x1, node.y1, s + top + left_bottom, node.end),
    ]
    .into_iter()
    .filter(|q| q.5 > q.4)
    .map(|(x0, y0, x1, y1, start, end)| Node {
        x0,
        y0,
        x1,
        y1,
        start,
        end,
    })
    .collect()
}

/// Moves the elements satisfying `pred` to the front; returns how many there are.
fn partition(v: &mut [usize], pred: impl Fn(usize) -> bool) -> usize {
    let mut k = 0;
    for j in 0..v.len() {
        if pred(v[j]) {
            v.swap(k, j);
            k += 1;
        }
    }
    k
}

/// The best-scored FAST corner of every `cell x cell` tile of the level (none for `cell == 0`
/// or a zero budget), in raster order of the corners.
pub(crate) fn floor_corners(corners: &[Corner], cell: usize, n: usize) -> Vec<Corner> {
    if cell == 0 || n == 0 {
        return Vec::new();
    }
    let mut best: std::collections::BTreeMap<(u32, u32), Corner> = Default::default();
    for c in corners {
        let key = (c.y / cell as u32, c.x / cell as u32);
        let e = best.entry(key).or_insert(*c);
        if c.score > e.score {
            *e = *c;
        }
    }
    let mut out: Vec<Corner> = best.into_values().collect();
    out.sort_unstable_by_key(|c| (c.y, c.x));
    out
}

/// Indices into `cand` of the level's `n` features: the `floor` corners first (their best `n`
/// by Harris response when there are more), then the quadtree selection of the others
/// ([`distribute`]) for the rest of the budget. `corners` are the candidates' corners, in
/// the same (raster) order. Sorted ascending.
pub(crate) fn select(
    cand: &Candidates,
    corners: &[Corner],
    floor: &[Corner],
    region: (f32, f32, f32, f32),
    n: usize,
    spread: f32,
) -> Vec<usize> {
    if floor.is_empty() {
        return distribute(&cand.xs, &cand.ys, &cand.responses, region, n, spread);
    }
    let is_floor = |c: &Corner| {
        floor
            .binary_search_by_key(&(c.y, c.x), |f| (f.y, f.x))
            .is_ok()
    };
    let (mut reserved, rest): (Vec<usize>, Vec<usize>) =
        (0..corners.len()).partition(|&i| is_floor(&corners[i]));
    if reserved.len() > n {
        reserved.sort_by(|&a, &b| {
            cand.responses[b]
                .total_cmp(&cand.responses[a])
                .then(a.cmp(&b))
        });
        reserved.truncate(n);
    }
    let pick = |v: &[f32]| rest.iter().map(|&i| v[i]).collect::<Vec<f32>>();
    let more = distribute(
        &pick(&cand.xs),
        &pick(&cand.ys),
        &pick(&cand.responses),
        region,
        n - reserved.len(),
        spread,
    );
    reserved.extend(more.into_iter().map(|j| rest[j]));
    reserved.sort_unstable();
    reserved
}

/// Corners of one level in level pixels with their Harris responses.
pub(crate) struct Candidates {
    pub xs: Vec<f32>,
    pub ys: Vec<f32>,
    pub responses: Vec<f32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dense_cluster_cannot_take_the_whole_budget() {
        // 500 strong points in a 10x10 corner, 20 weak ones spread over the rest.
        let (mut xs, mut ys, mut rs) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..500 {
            xs.push((i % 23) as f32 * 0.4);
            ys.push((i / 23) as f32 * 0.4);
            rs.push(10.0 + i as f32);
        }
        for i in 0..20 {
            xs.push(50.0 + (i % 5) as f32 * 35.0);
            ys.push(50.0 + (i / 5) as f32 * 35.0);
            rs.push(1.0);
        }
        let kept = distribute(&xs, &ys, &rs, (0.0, 0.0, 200.0, 200.0), 40, f32::INFINITY);
        assert_eq!(kept.len(), 40);
        let spread = kept.iter().filter(|&&i| i >= 500).count();
        // Every isolated point gets its own node; the last split round may overshoot the
        // budget by up to 3 nodes, and the weakest (isolated) ones are then cut.
        assert!(spread >= 17, "{spread} of 20 isolated points kept");
    }

    #[test]
    fn keeps_all_when_under_budget_and_none_for_zero() {
        let xs = [1.0, 2.0, 3.0];
        assert_eq!(
            distribute(&xs, &xs, &xs, (0.0, 0.0, 5.0, 5.0), 5, 2.0),
            vec![0, 1, 2]
        );
        assert!(distribute(&xs, &xs, &xs, (0.0, 0.0, 5.0, 5.0), 0, 2.0).is_empty());
    }
}
