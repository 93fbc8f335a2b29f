//! ORB on two images, kNN-2 + ratio matching, timings and a CSV of the matches.
//!
//! `cargo run --release -p vofront-features --example orb_match -- IMG1 IMG2 [N] [OUT.csv] [ranked]`
//!
//! Prints one line of timings (median of 15 runs; detect+describe with 1 and 2 rayon threads,
//! kNN-2 with 1 thread) and writes `x1,y1,x2,y2,distance` per match to `OUT.csv` if given.
//! `ranked` selects [`OrbConfig::ranked`] instead of the default configuration.

use std::io::Write;
use std::time::Instant;

use vofront_features::{knn2, match_descriptors, MatchConfig, Orb, OrbConfig};
use vofront_image::Image;

fn median_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: orb_match IMG1 IMG2 [N] [OUT.csv] [ranked]".into());
    }
    let i1 = Image::from_gray_owned(image::open(&args[0])?.to_luma8());
    let i2 = Image::from_gray_owned(image::open(&args[1])?.to_luma8());
    let n = args.get(2).map_or(Ok(2000), |s| s.parse())?;
    let base = match args.get(4).map(String::as_str) {
        Some("ranked") => OrbConfig::ranked(),
        _ => OrbConfig::default(),
    };
    let orb = Orb::new(OrbConfig {
        n_features: n,
        ..base
    })?;
    let pool = |k| rayon::ThreadPoolBuilder::new().num_threads(k).build();
    let (one, two) = (pool(1)?, pool(2)?);
    let detect1 = median_ms(15, || {
        one.install(|| orb.detect_and_describe(&i1)).ok();
    });
    let detect2 = median_ms(15, || {
        two.install(|| orb.detect_and_describe(&i1)).ok();
    });
    let f1 = orb.detect_and_describe(&i1)?;
    let f2 = orb.detect_and_describe(&i2)?;
    let knn_ms = median_ms(15, || {
        one.install(|| knn2(f1.descriptors(), f2.descriptors()));
    });
    let cfg = MatchConfig {
        ratio: Some(0.75),
        cross_check: false,
        max_distance: 256,
    };
    let matches = match_descriptors(f1.descriptors(), f2.descriptors(), &cfg);
    let mut levels = [0usize; 32];
    f1.levels().iter().for_each(|&l| levels[l as usize] += 1);
    println!(
        "detect_1t_ms {detect1:.3} detect_2t_ms {detect2:.3} knn2_1t_ms {knn_ms:.3} \
         features {} {} ratio_matches {} per_level {:?}",
        f1.len(),
        f2.len(),
        matches.len(),
        &levels[..orb.config().scale_levels]
    );
    if let Some(path) = args.get(3) {
        let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(out, "x1,y1,x2,y2,distance")?;
        for m in &matches {
            let (q, t) = (m.query as usize, m.train as usize);
            writeln!(
                out,
                "{},{},{},{},{}",
                f1.xs()[q],
                f1.ys()[q],
                f2.xs()[t],
                f2.ys()[t],
                m.distance
            )?;
        }
    }
    Ok(())
}
