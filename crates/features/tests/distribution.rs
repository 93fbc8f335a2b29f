//! Keypoint distribution (`spread_candidates`, the FAST fallback, `cell_floor`) on a rendered
//! image with strong texture in one corner and weak texture everywhere else, as a driving
//! frame's trees beside its road and sky.

use vofront_features::{Features, Orb, OrbConfig};
use vofront_image::Image;

const W: usize = 640;
const H: usize = 480;
/// The grid whose every cell must receive features: 4 x 4 cells of 160 x 120 pixels.
const GRID: usize = 4;

/// Squares of 8 px with pseudo-random grey levels: contrast up to 200 grey levels in the
/// top-left cell of the grid, at most 16 elsewhere (above the fallback FAST threshold 7, below the first one, 20).
fn corner_textured() -> Image<u8> {
    let cell = |x: usize, y: usize| {
        let mut s = ((x / 8) * 7919 + (y / 8) * 104_729) as u32;
        s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
        (s >> 16) % 256
    };
    let data = (0..W * H)
        .map(|i| {
            let (x, y) = (i % W, i / W);
            let r = cell(x, y);
            if x < W / GRID && y < H / GRID {
                (28 + r * 200 / 255) as u8
            } else {
                (120 + r * 16 / 255) as u8
            }
        })
        .collect();
    Image::new(W, H, data).expect("W * H grey levels")
}

/// Features per cell of the `GRID x GRID` grid, row by row.
fn per_cell(f: &Features) -> [usize; GRID * GRID] {
    let mut cells = [0usize; GRID * GRID];
    for (&x, &y) in f.xs().iter().zip(f.ys()) {
        let cx = ((x as usize) * GRID / W).min(GRID - 1);
        let cy = ((y as usize) * GRID / H).min(GRID - 1);
        cells[cy * GRID + cx] += 1;
    }
    cells
}

fn detect(cfg: OrbConfig) -> Features {
    Orb::new(OrbConfig {
        n_features: 500,
        ..cfg
    })
    .expect("valid config")
    .detect_and_describe(&corner_textured())
    .expect("features")
}

#[test]
fn the_quadtree_spread_gives_every_weak_cell_features() {
    // ORB-SLAM's distribution: every FAST corner (the weak cells' at the fallback threshold)
    // enters the quadtree, which keeps one per node.
    let spread = detect(OrbConfig {
        spread_candidates: f32::INFINITY,
        ..OrbConfig::default()
    });
    let cells = per_cell(&spread);
    assert!(spread.len() >= 450, "{}", spread.len());
    assert!(cells.iter().all(|&c| c >= 5), "{cells:?}");
}

#[test]
fn the_fallback_threshold_finds_the_weak_cells_and_the_default_ranks_the_strong_ones() {
    // Without the fallback, only the strong corner has corners at all.
    let strong_only = detect(OrbConfig {
        spread_candidates: f32::INFINITY,
        min_fast_threshold: 20,
        ..OrbConfig::default()
    });
    let cells = per_cell(&strong_only);
    assert!(cells[0] > 0, "{cells:?}");
    assert!(cells.iter().skip(1).all(|&c| c == 0), "{cells:?}");
    // The default selection, mostly Harris ranking, spends the budget where the texture is
    // strong.
    let ranked = detect(OrbConfig::default());
    let cells = per_cell(&ranked);
    assert!(cells[0] * 2 >= ranked.len(), "{cells:?}");
}

#[test]
fn the_cell_floor_keeps_weak_cells_beside_the_ranked_strong_ones() {
    let floored = detect(OrbConfig {
        cell_floor: 64,
        ..OrbConfig::default()
    });
    let cells = per_cell(&floored);
    assert_eq!(floored.len(), 500);
    // Each weak cell holds several 64-px tiles, each keeping its best corner at level 0.
    assert!(cells.iter().all(|&c| c >= 2), "{cells:?}");
    // The rest of the budget still goes by Harris ranking, to the strong corner.
    assert!(cells[0] * 2 >= floored.len(), "{cells:?}");
}
