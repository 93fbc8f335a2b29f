//! Five-point minimal solver for the essential matrix (Stewenius, Engels and Nister 2006).
//!
//! Given five correspondences `x2_i^T E x1_i = 0` (bearings or homogeneous normalized
//! coordinates), `E` lies in the 4-dimensional null space of the 5x9 constraint matrix:
//! `E = x X + y Y + z Z + W`. The cubic constraints `det E = 0` and
//! `2 E E^T E - tr(E E^T) E = 0` give ten equations in the twenty monomials of degree <= 3 in
//! `(x, y, z)`. Gauss-Jordan elimination expresses the ten cubic monomials in the basis
//! `b = [x^2, xy, xz, y^2, yz, z^2, x, y, z, 1]`, which yields the 10x10 action matrix of
//! multiplication by `x`: `A b(s) = x(s) b(s)` at every solution `s`. Its real eigenvalues and
//! eigenvectors give up to ten essential matrices.

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix algebra

use nalgebra::{Matrix3, SMatrix, Schur, Vector3};

/// Upper bound on the Schur decomposition's QR iterations for the 10x10 action matrix (a
/// converging decomposition takes a few per eigenvalue); a sample that needs more gives no
/// solution.
const MAX_QR_ITERATIONS: usize = 1000;

/// Number of monomials of degree <= 3 in three variables.
const NMON: usize = 20;

/// A polynomial of degree <= 3 in `(x, y, z)` in the monomial order
/// `x^3, x^2y, x^2z, xy^2, xyz, xz^2, y^3, y^2z, yz^2, z^3, x^2, xy, xz, y^2, yz, z^2, x, y, z, 1`.
type Poly = [f64; NMON];

/// Exponents `(ex, ey, ez)` of each monomial of [`Poly`].
const EXPONENTS: [[u8; 3]; NMON] = [
    [3, 0, 0],
    [2, 1, 0],
    [2, 0, 1],
    [1, 2, 0],
    [1, 1, 1],
    [1, 0, 2],
    [0, 3, 0],
    [0, 2, 1],
    [0, 1, 2],
    [0, 0, 3],
    [2, 0, 0],
    [1, 1, 0],
    [1, 0, 1],
    [0, 2, 0],
    [0, 1, 1],
    [0, 0, 2],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [0, 0, 0],
];

/// Index in [`Poly`] of the monomial `x^ex y^ey z^ez`, `usize::MAX` above degree 3.
const fn monomial_index(e: [u8; 3]) -> usize {
    let mut k = 0;
    while k < NMON {
        let m = EXPONENTS[k];
        if m[0] == e[0] && m[1] == e[1] && m[2] == e[2] {
            return k;
        }
        k += 1;
    }
    usize::MAX
}

/// `PRODUCT[i][j]`: index of monomial `i` times monomial `j` (`usize::MAX` above degree 3).
const PRODUCT: [[usize; NMON]; NMON] = {
    let mut t = [[usize::MAX; NMON]; NMON];
    let mut i = 0;
    while i < NMON {
        let mut j = 0;
        while j < NMON {
            let a = EXPONENTS[i];
            let b = EXPONENTS[j];
            t[i][j] = monomial_index([a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
            j += 1;
        }
        i += 1;
    }
    t
};

/// First index of the monomials of degree <= 1 and <= 2 in [`Poly`].
const LINEAR: usize = 16;
const QUADRATIC: usize = 10;

/// `a * b` for `a` supported on indices `from_a..` and `b` on `from_b..` (degree of the
/// product <= 3 guaranteed by the caller).
fn mul_from(a: &Poly, from_a: usize, b: &Poly, from_b: usize) -> Poly {
    let mut out = [0.0; NMON];
    for i in from_a..NMON {
        let ai = a[i];
        let row = &PRODUCT[i];
        for j in from_b..NMON {
            out[row[j]] += ai * b[j];
        }
    }
    out
}

/// Product of two linear polynomials.
fn mul(a: &Poly, b: &Poly) -> Poly {
    mul_from(a, LINEAR, b, LINEAR)
}

/// Product of a quadratic and a linear polynomial.
fn mul_ql(q: &Poly, l: &Poly) -> Poly {
    mul_from(q, QUADRATIC, l, LINEAR)
}

fn add(a: &Poly, b: &Poly) -> Poly {
    std::array::from_fn(|k| a[k] + b[k])
}

fn scale(a: &Poly, s: f64) -> Poly {
    a.map(|v| v * s)
}

/// Null space basis `[X, Y, Z, W]` (each a row-major 3x3 as 9 numbers) of the 5x9 matrix
/// with rows `x2 (x) x1`, by Gauss-Jordan elimination with partial pivoting.
fn null_space(x1: &[Vector3<f64>; 5], x2: &[Vector3<f64>; 5]) -> Option<[[f64; 9]; 4]> {
    let mut a = [[0.0; 9]; 5];
    for (row, (p, q)) in a.iter_mut().zip(x1.iter().zip(x2)) {
        for r in 0..3 {
            for c in 0..3 {
                row[3 * r + c] = q[r] * p[c];
            }
        }
    }
    for k in 0..5 {
        let piv = (k..5)
            .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
            .expect("non-empty range");
        if a[piv][k].abs() < 1e-12 {
            return None;
        }
        a.swap(k, piv);
        let inv = 1.0 / a[k][k];
        for v in a[k].iter_mut() {
            *v *= inv;
        }
        for i in 0..5 {
            if i != k {
                let f = a[i][k];
                if f != 0.0 {
                    for c in k..9 {
                        a[i][c] -= f * a[k][c];
                    }
                }
            }
        }
    }
    let mut basis = [[0.0; 9]; 4];
    for (k, b) in basis.iter_mut().enumerate() {
        for (r, row) in a.iter().enumerate() {
            b[r] = -row[5 + k];
        }
        b[5 + k] = 1.0;
    }
    // Orthonormalise (modified Gram-Schmidt) so that the unknowns x, y, z stay of order one
    // and the action matrix well scaled.
    for k in 0..4 {
        for j in 0..k {
            let d: f64 = (0..9).map(|i| basis[k][i] * basis[j][i]).sum();
            for i in 0..9 {
                basis[k][i] -= d * basis[j][i];
            }
        }
        let n = basis[k].iter().map(|v| v * v).sum::<f64>().sqrt();
        if n.is_nan() || n <= 1e-12 {
            return None;
        }
        for v in basis[k].iter_mut() {
            *v /= n;
        }
    }
    Some(basis)
}

/// Null vector of a (numerically) rank-9 10x10 matrix by Gaussian elimination with full
/// pivoting.
fn null_vector(mut m: SMatrix<f64, 10, 10>) -> Option<[f64; 10]> {
    let mut cols: [usize; 10] = std::array::from_fn(|i| i);
    for k in 0..9 {
        let (mut pi, mut pj, mut best) = (k, k, 0.0);
        for j in k..10 {
            for i in k..10 {
                let v = m[(i, j)].abs();
                if v > best {
                    (pi, pj, best) = (i, j, v);
                }
            }
        }
        if best < 1e-14 {
            return None;
        }
        m.swap_rows(k, pi);
        m.swap_columns(k, pj);
        cols.swap(k, pj);
        let inv = 1.0 / m[(k, k)];
        for i in k + 1..10 {
            let f = m[(i, k)] * inv;
            if f != 0.0 {
                for j in k..10 {
                    m[(i, j)] -= f * m[(k, j)];
                }
            }
        }
    }
    let mut v = [0.0; 10];
    v[9] = 1.0;
    for k in (0..9).rev() {
        let s: f64 = (k + 1..10).map(|j| m[(k, j)] * v[j]).sum();
        v[k] = -s / m[(k, k)];
    }
    let mut out = [0.0; 10];
    for (k, &c) in cols.iter().enumerate() {
        out[c] = v[k];
    }
    Some(out)
}

/// Essential matrices consistent with five correspondences `x2_i^T E x1_i = 0`.
///
/// `x1`, `x2`: bearings (or homogeneous normalized coordinates `(x, y, 1)`) in cameras 1 and 2
/// of the same five points; the solutions (up to ten, unit Frobenius norm, sign arbitrary) are
/// appended to `out` after clearing it. Degenerate samples give no solution.
///
/// ```
/// use nalgebra::{Matrix3, Rotation3, Vector3};
/// use vofront_geometry::essential::essential_5pt;
/// let r = Rotation3::new(Vector3::new(0.05, -0.1, 0.02));
/// let t = Vector3::new(0.3, 0.05, 0.1);
/// let pts = [[0.1, 0.2, 3.0], [-0.5, 0.3, 4.0], [0.7, -0.4, 5.0], [0.2, 0.9, 2.5], [-0.8, -0.6, 6.0]];
/// let x1: [Vector3<f64>; 5] = std::array::from_fn(|i| Vector3::from(pts[i]));
/// let x2: [Vector3<f64>; 5] = std::array::from_fn(|i| r * x1[i] + t);
/// let mut sols = Vec::new();
/// essential_5pt(&x1, &x2, &mut sols);
/// let truth = vofront_geometry::lie::hat(&t) * r.matrix();
/// let truth = truth / truth.norm();
/// assert!(sols.iter().any(|e| (e - truth).norm() < 1e-6 || (e + truth).norm() < 1e-6));
/// ```
pub fn essential_5pt(x1: &[Vector3<f64>; 5], x2: &[Vector3<f64>; 5], out: &mut Vec<Matrix3<f64>>) {
    out.clear();
    let Some(basis) = null_space(x1, x2) else {
        return;
    };
    // E_ij as a linear polynomial x X_ij + y Y_ij + z Z_ij + W_ij.
    let e: [[Poly; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let mut p = [0.0; NMON];
            p[16] = basis[0][3 * r + c];
            p[17] = basis[1][3 * r + c];
            p[18] = basis[2][3 * r + c];
            p[19] = basis[3][3 * r + c];
            p
        })
    });
    let mut m = [[0.0; NMON]; 10];
    // det E by cofactors of the first row.
    let cof = |a: usize, b: usize, c: usize, d: usize| -> Poly {
        add(
            &mul(&e[1][a], &e[2][b]),
            &scale(&mul(&e[1][c], &e[2][d]), -1.0),
        )
    };
    let det = add(
        &add(
            &mul_ql(&cof(1, 2, 2, 1), &e[0][0]),
            &mul_ql(&cof(2, 0, 0, 2), &e[0][1]),
        ),
        &mul_ql(&cof(0, 1, 1, 0), &e[0][2]),
    );
    m[0] = det;
    // E E^T (symmetric, quadratic entries).
    let mut eet = [[[0.0; NMON]; 3]; 3];
    for r in 0..3 {
        for c in r..3 {
            let mut s = [0.0; NMON];
            for k in 0..3 {
                s = add(&s, &mul(&e[r][k], &e[c][k]));
            }
            eet[r][c] = s;
            eet[c][r] = s;
        }
    }
    let trace = scale(&add(&add(&eet[0][0], &eet[1][1]), &eet[2][2]), -0.5);
    // (E E^T - tr/2 I) E = 0, i.e. half the trace constraint.
    for r in 0..3 {
        for c in 0..3 {
            let mut s = mul_ql(&trace, &e[r][c]);
            for k in 0..3 {
                s = add(&s, &mul_ql(&eet[r][k], &e[k][c]));
            }
            m[1 + 3 * r + c] = s;
        }
    }
    let system = m;
    let Some(reduced) = eliminate(&mut m) else {
        return;
    };
    // Action matrix of multiplication by x on b = [x^2, xy, xz, y^2, yz, z^2, x, y, z, 1]:
    // x b = [x^3, x^2y, x^2z, xy^2, xyz, xz^2, x^2, xy, xz, x].
    let mut action = SMatrix::<f64, 10, 10>::zeros();
    for r in 0..6 {
        for c in 0..10 {
            action[(r, c)] = -reduced[r][10 + c];
        }
    }
    action[(6, 0)] = 1.0;
    action[(7, 1)] = 1.0;
    action[(8, 2)] = 1.0;
    action[(9, 6)] = 1.0;
    // A bounded QR iteration: nalgebra's `complex_eigenvalues()` iterates without limit and
    // never returned on one action matrix (a RANSAC sample of relative-pose scene 615734).
    let Some(schur) = Schur::try_new(action, f64::EPSILON, MAX_QR_ITERATIONS) else {
        return;
    };
    let eig = schur.complex_eigenvalues();
    for lambda in eig.iter() {
        if lambda.im.abs() > 1e-8 * (1.0 + lambda.re.abs()) {
            continue;
        }
        let mut shifted = action;
        for k in 0..10 {
            shifted[(k, k)] -= lambda.re;
        }
        let Some(b) = null_vector(shifted) else {
            continue;
        };
        if b[9].abs() < 1e-12 {
            continue;
        }
        let (x, y, z) = polish(&system, [b[6] / b[9], b[7] / b[9], b[8] / b[9]]);
        let ess = Matrix3::from_fn(|r, c| {
            let k = 3 * r + c;
            x * basis[0][k] + y * basis[1][k] + z * basis[2][k] + basis[3][k]
        });
        let n = ess.norm();
        if n > 0.0 && n.is_finite() && is_essential(&(ess / n)) {
            out.push(ess / n);
        }
    }
}

/// Largest violation of `det E = 0` and `2 E E^T E - tr(E E^T) E = 0` accepted for a
/// unit-norm solution; spurious real parts of nearly complex eigenvalue pairs fail it.
const ESSENTIAL_TOL: f64 = 1e-7;

/// True when the unit-norm `e` satisfies the essential constraints within [`ESSENTIAL_TOL`].
fn is_essential(e: &Matrix3<f64>) -> bool {
    let eet = e * e.transpose();
    let trace = 2.0 * eet * e - eet.trace() * e;
    e.determinant().abs() < ESSENTIAL_TOL && trace.norm() < ESSENTIAL_TOL
}

/// Gauss-Jordan elimination of the ten cubic monomials (columns 0..10) of `m`; `None` when
/// the 10x10 block is singular (degenerate sample).
fn eliminate(m: &mut [[f64; NMON]; 10]) -> Option<&[[f64; NMON]; 10]> {
    for k in 0..10 {
        let piv = (k..10)
            .max_by(|&i, &j| m[i][k].abs().total_cmp(&m[j][k].abs()))
            .expect("non-empty range");
        if m[piv][k].abs() < 1e-14 {
            return None;
        }
        m.swap(k, piv);
        let inv = 1.0 / m[k][k];
        for v in m[k].iter_mut() {
            *v *= inv;
        }
        let pivot_row = m[k];
        for (i, row) in m.iter_mut().enumerate() {
            if i != k {
                let f = row[k];
                if f != 0.0 {
                    for c in k..NMON {
                        row[c] -= f * pivot_row[c];
                    }
                }
            }
        }
    }
    Some(m)
}

/// Gauss-Newton steps polishing each root.
const POLISH_STEPS: usize = 1;

/// Values of the twenty monomials at `(x, y, z)` and their partial derivatives.
fn monomials(p: [f64; 3]) -> ([f64; NMON], [[f64; NMON]; 3]) {
    let pw = |v: f64, e: u8| -> f64 { (0..e).fold(1.0, |a, _| a * v) };
    let mut val = [0.0; NMON];
    let mut der = [[0.0; NMON]; 3];
    for (k, e) in EXPONENTS.iter().enumerate() {
        let f = [pw(p[0], e[0]), pw(p[1], e[1]), pw(p[2], e[2])];
        val[k] = f[0] * f[1] * f[2];
        for d in 0..3 {
            if e[d] > 0 {
                let mut g = f;
                g[d] = e[d] as f64 * pw(p[d], e[d] - 1);
                der[d][k] = g[0] * g[1] * g[2];
            }
        }
    }
    (val, der)
}

/// Gauss-Newton refinement of a root `(x, y, z)` of the ten cubic constraints (the
/// eigen decomposition loses digits on nearly repeated eigenvalues).
fn polish(system: &[[f64; NMON]; 10], mut p: [f64; 3]) -> (f64, f64, f64) {
    for _ in 0..POLISH_STEPS {
        let (val, der) = monomials(p);
        let mut jtj = nalgebra::Matrix3::<f64>::zeros();
        let mut jtr = Vector3::zeros();
        for row in system {
            let r: f64 = row.iter().zip(&val).map(|(a, b)| a * b).sum();
            let j = Vector3::from_fn(|d, _| row.iter().zip(&der[d]).map(|(a, b)| a * b).sum());
            jtj += j * j.transpose();
            jtr += j * r;
        }
        match jtj.try_inverse() {
            Some(inv) => {
                let step = inv * jtr;
                if !step.iter().all(|v| v.is_finite()) {
                    break;
                }
                p = [p[0] - step.x, p[1] - step.y, p[2] - step.z];
            }
            None => break,
        }
    }
    (p[0], p[1], p[2])
}
