//! Robust losses for M-estimation.
//!
//! Each loss is a function `rho(r)` of a residual `r` that is already divided by the residual
//! scale (so `r` is in sigmas). The influence is `psi(r) = rho'(r)` and the IRLS weight is
//! `w(r) = psi(r) / r`, which is what iteratively reweighted least squares multiplies each
//! squared residual by. All losses are normalised so that `rho(r) ~ r^2 / 2` near zero, hence
//! `w(0) = 1`.

/// A robust loss `rho(r)` with its influence `psi = rho'` and IRLS weight `psi(r) / r`.
pub trait RobustLoss {
    /// The loss `rho(r)`: even, non-decreasing in `|r|`, `rho(0) = 0`.
    fn rho(&self, r: f64) -> f64;
    /// The influence `psi(r) = d rho / d r`.
    fn psi(&self, r: f64) -> f64;
    /// The IRLS weight `psi(r) / r`, taken as its limit `1` at `r = 0`.
    fn weight(&self, r: f64) -> f64;
    /// The curvature `psi'(r) = d^2 rho / d r^2` (the one-sided value at a kink), which the
    /// sandwich covariance of an M-estimate needs; negative where a redescending loss bends
    /// down.
    fn psi_prime(&self, r: f64) -> f64;
}

/// Plain least squares: `rho = r^2 / 2`, weight 1.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Squared;

impl RobustLoss for Squared {
    fn rho(&self, r: f64) -> f64 {
        0.5 * r * r
    }
    fn psi(&self, r: f64) -> f64 {
        r
    }
    fn weight(&self, _r: f64) -> f64 {
        1.0
    }
    fn psi_prime(&self, _r: f64) -> f64 {
        1.0
    }
}

/// Huber loss with threshold `delta`: quadratic for `|r| <= delta`, linear beyond.
///
/// `rho = r^2/2` for `|r| <= delta`, `delta (|r| - delta/2)` otherwise;
/// weight `1` inside, `delta / |r|` outside. `delta = 1.345` gives 95% efficiency on Gaussians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Huber {
    /// Threshold between the quadratic and the linear part, in sigmas.
    pub delta: f64,
}

impl RobustLoss for Huber {
    fn rho(&self, r: f64) -> f64 {
        let a = r.abs();
        if a <= self.delta {
            0.5 * r * r
        } else {
            self.delta * (a - 0.5 * self.delta)
        }
    }
    fn psi(&self, r: f64) -> f64 {
        r.clamp(-self.delta, self.delta)
    }
    fn weight(&self, r: f64) -> f64 {
        let a = r.abs();
        if a <= self.delta {
            1.0
        } else {
            self.delta / a
        }
    }
    fn psi_prime(&self, r: f64) -> f64 {
        if r.abs() <= self.delta {
            1.0
        } else {
            0.0
        }
    }
}

/// Cauchy (Lorentzian) loss: `rho = c^2/2 ln(1 + (r/c)^2)`, weight `1 / (1 + (r/c)^2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cauchy {
    /// Scale parameter `c` in sigmas (2.385 gives 95% efficiency on Gaussians).
    pub c: f64,
}

impl RobustLoss for Cauchy {
    fn rho(&self, r: f64) -> f64 {
        let q = r / self.c;
        0.5 * self.c * self.c * q.mul_add(q, 1.0).ln()
    }
    fn psi(&self, r: f64) -> f64 {
        r * self.weight(r)
    }
    fn weight(&self, r: f64) -> f64 {
        let q = r / self.c;
        1.0 / q.mul_add(q, 1.0)
    }
    /// `(1 - q^2) / (1 + q^2)^2`, `q = r / c`.
    fn psi_prime(&self, r: f64) -> f64 {
        let q2 = (r / self.c).powi(2);
        (1.0 - q2) / (1.0 + q2).powi(2)
    }
}

/// Tukey's biweight: redescending, residuals beyond `c` have zero influence.
///
/// `rho = c^2/6 (1 - (1 - (r/c)^2)^3)` for `|r| <= c`, `c^2/6` beyond;
/// weight `(1 - (r/c)^2)^2` inside and exactly `0` beyond, so unlike the other losses its
/// weight lies in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tukey {
    /// Rejection threshold `c` in sigmas (4.685 gives 95% efficiency on Gaussians).
    pub c: f64,
}

impl RobustLoss for Tukey {
    fn rho(&self, r: f64) -> f64 {
        let c2 = self.c * self.c;
        if r.abs() >= self.c {
            c2 / 6.0
        } else {
            let u = 1.0 - (r * r) / c2;
            c2 / 6.0 * (1.0 - u * u * u)
        }
    }
    fn psi(&self, r: f64) -> f64 {
        r * self.weight(r)
    }
    fn weight(&self, r: f64) -> f64 {
        if r.abs() >= self.c {
            0.0
        } else {
            let u = 1.0 - (r * r) / (self.c * self.c);
            u * u
        }
    }
    /// `(1 - q^2)(1 - 5 q^2)` inside, `q = r / c`; `0` beyond.
    fn psi_prime(&self, r: f64) -> f64 {
        if r.abs() >= self.c {
            0.0
        } else {
            let q2 = (r / self.c).powi(2);
            (1.0 - q2) * (1.0 - 5.0 * q2)
        }
    }
}

/// Student-t loss with `nu` degrees of freedom, the usual model of photometric residuals.
///
/// `rho = nu/2 ln(1 + r^2/nu)`, weight `nu / (nu + r^2)`. This is the negative log-likelihood
/// of a t distribution, rescaled by `nu / (nu + 1)` so that the weight is 1 at `r = 0`
/// (DVO uses `nu = 5`). As `nu -> inf` it becomes [`Squared`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudentT {
    /// Degrees of freedom `nu > 0`.
    pub nu: f64,
}

impl RobustLoss for StudentT {
    fn rho(&self, r: f64) -> f64 {
        0.5 * self.nu * (r * r / self.nu).ln_1p()
    }
    fn psi(&self, r: f64) -> f64 {
        r * self.weight(r)
    }
    fn weight(&self, r: f64) -> f64 {
        self.nu / (self.nu + r * r)
    }
    /// `nu (nu - r^2) / (nu + r^2)^2`.
    fn psi_prime(&self, r: f64) -> f64 {
        self.nu * (self.nu - r * r) / (self.nu + r * r).powi(2)
    }
}

/// A loss chosen at run time, for configuration structs.
///
/// The parameter of each variant is the one of the matching struct, in sigmas.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Loss {
    /// [`Squared`]: plain least squares.
    Squared,
    /// [`Huber`] with its `delta`.
    Huber(f64),
    /// [`Cauchy`] with its `c`.
    Cauchy(f64),
    /// [`Tukey`] with its `c`.
    Tukey(f64),
    /// [`StudentT`] with its degrees of freedom `nu`.
    StudentT(f64),
}

impl Default for Loss {
    /// Huber with `delta = 1.345` sigmas.
    fn default() -> Self {
        Loss::Huber(1.345)
    }
}

macro_rules! dispatch {
    ($self:ident, $method:ident, $r:ident) => {
        match *$self {
            Loss::Squared => Squared.$method($r),
            Loss::Huber(delta) => Huber { delta }.$method($r),
            Loss::Cauchy(c) => Cauchy { c }.$method($r),
            Loss::Tukey(c) => Tukey { c }.$method($r),
            Loss::StudentT(nu) => StudentT { nu }.$method($r),
        }
    };
}

impl RobustLoss for Loss {
    fn rho(&self, r: f64) -> f64 {
        dispatch!(self, rho, r)
    }
    fn psi(&self, r: f64) -> f64 {
        dispatch!(self, psi, r)
    }
    fn weight(&self, r: f64) -> f64 {
        dispatch!(self, weight, r)
    }
    fn psi_prime(&self, r: f64) -> f64 {
        dispatch!(self, psi_prime, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psi_prime_is_the_derivative_of_psi() {
        let h = 1e-6;
        for loss in [
            Loss::Squared,
            Loss::Huber(1.345),
            Loss::Cauchy(2.385),
            Loss::Tukey(4.685),
            Loss::StudentT(5.0),
        ] {
            // Away from the kinks of Huber (1.345) and Tukey (4.685).
            for r in [-6.0, -3.0, -1.0, -0.2, 0.0, 0.5, 1.2, 2.0, 4.0, 7.5] {
                let numeric = (loss.psi(r + h) - loss.psi(r - h)) / (2.0 * h);
                let exact = loss.psi_prime(r);
                assert!(
                    (numeric - exact).abs() < 1e-6,
                    "{loss:?} at {r}: {exact} vs {numeric}"
                );
            }
        }
    }
}
