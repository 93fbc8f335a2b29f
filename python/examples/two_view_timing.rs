//! Times the library's two-view call (estimation and its JSON report) on one pair, the Rust
//! side of the Python overhead measurement (`examples/two_view_timing.py` times the same work
//! through `vofront.two_view`):
//!
//! `cargo run --release -p vofront-python --example two_view_timing -- IMG1 IMG2 [DEPTH1] [REPS]`
//!
//! Camera: the ROS default (525, 525, 319.5, 239.5). Prints `{"min_ms", "median_ms", "cpu_ms", "reps"}` (`cpu_ms`: process CPU time per call,
//! all threads, the figure least disturbed by other load on the machine).

use std::path::Path;
use std::time::Instant;

use vofront::geometry::camera::{Camera, Pinhole};
use vofront::input::{load_depth, load_gray};
use vofront::report::two_view::to_json;
use vofront::two_view::{estimate, Inputs, Method};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: two_view_timing IMG1 IMG2 [DEPTH1] [REPS]");
        std::process::exit(2);
    }
    let depth1 = match args.get(3) {
        Some(p) => Some(load_depth(Path::new(p), 5000.0)?),
        None => None,
    };
    let reps: usize = args.get(4).map_or(Ok(20), |s| s.parse())?;
    let inputs = Inputs {
        img1: load_gray(Path::new(&args[1]))?,
        img2: load_gray(Path::new(&args[2]))?,
        depth1,
        camera: Camera::pinhole(Pinhole::new(525.0, 525.0, 319.5, 239.5)?),
        method: Method::All,
        features: 2000,
        stereo: None,
    };
    let cpu_start = process_cpu_ms()?;
    let mut ms: Vec<f64> = (0..reps)
        .map(|_| {
            let start = Instant::now();
            let report = to_json(&estimate(&inputs));
            std::hint::black_box(report);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let cpu_ms = (process_cpu_ms()? - cpu_start) / reps as f64;
    ms.sort_by(f64::total_cmp);
    println!(
        "{{\"min_ms\": {:.3}, \"median_ms\": {:.3}, \"cpu_ms\": {cpu_ms:.3}, \"reps\": {reps}}}",
        ms[0],
        ms[ms.len() / 2]
    );
    Ok(())
}

/// User + system CPU time of this process (all threads) so far, milliseconds, from
/// `/proc/self/stat` (fields 14 and 15, in clock ticks of 10 ms). Unlike wall time it does not
/// count the time other processes hold the cores.
fn process_cpu_ms() -> Result<f64, Box<dyn std::error::Error>> {
    let stat = std::fs::read_to_string("/proc/self/stat")?;
    let after_name = stat.rsplit_once(')').ok_or("malformed /proc/self/stat")?.1;
    let fields: Vec<&str> = after_name.split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>()? + fields[12].parse::<f64>()?;
    Ok(ticks * 10.0)
}
