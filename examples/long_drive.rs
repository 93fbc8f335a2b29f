//! The rendered long drive (`vofront_fixtures::long_drive`: laps of a town loop with sharp
//! corners, reverse driving and a crossing car) tracked by the default [`MonoTracker`], frame
//! by frame as it is rendered: whether every frame is posed, where tracking breaks (frame and
//! the tracker's message), the ATE after Sim(3) alignment, and whether memory and time per
//! frame stay flat over the run.
//!
//!     cargo run --release --example long_drive -- [--frames N] [--size WxH] [--seed S]
//!
//! Defaults: 3000 frames at 1241x376 (KITTI's size), textures seed 1. It prints one line per
//! frame that is lost or restarts tracking, then one JSON line: frames, posed, lost,
//! reinitialised, segment breaks, ATE (metres and percent of the path), resident memory
//! (`VmRSS` of `/proc/self/status`, MiB) at frame 300 and its maximum over the run, the peak
//! (`VmHWM`) at the end, at frame 300 and at the last frame (`hwm_mib_run`, before the
//! evaluation) and the ratio of the last two (an instant's `VmRSS` dips when the allocator
//! returns memory, the peak does not), the local map's points at frame 300 and their maximum, and the tracker's mean
//! time per frame over frames 100-400 and over the last 300 frames (rendering excluded).
//! It also reads the heap itself: the bytes the program holds at the end of each frame
//! ([`CountingAllocator`]) at frame 300, their maximum after it and at the last frame
//! (`heap_mib_*`), which no allocator's timing of returning pages moves.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use nalgebra::Isometry3;

use vofront::dataset::Frame;
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::{TrackStatus, Tracker};
use vofront::trajectory::Trajectory;
use vofront_fixtures::image2d::to_gray8;
use vofront_fixtures::long_drive::{LongDrive, LONG_DRIVE_SIZE};

/// The system allocator, counting the bytes the program holds in [`HEAP_BYTES`].
struct CountingAllocator;

/// Bytes allocated and not yet freed.
static HEAP_BYTES: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded unchanged to `System`, which upholds `GlobalAlloc`'s
// contract; the counter is only arithmetic on the sizes.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's `layout` is passed on as it came.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            HEAP_BYTES.fetch_add(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            HEAP_BYTES.fetch_add(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HEAP_BYTES.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: `ptr` came from this allocator (so from `System`) with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `dealloc`, with the caller's valid `new_size`.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            HEAP_BYTES.fetch_add(new_size, Ordering::Relaxed);
            HEAP_BYTES.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// [`HEAP_BYTES`] in MiB.
fn heap_mib() -> f64 {
    HEAP_BYTES.load(Ordering::Relaxed) as f64 / (1024.0 * 1024.0)
}

/// `(VmRSS, VmHWM)` of this process, MiB (`None` where `/proc` is not there).
fn memory_mib() -> Option<(f64, f64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| -> Option<f64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb / 1024.0)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

/// The value after `flag` in `args`, parsed.
fn flag<T: std::str::FromStr>(args: &[String], flag: &str) -> Option<T> {
    let k = args.iter().position(|a| a == flag)?;
    args.get(k + 1)?.parse().ok()
}

/// Mean of `values[range]` (NaN when empty).
fn mean(values: &[f64], range: std::ops::Range<usize>) -> f64 {
    let part = &values[range.start.min(values.len())..range.end.min(values.len())];
    part.iter().sum::<f64>() / part.len() as f64
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let frames: usize = flag(&args, "--frames").unwrap_or(3000);
    let seed: u64 = flag(&args, "--seed").unwrap_or(1);
    let size = flag::<String>(&args, "--size")
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or(LONG_DRIVE_SIZE);
    let drive = LongDrive::new(seed, frames, size);
    let mut tracker =
        MonoTracker::new(drive.camera, MonoConfig::default()).map_err(|e| e.to_string())?;
    // The local map's points are read from the tracker's details.
    tracker.keep_details(true);
    // Each frame's status and pose, time and map size, allocated and written in full before the
    // run, so that the process grows only by the tracker's memory: a whole estimate with its
    // quality record is 392 bytes, and a growing record of 3000 of them added more than a
    // megabyte to the readings.
    let mut posed = vec![(TrackStatus::Lost, Isometry3::identity()); frames];
    let mut track_ms = vec![0.0; frames];
    let mut map_points = vec![0; frames];
    let (mut rss_max, mut rss_300, mut points_300) = (0.0_f64, f64::NAN, 0);
    let (mut hwm_300, mut hwm_run) = (f64::NAN, f64::NAN);
    let (mut heap_300, mut heap_max, mut heap_last) = (f64::NAN, 0.0_f64, f64::NAN);
    let (mut render_s, mut breaks) = (0.0, 0);
    for i in 0..frames {
        let render_start = Instant::now();
        let image = to_gray8(&drive.render(i).image);
        render_s += render_start.elapsed().as_secs_f64();
        let frame = Frame::new(LongDrive::timestamp(i), image, None).map_err(|e| e.to_string())?;
        let start = Instant::now();
        let estimate = tracker.track(&frame);
        track_ms[i] = 1e3 * start.elapsed().as_secs_f64();
        posed[i] = (estimate.status, estimate.pose_wc);
        for (back, e) in tracker.revised() {
            posed[i - back] = (e.status, e.pose_wc);
        }
        let status = estimate.status;
        if status == TrackStatus::Lost || status == TrackStatus::Reinitialised {
            let message = estimate.message.as_deref().unwrap_or("");
            breaks += usize::from(message.contains("segment break"));
            println!("frame {i}: {status:?}: {message}");
        }
        map_points[i] = tracker.details().map_or(0, |d| d.map_points.len());
        // The heap at the end of the frame: what the tracker (and the renderer) keep.
        drop((frame, estimate));
        heap_last = heap_mib();
        if i == 300.min(frames - 1) {
            heap_300 = heap_last;
        }
        if i >= 300.min(frames - 1) {
            heap_max = heap_max.max(heap_last);
        }
        if let Some((rss, hwm)) = memory_mib() {
            rss_max = rss_max.max(rss);
            hwm_run = hwm;
            if i == 300.min(frames - 1) {
                (rss_300, hwm_300, points_300) = (rss, hwm, map_points[i]);
            }
        }
    }
    let (mut truth, mut trajectory) = (Trajectory::default(), Trajectory::default());
    for (i, (status, pose_wc)) in posed.iter().enumerate() {
        truth.push(LongDrive::timestamp(i), drive.poses_wc[i]);
        if *status != TrackStatus::Lost {
            trajectory.push(LongDrive::timestamp(i), *pose_wc);
        }
    }
    let cfg = EvalConfig {
        alignment: Alignment::Sim3,
        ..EvalConfig::default()
    };
    let ate_m = match ate(&truth, &trajectory, &cfg) {
        Ok(a) => a.stats.rmse,
        Err(e) => {
            eprintln!("long_drive: ATE: {e}");
            f64::NAN
        }
    };
    let path = drive.path_length();
    let count = |s: TrackStatus| posed.iter().filter(|(status, _)| *status == s).count();
    println!(
        "{{\"frames\": {frames}, \"size\": \"{}x{}\", \"posed\": {}, \"lost\": {}, \"reinitialised\": {}, \"segment_breaks\": {breaks}, \"path_m\": {path:.1}, \"ate_m\": {ate_m:.3}, \"ate_percent\": {:.3}, \"rss_mib_300\": {rss_300:.1}, \"rss_mib_max\": {rss_max:.1}, \"rss_ratio\": {:.3}, \"hwm_mib\": {:.1}, \"hwm_mib_300\": {hwm_300:.1}, \"hwm_mib_run\": {hwm_run:.1}, \"hwm_ratio\": {:.3}, \"heap_mib_300\": {heap_300:.2}, \"heap_mib_max\": {heap_max:.2}, \"heap_mib_last\": {heap_last:.2}, \"heap_ratio\": {:.3}, \"map_points_300\": {points_300}, \"map_points_max\": {}, \"ms_100_400\": {:.2}, \"ms_last_300\": {:.2}, \"render_s\": {render_s:.1}}}",
        size.0,
        size.1,
        trajectory.len(),
        count(TrackStatus::Lost),
        count(TrackStatus::Reinitialised),
        100.0 * ate_m / path.max(1e-9),
        rss_max / rss_300,
        memory_mib().map_or(f64::NAN, |m| m.1),
        hwm_run / hwm_300,
        heap_max / heap_300,
        map_points.iter().max().unwrap_or(&0),
        mean(&track_ms, 100..400),
        mean(&track_ms, frames.saturating_sub(300)..frames),
    );
    Ok(())
}
