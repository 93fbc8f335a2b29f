//! Wall-clock timing of the pipelines' stages (the `ms` fields of every report).

use std::time::Instant;

/// Milliseconds since `start`: `start.elapsed()` in seconds times 1000.
pub fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
