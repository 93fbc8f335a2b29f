//! What reading a dataset costs: opens each dataset given (a folder or a ROS 2 bag) and loads
//! every frame (grey image, depth when listed), timing the open and the loads separately;
//! prints one JSON line per dataset (`open_ms`, `load_ms_per_frame`, `frames`, and on Linux the
//! process's resident memory after the open and at its peak so far, `rss_mb_open` and
//! `peak_rss_mb`, from `/proc/self/status`). Compare `load_ms_per_frame` with the `ms per
//! frame` of `vofront odometry` on the same data; give one dataset per run for its own peak.
//!
//!     cargo run --release --example read_time -- DATASET [DATASET ...]

use std::time::Instant;

/// A `/proc/self/status` field in MB (`VmRSS`, `VmHWM`), `None` where there is none.
fn status_mb(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

use vofront::dataset::Dataset;
use vofront::timing::ms_since;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: read_time DATASET [DATASET ...]");
        std::process::exit(2);
    }
    for path in paths {
        let start = Instant::now();
        let dataset = Dataset::open(&path)?;
        let open_ms = ms_since(start);
        let rss_open = status_mb("VmRSS:");
        let start = Instant::now();
        for i in 0..dataset.len() {
            dataset.load(i)?;
        }
        let load_ms = ms_since(start);
        println!(
            "{}",
            serde_json::json!({
                "dataset": path,
                "frames": dataset.len(),
                "open_ms": open_ms,
                "load_ms_per_frame": load_ms / dataset.len() as f64,
                "rss_mb_open": rss_open,
                "peak_rss_mb": status_mb("VmHWM:"),
            })
        );
    }
    Ok(())
}
