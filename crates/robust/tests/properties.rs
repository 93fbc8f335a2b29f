//! Property tests of the robust core: loss identities, IRLS under outliers, degeneracy.

use nalgebra::{Matrix2, SVector, Vector2};
use proptest::prelude::*;
use vofront_robust::{
    irls, solve_damped, Damping, IrlsConfig, IrlsError, Loss, NormalEquations, Problem, RobustLoss,
    Rows, ScaleMode, SolveError,
};

fn every_loss() -> Vec<Loss> {
    vec![
        Loss::Squared,
        Loss::Huber(1.345),
        Loss::Cauchy(2.385),
        Loss::Tukey(4.685),
        Loss::StudentT(5.0),
    ]
}

proptest! {
    #[test]
    fn huber_weight_is_one_inside_and_delta_over_r_outside(delta in 0.1f64..10.0, r in -100.0f64..100.0) {
        let w = Loss::Huber(delta).weight(r);
        if r.abs() <= delta {
            prop_assert_eq!(w, 1.0);
        } else {
            prop_assert!((w - delta / r.abs()).abs() <= 1e-15);
        }
    }

    #[test]
    fn weights_are_in_unit_interval_and_times_r_give_psi(r in -50.0f64..50.0) {
        for loss in every_loss() {
            let w = loss.weight(r);
            // Tukey is redescending: its weight is exactly 0 past c; the others stay positive.
            let lower_ok = if matches!(loss, Loss::Tukey(_)) { w >= 0.0 } else { w > 0.0 };
            prop_assert!(lower_ok && w <= 1.0, "{loss:?} w({r}) = {w}");
            prop_assert!((w * r - loss.psi(r)).abs() <= 1e-12 * (1.0 + r.abs()), "{loss:?}");
        }
    }

    #[test]
    fn rho_is_even_and_non_decreasing(a in 0.0f64..50.0, b in 0.0f64..50.0) {
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        for loss in every_loss() {
            prop_assert_eq!(loss.rho(hi), loss.rho(-hi));
            prop_assert!(loss.rho(lo) <= loss.rho(hi) + 1e-12, "{loss:?}");
            prop_assert!(loss.rho(0.0) == 0.0);
        }
    }

    #[test]
    fn psi_is_continuous_and_is_the_derivative_of_rho(r in -20.0f64..20.0) {
        let h = 1e-6;
        for loss in every_loss() {
            let jump = (loss.psi(r + h) - loss.psi(r - h)).abs();
            prop_assert!(jump < 1e-4, "{loss:?} psi jumps by {jump} at {r}");
            let numeric = (loss.rho(r + h) - loss.rho(r - h)) / (2.0 * h);
            prop_assert!((numeric - loss.psi(r)).abs() < 1e-5, "{loss:?} at {r}");
        }
    }

    #[test]
    fn merged_accumulators_equal_one_accumulator(
        rows in prop::collection::vec((prop::array::uniform6(-10.0f64..10.0), -5.0f64..5.0, 0.0f64..1.0), 1..60),
        split in 0usize..60,
    ) {
        let split = split.min(rows.len());
        let add = |ne: &mut NormalEquations<6>, (j, r, w): &([f64; 6], f64, f64)| {
            ne.add(&SVector::from(*j), *r, *w)
        };
        let mut all = NormalEquations::<6>::new();
        rows.iter().for_each(|row| add(&mut all, row));
        let mut left = NormalEquations::<6>::new();
        let mut right = NormalEquations::<6>::new();
        rows[..split].iter().for_each(|row| add(&mut left, row));
        rows[split..].iter().for_each(|row| add(&mut right, row));
        let merged = left.merge(&right);
        prop_assert!((merged.hessian() - all.hessian()).abs().max() < 1e-9);
        prop_assert!((merged.g - all.g).abs().max() < 1e-9);
        prop_assert!((merged.cost - all.cost).abs() < 1e-9);
        prop_assert_eq!(merged.count, all.count);
    }

    #[test]
    fn affine_brightness_least_squares_matches_closed_form(
        a in 0.5f64..2.0, b in -40.0f64..40.0,
        refs in prop::collection::vec(0.0f64..255.0, 8..100),
        noise_seed in any::<u64>(),
    ) {
        // Fit I_t = a I_ref + b: residual r = a I_ref + b - I_t, Jacobian [I_ref, 1].
        let mut state = noise_seed;
        let targets: Vec<f64> = refs.iter().map(|&x| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            a * x + b + ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5)
        }).collect();
        let mut ne = NormalEquations::<2>::new();
        for (&x, &y) in refs.iter().zip(&targets) {
            ne.add(&Vector2::new(x, 1.0), -y, 1.0);
        }
        prop_assume!(refs.iter().any(|&x| (x - refs[0]).abs() > 1.0));
        let fit = solve_damped(&ne.hessian(), &ne.g, 0.0, Damping::Diagonal, 1e12).unwrap();
        // Closed form of the 2x2 normal equations.
        let n = refs.len() as f64;
        let (sx, sy) = (refs.iter().sum::<f64>(), targets.iter().sum::<f64>());
        let sxx: f64 = refs.iter().map(|x| x * x).sum();
        let sxy: f64 = refs.iter().zip(&targets).map(|(x, y)| x * y).sum();
        let a_closed = (n * sxy - sx * sy) / (n * sxx - sx * sx);
        let b_closed = (sy - a_closed * sx) / n;
        prop_assert!((fit[0] - a_closed).abs() < 1e-8 * (1.0 + a_closed.abs()));
        prop_assert!((fit[1] - b_closed).abs() < 1e-6 * (1.0 + b_closed.abs()));
    }

    #[test]
    fn collinear_gradients_are_reported_as_degenerate(
        angle in 0.0f64..std::f64::consts::PI,
        mags in prop::collection::vec(0.1f64..50.0, 2..200),
    ) {
        // Every image gradient points along one direction: the 2D translation H has rank 1.
        let dir = Vector2::new(angle.cos(), angle.sin());
        let mut ne = NormalEquations::<2>::new();
        for (i, m) in mags.iter().enumerate() {
            ne.add(&(dir * *m), (i as f64).sin(), 1.0);
        }
        let res = solve_damped(&ne.hessian(), &ne.g, 0.0, Damping::Diagonal, 1e10);
        prop_assert!(matches!(res, Err(SolveError::Degenerate { .. })), "{res:?}");
    }

    #[test]
    fn irls_recovers_a_line_with_thirty_percent_gross_outliers(
        slope in -3.0f64..3.0, offset in -10.0f64..10.0, seed in any::<u64>(),
    ) {
        let points = line_with_outliers(slope, offset, seed);
        let cfg = IrlsConfig { loss: Loss::Cauchy(2.385), ..IrlsConfig::default() };
        let robust = irls(&mut Line(points.clone()), Vector2::zeros(), &cfg).unwrap();
        let l2_cfg = IrlsConfig { loss: Loss::Squared, ..IrlsConfig::default() };
        let plain = irls(&mut Line(points), Vector2::zeros(), &l2_cfg).unwrap();
        prop_assert!((robust.state[0] - slope).abs() < 0.02, "robust {:?}", robust.state);
        prop_assert!((robust.state[1] - offset).abs() < 0.5, "robust {:?}", robust.state);
        let l2_err = (plain.state[0] - slope).abs() + (plain.state[1] - offset).abs() / 10.0;
        prop_assert!(l2_err > 0.1, "least squares should be pulled away: {:?}", plain.state);
    }
}

/// Fit `y = m x + c`: residual `m x + c - y`, Jacobian `[x, 1]`.
struct Line(Vec<(f64, f64)>);

impl Problem<2> for Line {
    type State = Vector2<f64>;
    fn evaluate(&mut self, p: &Vector2<f64>, rows: &mut Rows<2>) {
        for &(x, y) in &self.0 {
            rows.push(Vector2::new(x, 1.0), p[0] * x + p[1] - y);
        }
    }
    fn retract(&self, p: &Vector2<f64>, d: &Vector2<f64>) -> Vector2<f64> {
        p + d
    }
}

/// 100 points on the line with +-0.1 noise, 30 of them replaced by points 20..60 above it.
fn line_with_outliers(slope: f64, offset: f64, seed: u64) -> Vec<(f64, f64)> {
    let mut state = seed | 1;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..100)
        .map(|i| {
            let x = i as f64 / 10.0;
            let y = slope * x + offset + 0.2 * (uniform() - 0.5);
            if i % 10 < 3 {
                (x, y + 20.0 + 40.0 * uniform())
            } else {
                (x, y)
            }
        })
        .collect()
}

#[test]
fn irls_reports_degenerate_problems_and_too_few_rows() {
    // All x equal: slope and offset cannot be told apart.
    let mut vertical = Line(vec![(1.0, 2.0); 10]);
    let err = irls(&mut vertical, Vector2::zeros(), &IrlsConfig::default()).unwrap_err();
    assert!(
        matches!(err, IrlsError::Solve(SolveError::Degenerate { .. })),
        "{err:?}"
    );
    let mut single = Line(vec![(1.0, 2.0)]);
    let err = irls(&mut single, Vector2::zeros(), &IrlsConfig::default()).unwrap_err();
    assert_eq!(
        err,
        IrlsError::TooFewResiduals {
            rows: 1,
            required: 2
        }
    );
}

#[test]
fn irls_covariance_is_whites_estimator_for_least_squares() {
    // For plain least squares the sandwich covariance is White's heteroscedasticity-consistent
    // estimator n / (n - 2) (J^T J)^-1 (sum r_i^2 J_i J_i^T) (J^T J)^-1.
    let points = line_with_outliers(1.0, 0.0, 7)
        .into_iter()
        .enumerate()
        .filter(|(i, _)| i % 10 >= 3)
        .map(|(_, p)| p)
        .collect::<Vec<_>>();
    let cfg = IrlsConfig {
        loss: Loss::Squared,
        scale: ScaleMode::Fixed(1.0),
        ..IrlsConfig::default()
    };
    let fit = irls(&mut Line(points.clone()), Vector2::zeros(), &cfg).unwrap();
    let covariance = fit.covariance.expect("a well-posed line fit");
    let row = |x: f64| Vector2::new(x, 1.0);
    let jtj = points.iter().fold(Matrix2::zeros(), |acc, &(x, _)| {
        acc + row(x) * row(x).transpose()
    });
    let meat = points.iter().fold(Matrix2::zeros(), |acc, &(x, y)| {
        let r = fit.state[0] * x + fit.state[1] - y;
        acc + row(x) * row(x).transpose() * (r * r)
    });
    let n = points.len() as f64;
    let bread = jtj.try_inverse().unwrap();
    let expected = bread * meat * bread * (n / (n - 2.0));
    assert!((covariance - expected).abs().max() < 1e-9 * expected.abs().max());
    assert!(fit.costs.windows(2).all(|c| c[1] <= c[0]));
}

#[test]
fn irls_without_covariance_reaches_the_same_state_and_reports_none() {
    let points = line_with_outliers(0.5, 2.0, 11);
    let with = irls(
        &mut Line(points.clone()),
        Vector2::zeros(),
        &IrlsConfig::default(),
    )
    .unwrap();
    let without_cfg = IrlsConfig {
        covariance: false,
        ..IrlsConfig::default()
    };
    let without = irls(&mut Line(points), Vector2::zeros(), &without_cfg).unwrap();
    assert!(with.covariance.is_some());
    assert!(without.covariance.is_none());
    assert_eq!(with.state, without.state);
    assert_eq!(with.hessian, without.hessian);
}
