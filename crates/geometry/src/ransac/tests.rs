//! Tests of the LO-MSAC loop on a line fixture.

use super::*;

/// Line `y = a x + b` through two points; residual is the vertical distance.
struct Line(Vec<(f64, f64)>);

impl Estimator for Line {
    type Model = (f64, f64);
    fn sample_size(&self) -> usize {
        2
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        out.clear();
        let ((x0, y0), (x1, y1)) = (self.0[s[0]], self.0[s[1]]);
        if (x1 - x0).abs() > 1e-12 {
            let a = (y1 - y0) / (x1 - x0);
            out.push((a, y0 - a * x0));
        }
    }
    fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        out.clear();
        let n = s.len() as f64;
        let (mx, my) = s
            .iter()
            .fold((0.0, 0.0), |(a, b), &i| (a + self.0[i].0, b + self.0[i].1));
        let (mx, my) = (mx / n, my / n);
        let sxy: f64 = s
            .iter()
            .map(|&i| (self.0[i].0 - mx) * (self.0[i].1 - my))
            .sum();
        let sxx: f64 = s.iter().map(|&i| (self.0[i].0 - mx).powi(2)).sum();
        let a = sxy / sxx;
        out.push((a, my - a * mx));
    }
    fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
        let (x, y) = self.0[i];
        (m.0 * x + m.1 - y).powi(2)
    }
}

fn data() -> Line {
    // 60 points on y = 2x + 1 with +-0.05 deterministic noise, 60 gross outliers.
    let mut pts = Vec::new();
    for i in 0..120 {
        let x = i as f64 * 0.1;
        let noise = 0.05 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
        let y = if i % 2 == 0 {
            2.0 * x + 1.0 + noise
        } else {
            ((i * 104_729) % 97) as f64 - 40.0
        };
        pts.push((x, y));
    }
    Line(pts)
}

#[test]
fn adaptive_iteration_count_matches_the_formula() {
    // log(1 - 0.99) / log(1 - 0.5^2) = 16.0078...
    assert_eq!(required_iterations(0.99, 0.5, 2), 17);
    assert_eq!(required_iterations(0.99, 1.0, 2), 1);
    assert_eq!(required_iterations(0.99, 0.0, 2), usize::MAX);
}

#[test]
fn finds_the_line_among_half_outliers_reproducibly() {
    let d = data();
    let cfg = RansacConfig {
        threshold: 0.1,
        ..Default::default()
    };
    let a = ransac(&d, &cfg).expect("a model");
    assert!((a.model.0 - 2.0).abs() < 0.01 && (a.model.1 - 1.0).abs() < 0.05);
    assert!(a.inlier_count() >= 60 && a.inlier_count() <= 62);
    // The ratio asks for ~30 samples: the search stops at the minimum, far below the cap.
    assert_eq!(a.iterations, cfg.min_iterations);
    let b = ransac(&d, &cfg).expect("a model");
    assert_eq!((a.model, a.iterations), (b.model, b.iterations));
}

/// The line data with another local optimisation: `refit(line, inliers, out)`.
struct Refit<F>(Line, F);

impl<F: Fn(&Line, &[usize], &mut Vec<(f64, f64)>) + Sync> Estimator for Refit<F> {
    type Model = (f64, f64);
    fn sample_size(&self) -> usize {
        2
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        self.0.fit_minimal(s, out);
    }
    fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        (self.1)(&self.0, s, out);
    }
    fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
        self.0.residual_sq(m, i)
    }
}

/// A local optimisation that never reproduces a model.
fn never_refits(_: &Line, _: &[usize], out: &mut Vec<(f64, f64)>) {
    out.clear();
}

#[test]
fn an_unconfirmed_model_never_shortens_the_search() {
    let cfg = RansacConfig {
        threshold: 0.1,
        max_iterations: 700,
        ..Default::default()
    };
    let res = ransac(&Refit(data(), never_refits), &cfg).expect("a model");
    // Still the right line (the best minimal model), but found without confirmation, so
    // the search ran to the cap.
    assert!((res.model.0 - 2.0).abs() < 0.05);
    assert_eq!(res.iterations, cfg.max_iterations);
    // With local optimisation disabled every model counts as confirmed.
    let no_lo = RansacConfig {
        lo_rounds: 0,
        ..cfg
    };
    let res = ransac(&Refit(data(), never_refits), &no_lo).expect("a model");
    assert_eq!(res.iterations, cfg.min_iterations);
}

#[test]
fn a_guess_is_polished_first_and_a_wrong_one_is_beaten() {
    let d = data();
    let cfg = RansacConfig {
        threshold: 0.1,
        ..Default::default()
    };
    // With no sample drawn, a guess near the line comes back refitted on its inliers.
    let none_drawn = RansacConfig {
        min_iterations: 0,
        max_iterations: 0,
        ..cfg
    };
    let guess = (2.02, 0.95);
    let polished = ransac_from(&d, &none_drawn, Some(guess)).expect("the guess");
    assert_eq!(polished.iterations, 0);
    assert_ne!(polished.model, guess);
    assert!((polished.model.0 - 2.0).abs() < 0.01 && (polished.model.1 - 1.0).abs() < 0.05);
    assert!(polished.inlier_count() >= 60);
    assert!(ransac(&d, &none_drawn).is_none());
    // A wrong guess loses to the sampled line.
    let beaten = ransac_from(&d, &cfg, Some((-1.0, 30.0))).expect("a model");
    let plain = ransac(&d, &cfg).expect("a model");
    assert!((beaten.model.0 - 2.0).abs() < 0.01 && (beaten.model.1 - 1.0).abs() < 0.05);
    assert_eq!(beaten.inlier_count(), plain.inlier_count());
    assert_eq!(beaten.iterations, cfg.min_iterations);
}

#[test]
fn the_minimum_holds_even_when_every_point_is_an_inlier() {
    let exact = Line((0..50).map(|i| (i as f64, 3.0 * i as f64 - 2.0)).collect());
    for min_iterations in [1, 37, 250] {
        let cfg = RansacConfig {
            threshold: 0.01,
            min_iterations,
            ..Default::default()
        };
        let res = ransac(&exact, &cfg).expect("a model");
        assert_eq!(res.iterations, min_iterations);
        assert_eq!(res.inlier_count(), 50);
    }
}

#[test]
fn too_few_points_give_none() {
    let d = Line(vec![(0.0, 0.0)]);
    assert!(ransac(&d, &RansacConfig::default()).is_none());
}

#[test]
fn a_run_capped_at_its_least_budget_is_the_start_of_a_longer_one() {
    // The two-view selection relies on this: the homography's least budget runs first,
    // and a larger budget re-runs it from the same seed.
    let est = data();
    let at = |max_iterations| {
        ransac(
            &est,
            &RansacConfig {
                threshold: 0.2,
                min_iterations: 30,
                max_iterations,
                ..Default::default()
            },
        )
        .expect("a model")
    };
    let (capped, longer) = (at(30), at(10_000));
    assert_eq!(capped.iterations, 30);
    assert_eq!(
        longer.iterations, 30,
        "the inlier ratio asks for fewer than 30"
    );
    assert_eq!((capped.model, capped.score), (longer.model, longer.score));
    assert_eq!(capped.inliers, longer.inliers);
}

/// [`Line`] counting its local optimisations.
struct Counting(Line, std::sync::atomic::AtomicUsize);

impl Estimator for Counting {
    type Model = (f64, f64);
    fn sample_size(&self) -> usize {
        self.0.sample_size()
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        self.0.fit_minimal(s, out);
    }
    fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.0.fit_nonminimal(s, out);
    }
    fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
        self.0.residual_sq(m, i)
    }
}

#[test]
fn hypotheses_that_share_the_polished_inliers_are_not_polished_again() {
    let est = Counting(data(), std::sync::atomic::AtomicUsize::new(0));
    let run = |lo_skip_shared| {
        est.1.store(0, std::sync::atomic::Ordering::Relaxed);
        let cfg = RansacConfig {
            threshold: 0.1,
            lo_skip_shared,
            ..Default::default()
        };
        let result = ransac(&est, &cfg).expect("a model");
        (result, est.1.load(std::sync::atomic::Ordering::Relaxed))
    };
    let (every, refits_every) = run(f64::INFINITY);
    let (skipping, refits_skipping) = run(0.9);
    assert!(
        refits_skipping < refits_every,
        "{refits_skipping} refits against {refits_every}"
    );
    assert_eq!(skipping.inliers, every.inliers);
    assert!((skipping.model.0 - every.model.0).abs() < 1e-9);
    assert!((skipping.model.1 - every.model.1).abs() < 1e-9);
    // A share above 1 can never be met: nothing is skipped.
    assert_eq!(run(1.0 + 1e-9).1, refits_every);
}

/// Two lines sharing most inliers: 60 points near `x = 0` lie within the threshold (0.1) of
/// any line through the origin with a slope under 0.4; far out, 20 points lie on the true line
/// `y = 0` and 10 on `y = 0.3 x`; 20 gross outliers.
fn shared_inliers() -> Line {
    let mut rng = StdRng::seed_from_u64(5);
    let mut pts = Vec::new();
    for _ in 0..60 {
        pts.push((rng.random_range(-0.2..0.2), rng.random_range(-0.02..0.02)));
    }
    for _ in 0..20 {
        pts.push((rng.random_range(2.0..4.0), rng.random_range(-0.02..0.02)));
    }
    for _ in 0..10 {
        let x = rng.random_range(2.0..4.0);
        pts.push((x, 0.3 * x + rng.random_range(-0.02..0.02)));
    }
    for _ in 0..20 {
        pts.push((rng.random_range(-4.0..4.0), rng.random_range(2.0..6.0)));
    }
    Line(pts)
}

/// [`Line`] whose every minimal sample gives the line `y = 0.05 x`: a raw hypothesis of the
/// true line `y = 0` that keeps only the 60 points near the origin.
struct NearTrue(Line);

impl Estimator for NearTrue {
    type Model = (f64, f64);
    fn sample_size(&self) -> usize {
        self.0.sample_size()
    }
    fn len(&self) -> usize {
        self.0.len()
    }
    fn fit_minimal(&self, _s: &[usize], out: &mut Vec<(f64, f64)>) {
        out.clear();
        out.push((0.05, 0.0));
    }
    fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
        self.0.fit_nonminimal(s, out);
    }
    fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
        self.0.residual_sq(m, i)
    }
}

#[test]
fn skipping_a_hypothesis_that_shares_the_polished_inliers_can_miss_the_better_model() {
    let est = NearTrue(shared_inliers());
    // The guess, near the wrong line, is polished first onto `y = 0.3 x` (70 inliers). The
    // raw `y = 0.05 x` then scores worse than it, has fewer inliers (60), all of them the
    // wrong line's. Polished, its first refit on the 60 points near the origin brings in the
    // 20 on `y = 0`, and it ends on the true line (80 inliers); skipped, it never does.
    let run = |lo_skip_shared| {
        let cfg = RansacConfig {
            threshold: 0.1,
            lo_skip_shared,
            ..Default::default()
        };
        ransac_from(&est, &cfg, Some((0.3, 0.03))).expect("a model")
    };
    let polished = run(RansacConfig::default().lo_skip_shared);
    assert!(
        polished.model.0.abs() < 0.02 && polished.model.1.abs() < 0.02,
        "{:?}",
        polished.model
    );
    assert_eq!(polished.inlier_count(), 80);
    let skipped = run(0.9);
    assert!((skipped.model.0 - 0.3).abs() < 0.02, "{:?}", skipped.model);
    assert_eq!(skipped.inlier_count(), 70);
    assert!(skipped.score > polished.score);
}

#[test]
fn thinning_keeps_an_even_spread_of_the_list() {
    let mut v: Vec<usize> = (0..10).collect();
    local::thin_evenly(&mut v, 4);
    assert_eq!(v, [0, 2, 5, 7]);
    let mut short = vec![3, 1, 4];
    local::thin_evenly(&mut short, 4);
    assert_eq!(short, [3, 1, 4]);
    let mut one = vec![5, 6, 7];
    local::thin_evenly(&mut one, 0);
    assert_eq!(one, [5]);
}

#[test]
fn a_capped_local_optimisation_refits_on_few_inliers_and_scores_on_all() {
    // The result and the largest set a refit was given.
    let run = |lo_max_inliers| {
        let largest = std::sync::atomic::AtomicUsize::new(0);
        let est = Refit(
            data(),
            |line: &Line, s: &[usize], out: &mut Vec<(f64, f64)>| {
                largest.fetch_max(s.len(), std::sync::atomic::Ordering::Relaxed);
                line.fit_nonminimal(s, out);
            },
        );
        let cfg = RansacConfig {
            threshold: 0.1,
            lo_max_inliers,
            ..Default::default()
        };
        let res = ransac(&est, &cfg).expect("a model");
        (res, largest.into_inner())
    };
    let (all, largest_all) = run(RansacConfig::default().lo_max_inliers);
    assert!(
        largest_all >= 60,
        "uncapped refits see every inlier: {largest_all}"
    );
    let (capped, largest_capped) = run(12);
    assert_eq!(largest_capped, 12);
    // Twelve of the sixty inliers, spread along the line, still give the line, and its
    // inliers are counted on every point.
    assert!((capped.model.0 - 2.0).abs() < 0.02 && (capped.model.1 - 1.0).abs() < 0.1);
    assert!(capped.inlier_count() >= 59, "{}", capped.inlier_count());
    assert!((capped.model.0 - all.model.0).abs() < 0.02);
}
