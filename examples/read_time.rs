//! What reading a dataset costs: opens each dataset given (a folder or a ROS 2 bag) and loads
//! every frame (grey image, depth when listed), timing the open and the loads separately;
//! prints one JSON line per dataset (`open_ms`, `load_ms_per_frame`, `frames`). Compare
//! `load_ms_per_frame` with the `ms per frame` of `vofront odometry` on the same data.
//!
//!     cargo run --release --example read_time -- DATASET [DATASET ...]

use std::time::Instant;

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
            })
        );
    }
    Ok(())
}
