//! The block solve against the dense solve of the full normal equations.

use super::*;

/// A deterministic pseudo-random sequence in `[-1, 1]`.
fn f(k: usize) -> f64 {
    ((k as f64) * 0.7391).sin()
}

/// `A = I + sum J_o^T J_o` for two random rows per observation (every point seen by every one
/// of `k` poses; with `hosted`, each row also depends on the next pose, as a photometric
/// residual on its point's host frame): symmetric positive definite with the bundle sparsity;
/// and a gradient `g`.
fn dense_problem<const P: usize, const Q: usize>(
    k: usize,
    m: usize,
    hosted: bool,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = P * k + Q * m;
    let mut a = DMatrix::<f64>::identity(n, n);
    let mut idx = 0;
    for j in 0..m {
        for i in 0..k {
            for _ in 0..2 {
                let mut row = DVector::<f64>::zeros(n);
                for c in 0..P {
                    row[P * i + c] = f(idx);
                    idx += 1;
                }
                if hosted && k > 1 {
                    let host = (i + 1) % k;
                    for c in 0..P {
                        row[P * host + c] = f(idx);
                        idx += 1;
                    }
                }
                for c in 0..Q {
                    row[P * k + Q * j + c] = f(idx);
                    idx += 1;
                }
                a += &row * row.transpose();
            }
        }
    }
    let g = DVector::<f64>::from_fn(n, |r, _| f(1000 + r));
    (a, g)
}

/// The blocks of a dense system built by [`dense_problem`].
fn blocks<const P: usize, const Q: usize>(
    a: &DMatrix<f64>,
    g: &DVector<f64>,
    k: usize,
    m: usize,
) -> SchurSystem<P, Q> {
    SchurSystem {
        u: (0..k)
            .map(|i| a.fixed_view::<P, P>(P * i, P * i).into_owned())
            .collect(),
        gc: (0..k)
            .map(|i| g.fixed_rows::<P>(P * i).into_owned())
            .collect(),
        points: (0..m)
            .map(|j| PointBlock {
                v: a.fixed_view::<Q, Q>(P * k + Q * j, P * k + Q * j)
                    .into_owned(),
                gp: g.fixed_rows::<Q>(P * k + Q * j).into_owned(),
                couplings: (0..k)
                    .map(|i| Coupling {
                        pose: i,
                        w: a.fixed_view::<P, Q>(P * i, P * k + Q * j).into_owned(),
                    })
                    .collect(),
            })
            .collect(),
        pairs: (0..k)
            .flat_map(|i| (i + 1..k).map(move |l| (i, l)))
            .map(|(i, l)| PosePair {
                // Given in both orders, to check that either is read right.
                i: if (i + l) % 2 == 0 { i } else { l },
                k: if (i + l) % 2 == 0 { l } else { i },
                u: if (i + l) % 2 == 0 {
                    a.fixed_view::<P, P>(P * i, P * l).into_owned()
                } else {
                    a.fixed_view::<P, P>(P * l, P * i).into_owned()
                },
            })
            .collect(),
    }
}

/// Solves the block system and the dense `(A + lambda diag(A)) d = -g`, compares the steps and
/// `d^T A d`; returns the block step.
fn check_against_dense<const P: usize, const Q: usize>(
    k: usize,
    m: usize,
    hosted: bool,
) -> SchurStep<P, Q> {
    let (a, g) = dense_problem::<P, Q>(k, m, hosted);
    let system = blocks::<P, Q>(&a, &g, k, m);
    let lambda = 0.1;
    let step = system.solve(lambda, Damping::Diagonal, 1e10).unwrap();
    let mut damped_a = a.clone();
    for i in 0..a.nrows() {
        damped_a[(i, i)] += lambda * a[(i, i)];
    }
    let dense = damped_a.cholesky().unwrap().solve(&(-&g));
    let mut full = DVector::<f64>::zeros(a.nrows());
    for i in 0..k {
        let want = dense.fixed_rows::<P>(P * i).into_owned();
        assert!((step.poses[i] - want).norm() < 1e-10, "pose {i}");
        full.fixed_rows_mut::<P>(P * i).copy_from(&step.poses[i]);
    }
    for j in 0..m {
        let want = dense.fixed_rows::<Q>(P * k + Q * j).into_owned();
        assert!((step.points[j] - want).norm() < 1e-10, "point {j}");
        full.fixed_rows_mut::<Q>(P * k + Q * j)
            .copy_from(&step.points[j]);
    }
    // delta^T A delta from the blocks equals the dense quadratic form (undamped A).
    let quad = (full.transpose() * &a * &full)[(0, 0)];
    assert!((system.information_norm2(&step) - quad).abs() < 1e-9 * quad.abs());
    step
}

#[test]
fn pose_and_point_blocks_match_the_dense_solve() {
    // Two free 6-dof poses, three 3-dof points, every point seen by both poses.
    check_against_dense::<6, 3>(2, 3, false);
}

#[test]
fn frames_with_brightness_and_inverse_depths_match_the_dense_solve() {
    // Three free 8-dof frames (pose, a, b), five 1-dof inverse depths: diagonal elimination.
    let step = check_against_dense::<8, 1>(3, 5, false);
    assert_eq!((step.poses.len(), step.points.len()), (3, 5));
}

#[test]
fn residuals_on_two_frames_match_the_dense_solve() {
    // Four free frames, each residual also on its point's host (the next frame): the pose
    // pairs fill U's off-diagonal blocks.
    let (a, _) = dense_problem::<8, 1>(4, 6, true);
    assert!(a.fixed_view::<8, 8>(0, 8).norm() > 0.0);
    let step = check_against_dense::<8, 1>(4, 6, true);
    assert_eq!((step.poses.len(), step.points.len()), (4, 6));
}

#[test]
fn a_point_without_observations_keeps_a_zero_step() {
    let (k, m) = (3, 5);
    let (a, g) = dense_problem::<8, 1>(k, m, false);
    let mut system = blocks::<8, 1>(&a, &g, k, m);
    let reference = system.solve(0.1, Damping::Diagonal, 1e10).unwrap();
    // V = 0 stays 0 under Marquardt damping: not positive definite, so the point is held.
    let mut held = PointBlock::zeros();
    held.gp[0] = 3.0;
    system.points.push(held);
    let step = system.solve(0.1, Damping::Diagonal, 1e10).unwrap();
    assert_eq!(step.points[m][0], 0.0);
    assert_eq!(step.poses, reference.poses);
    assert_eq!(&step.points[..m], &reference.points[..]);
}

#[test]
fn non_finite_blocks_are_an_error() {
    let (a, g) = dense_problem::<8, 1>(2, 2, false);
    let mut system = blocks::<8, 1>(&a, &g, 2, 2);
    system.points[1].gp[0] = f64::NAN;
    assert_eq!(
        system.solve(0.1, Damping::Diagonal, 1e10),
        Err(SolveError::NotFinite)
    );
}
