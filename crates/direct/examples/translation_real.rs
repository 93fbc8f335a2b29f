//! Recovers a synthetic sub-pixel shift of a real image, as `opencv_peer.py translation` does.
//!
//! Usage: `cargo run --release -p vofront-direct --example translation_real -- IMG DX DY [REPS]`
//!
//! The moved image replicates `cv2.warpAffine(img, [[1, 0, dx], [0, 1, dy]], INTER_LINEAR)`:
//! `moved(x) = img(x - d)` by bilinear interpolation with OpenCV's 1/32-pixel weight
//! quantisation and a black border. Prints the shift found, its error against the nominal
//! shift and against the 1/32-quantised one, and the median time of `align_translation`.

use std::time::Instant;

use vofront_direct::{align_translation, TranslationConfig, TranslationMethod};
use vofront_image::Image;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: translation_real IMG DX DY [REPS]");
        std::process::exit(2);
    }
    let img = Image::from_gray8(&image::open(&args[1])?.to_luma8());
    let (dx, dy): (f64, f64) = (args[2].parse()?, args[3].parse()?);
    let reps: usize = args.get(4).map_or(Ok(20), |s| s.parse())?;
    let quantised = ((dx * 32.0).round() / 32.0, (dy * 32.0).round() / 32.0);
    let moved = shift_like_opencv(&img, quantised.0, quantised.1);
    for method in [
        TranslationMethod::InverseCompositional,
        TranslationMethod::ForwardAdditive,
    ] {
        let cfg = TranslationConfig {
            method,
            ..TranslationConfig::default()
        };
        let mut times = Vec::new();
        let mut fit = None;
        for _ in 0..reps {
            let start = Instant::now();
            fit = Some(align_translation(&img, &moved, &cfg)?);
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let fit = fit.expect("reps >= 1");
        let err = |t: (f64, f64)| ((fit.d.x - t.0).powi(2) + (fit.d.y - t.1).powi(2)).sqrt();
        println!(
            "{{\"method\": \"{method:?}\", \"d\": [{:.5}, {:.5}], \"err_nominal\": {:.5}, \"err_quantised\": {:.5}, \"ms\": {:.3}, \"iterations\": {:?}, \"rmse\": {:.3}, \"used\": {:.3}, \"converged\": {}}}",
            fit.d.x,
            fit.d.y,
            err((dx, dy)),
            err(quantised),
            times[times.len() / 2],
            fit.iterations,
            fit.rmse,
            fit.used_fraction,
            fit.converged
        );
    }
    Ok(())
}

/// `moved(x, y) = img(x - dx, y - dy)`, bilinear, 0 outside (`cv2.warpAffine` semantics).
fn shift_like_opencv(img: &Image<f32>, dx: f64, dy: f64) -> Image<f32> {
    let (w, h) = img.size();
    let mut out = Image::filled(w, h, 0.0);
    for y in 0..h {
        for x in 0..w {
            let (sx, sy) = (x as f64 - dx, y as f64 - dy);
            let (x0, y0) = (sx.floor(), sy.floor());
            let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
            let px = |xx: f64, yy: f64| {
                if xx >= 0.0 && yy >= 0.0 && (xx as usize) < w && (yy as usize) < h {
                    img.at(xx as usize, yy as usize)
                } else {
                    0.0
                }
            };
            let top = px(x0, y0) * (1.0 - fx) + px(x0 + 1.0, y0) * fx;
            let bottom = px(x0, y0 + 1.0) * (1.0 - fx) + px(x0 + 1.0, y0 + 1.0) * fx;
            out.data_mut()[y * w + x] = top * (1.0 - fy) + bottom * fy;
        }
    }
    out
}
