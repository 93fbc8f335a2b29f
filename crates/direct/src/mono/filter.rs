//! The depth filter of one point: a Gaussian belief `N(rho, var)` over its inverse depth
//! (1 / map units), fused with each epipolar measurement `N(rho_m, var_m)` (SVO's update
//! without the inlier ratio; outliers are gated instead):
//!
//! `rho' = (var_m rho + var rho_m) / (var + var_m)`, `var' = var var_m / (var + var_m)`.
//!
//! A measurement further than `gate` standard deviations of the difference,
//! `|rho_m - rho| > gate sqrt(var + var_m)`, is an outlier: counted, not fused.

/// Gaussian belief over one point's inverse depth, with its update and outlier counts.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DepthFilter {
    /// Mean inverse depth, 1 / map units.
    pub rho: f64,
    /// Variance of `rho`, (1 / map units)^2.
    pub var: f64,
    /// Measurements fused.
    pub updates: u32,
    /// Measurements rejected by the gate.
    pub outliers: u32,
}

impl DepthFilter {
    /// A belief `N(rho, var)` with no measurement yet.
    pub fn new(rho: f64, var: f64) -> Self {
        Self {
            rho,
            var,
            updates: 0,
            outliers: 0,
        }
    }

    /// Standard deviation of the inverse depth.
    pub fn sigma(&self) -> f64 {
        self.var.sqrt()
    }

    /// Fuses the measurement `N(rho_m, var_m)` (module documentation); returns false (and
    /// counts an outlier) when it fails the `gate` test or is not finite and positive-variance.
    pub fn update(&mut self, rho_m: f64, var_m: f64, gate: f64) -> bool {
        if !(rho_m.is_finite() && var_m.is_finite() && var_m > 0.0) {
            self.outliers += 1;
            return false;
        }
        let d = rho_m - self.rho;
        if d * d > gate * gate * (self.var + var_m) {
            self.outliers += 1;
            return false;
        }
        let s = self.var + var_m;
        self.rho = (var_m * self.rho + self.var * rho_m) / s;
        self.var = self.var * var_m / s;
        self.updates += 1;
        true
    }

    /// Converged: at least one measurement and `sigma <= relative rho + absolute`.
    pub fn converged(&self, relative: f64, absolute: f64) -> bool {
        self.updates > 0 && self.rho > 0.0 && self.sigma() <= relative * self.rho + absolute
    }

    /// The belief of the same point seen from another camera in which its depth is
    /// `Z' = c / rho + t_z` (`c = (R K^-1 x)_z`, `t_z` the translation's z):
    /// `rho' = rho / (c + rho t_z)`, its variance carried by `drho'/drho = c / (c + rho t_z)^2`.
    /// `None` when the point is not in front of the new camera.
    pub fn transferred(&self, c: f64, t_z: f64) -> Option<Self> {
        let den = c + self.rho * t_z;
        if den <= 0.0 || self.rho <= 0.0 {
            return None;
        }
        let jac = c / (den * den);
        Some(Self {
            rho: self.rho / den,
            var: self.var * jac * jac,
            ..*self
        })
    }
}

#[cfg(test)]
mod tests {
    use super::DepthFilter;

    /// Equal variances average the means and halve the variance.
    #[test]
    fn fusion_is_the_product_of_gaussians() {
        let mut f = DepthFilter::new(1.0, 0.04);
        assert!(f.update(1.2, 0.04, 3.0));
        assert!((f.rho - 1.1).abs() < 1e-12);
        assert!((f.var - 0.02).abs() < 1e-12);
        assert_eq!(f.updates, 1);
    }

    #[test]
    fn an_outlier_is_counted_not_fused() {
        let mut f = DepthFilter::new(1.0, 0.0001);
        assert!(!f.update(2.0, 0.0001, 3.0));
        assert_eq!((f.rho, f.outliers, f.updates), (1.0, 1, 0));
        assert!(!f.update(f64::NAN, 0.1, 3.0));
        assert_eq!(f.outliers, 2);
    }

    /// A point 4 units ahead, seen from a camera 1 unit further along z, is 3 units away.
    #[test]
    fn transfer_moves_the_inverse_depth_with_the_camera() {
        let f = DepthFilter::new(0.25, 1e-4);
        let g = f.transferred(1.0, -1.0).unwrap();
        assert!((g.rho - 1.0 / 3.0).abs() < 1e-12);
        // drho'/drho = 1 / (1 - 0.25)^2.
        assert!((g.var - 1e-4 / 0.75f64.powi(4)).abs() < 1e-15);
        assert!(f.transferred(1.0, -5.0).is_none());
    }
}
