//! Shi-Tomasi + pyramidal KLT on a real image pair, timed like `opencv_peer.py klt`.
//!
//! Usage: `cargo run --release -p vofront-direct --example klt_real -- IMG1 IMG2 [N] [REPS] [OUT.csv]`
//!
//! Detects `N` (500) corners in `IMG1` (quality 0.01, min distance 8, as the peer), tracks
//! them into `IMG2` with the default 21x21 window and 4 levels, with and without the
//! forward-backward check, and prints the median times and track counts. With `OUT.csv`, the
//! corners and their tracked positions are written as `x1,y1,x2,y2,status` so that another
//! tracker can be compared on the same points.

use std::io::Write;
use std::time::Instant;

use vofront_direct::{good_features_to_track, track_klt, KltConfig, KltStatus};
use vofront_image::Image;

fn median_ms<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::new();
    let mut out = None;
    for _ in 0..reps.max(1) {
        let start = Instant::now();
        out = Some(f());
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (
        times[times.len() / 2],
        out.expect("at least one repetition"),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: klt_real IMG1 IMG2 [N] [REPS] [OUT.csv]");
        std::process::exit(2);
    }
    let i1 = Image::from_gray8(&image::open(&args[1])?.to_luma8());
    let i2 = Image::from_gray8(&image::open(&args[2])?.to_luma8());
    let n: usize = args.get(3).map_or(Ok(500), |s| s.parse())?;
    let reps: usize = args.get(4).map_or(Ok(20), |s| s.parse())?;
    let (detect_ms, corners) = median_ms(reps, || good_features_to_track(&i1, n, 0.01, 8.0));
    let plain = KltConfig {
        forward_backward: None,
        ..KltConfig::default()
    };
    let (track_ms, tracks) = median_ms(reps, || track_klt(&i1, &i2, &corners, &plain));
    let tracks = tracks?;
    let (fb_ms, fb_tracks) = median_ms(reps, || {
        track_klt(&i1, &i2, &corners, &KltConfig::default())
    });
    let fb_tracks = fb_tracks?;
    let ok = |t: &[vofront_direct::KltTrack]| {
        t.iter().filter(|t| t.status == KltStatus::Tracked).count()
    };
    println!(
        "{{\"detect_ms\": {detect_ms:.3}, \"track_ms\": {track_ms:.3}, \"track_fb_ms\": {fb_ms:.3}, \"points\": {}, \"tracked\": {}, \"tracked_fb\": {}}}",
        corners.len(),
        ok(&tracks),
        ok(&fb_tracks)
    );
    if let Some(path) = args.get(5) {
        let mut f = std::fs::File::create(path)?;
        for (p, t) in corners.iter().zip(&tracks) {
            let status = u8::from(t.status == KltStatus::Tracked);
            writeln!(
                f,
                "{},{},{},{},{status}",
                p.x, p.y, t.position.x, t.position.y
            )?;
        }
    }
    Ok(())
}
