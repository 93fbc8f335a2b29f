//! Camera models: pinhole intrinsics with one of two lens models.
//!
//! Frames and units: a point `P = (X, Y, Z)` in the camera frame (metres, `Z` forward, `X`
//! right, `Y` down) projects to normalized coordinates `x_n = (X/Z, Y/Z)`, which the lens
//! distorts to `x_d = D(x_n)`, and the intrinsics map to pixels `u = fx x_d + cx`,
//! `v = fy y_d + cy` (pixel centers at integer coordinates, `(0, 0)` the top-left pixel).
//!
//! The lens `D` is a [`Lens`]: radial-tangential ([`Distortion`], Brown-Conrady, OpenCV
//! `k1 k2 p1 p2 k3`) or Kannala-Brandt equidistant ([`KannalaBrandt`], OpenCV `fisheye`,
//! Kalibr `equidistant`). Callers go through [`Camera`] and never look at the model.
//!
//! Radial-tangential, with `r^2 = x^2 + y^2`:
//! `x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)`,
//! `y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y`.
//! Kannala-Brandt: see [`kannala_brandt`]. Every model works on rays in front of the camera
//! (`Z > 0`, less than 90 degrees off the axis), the domain of normalized coordinates.

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Unit, Vector2, Vector3};
use thiserror::Error;

pub mod kannala_brandt;
pub use kannala_brandt::KannalaBrandt;

/// Invalid camera parameters.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum CameraError {
    /// A focal length is zero, negative or not finite.
    #[error("focal lengths must be positive and finite, got fx = {fx}, fy = {fy}")]
    BadFocalLength {
        /// Horizontal focal length in pixels.
        fx: f64,
        /// Vertical focal length in pixels.
        fy: f64,
    },
    /// The principal point or a distortion coefficient is not finite.
    #[error("camera parameters must be finite")]
    NotFinite,
}

/// Pinhole intrinsics in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point `u`, pixels.
    pub cx: f64,
    /// Principal point `v`, pixels.
    pub cy: f64,
}

impl Pinhole {
    /// Checked constructor: focal lengths must be positive, everything finite.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self, CameraError> {
        let p = Self { fx, fy, cx, cy };
        p.validate()?;
        Ok(p)
    }

    /// Checks the invariants of [`Pinhole::new`] for a value built from public fields.
    pub fn validate(&self) -> Result<(), CameraError> {
        if !(self.fx > 0.0 && self.fy > 0.0 && self.fx.is_finite() && self.fy.is_finite()) {
            return Err(CameraError::BadFocalLength {
                fx: self.fx,
                fy: self.fy,
            });
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        Ok(())
    }

    /// The matrix `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Pixel of the (already distorted, or distortion-free) normalized point `x`.
    #[inline]
    pub fn to_pixel(&self, x: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new(self.fx * x.x + self.cx, self.fy * x.y + self.cy)
    }

    /// Normalized coordinates of pixel `u` (inverse of [`Pinhole::to_pixel`]).
    #[inline]
    pub fn to_normalized(&self, u: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new((u.x - self.cx) / self.fx, (u.y - self.cy) / self.fy)
    }

    /// Pixel of a camera-frame point, `None` when it is not in front (`Z <= 0`).
    #[inline]
    pub fn project(&self, p: &Vector3<f64>) -> Option<Vector2<f64>> {
        (p.z > 0.0).then(|| self.to_pixel(&Vector2::new(p.x / p.z, p.y / p.z)))
    }

    /// The camera-frame point at depth `z` (metres along the optical axis) seen at pixel `u`.
    #[inline]
    pub fn back_project(&self, u: &Vector2<f64>, z: f64) -> Vector3<f64> {
        let x = self.to_normalized(u);
        Vector3::new(x.x * z, x.y * z, z)
    }
}

/// Radial-tangential distortion coefficients (OpenCV order `k1, k2, p1, p2, k3`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Radial `r^2` coefficient.
    pub k1: f64,
    /// Radial `r^4` coefficient.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial `r^6` coefficient.
    pub k3: f64,
}

impl Distortion {
    /// From the OpenCV order `[k1, k2, p1, p2, k3]`.
    pub fn from_array(d: [f64; 5]) -> Self {
        Self {
            k1: d[0],
            k2: d[1],
            p1: d[2],
            p2: d[3],
            k3: d[4],
        }
    }

    /// True when every coefficient is zero (distortion is the identity).
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }

    /// Distorts normalized coordinates, `x_d = D(x_n)` (see the module documentation).
    #[inline]
    pub fn distort(&self, x: &Vector2<f64>) -> Vector2<f64> {
        let (a, b) = (x.x, x.y);
        let r2 = a * a + b * b;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        Vector2::new(
            a * radial + 2.0 * self.p1 * a * b + self.p2 * (r2 + 2.0 * a * a),
            b * radial + self.p1 * (r2 + 2.0 * b * b) + 2.0 * self.p2 * a * b,
        )
    }

    /// Jacobian `d x_d / d x_n` of [`Distortion::distort`].
    pub fn distort_jacobian(&self, x: &Vector2<f64>) -> Matrix2<f64> {
        let (a, b) = (x.x, x.y);
        let r2 = a * a + b * b;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r2
        let dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        Matrix2::new(
            radial + 2.0 * a * a * dradial + 2.0 * self.p1 * b + 6.0 * self.p2 * a,
            2.0 * a * b * dradial + 2.0 * self.p1 * a + 2.0 * self.p2 * b,
            2.0 * a * b * dradial + 2.0 * self.p1 * a + 2.0 * self.p2 * b,
            radial + 2.0 * b * b * dradial + 6.0 * self.p1 * b + 2.0 * self.p2 * a,
        )
    }

    /// Inverts [`Distortion::distort`] by Newton iterations from `x_n = x_d`.
    ///
    /// Returns `None` when the iteration does not reach `1e-12` (a point outside the region
    /// where the distortion polynomial is invertible).
    pub fn undistort(&self, xd: &Vector2<f64>) -> Option<Vector2<f64>> {
        if self.is_identity() {
            return Some(*xd);
        }
        let mut x = *xd;
        for _ in 0..30 {
            let err = self.distort(&x) - xd;
            if err.norm_squared() < 1e-24 {
                return Some(x);
            }
            let step = self.distort_jacobian(&x).try_inverse()? * err;
            x -= step;
            if !x.iter().all(|v| v.is_finite()) {
                return None;
            }
        }
        ((self.distort(&x) - xd).norm() < 1e-9).then_some(x)
    }
}

/// The lens model of a [`Camera`]: how normalized coordinates bend, `x_d = D(x_n)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lens {
    /// Radial-tangential (Brown-Conrady) distortion; all zero = an ideal pinhole.
    RadialTangential(Distortion),
    /// Kannala-Brandt equidistant fisheye.
    KannalaBrandt(KannalaBrandt),
}

impl Default for Lens {
    /// No distortion (radial-tangential with every coefficient zero).
    fn default() -> Self {
        Self::RadialTangential(Distortion::default())
    }
}

impl From<Distortion> for Lens {
    fn from(d: Distortion) -> Self {
        Self::RadialTangential(d)
    }
}

impl From<KannalaBrandt> for Lens {
    fn from(k: KannalaBrandt) -> Self {
        Self::KannalaBrandt(k)
    }
}

impl Lens {
    /// The model's name as calibration files spell it: `radial-tangential` or `equidistant`.
    pub fn model_name(&self) -> &'static str {
        match self {
            Self::RadialTangential(_) => "radial-tangential",
            Self::KannalaBrandt(_) => "equidistant",
        }
    }

    /// The coefficients in the model's order: `[k1, k2, p1, p2, k3]` or `[k1, k2, k3, k4]`.
    pub fn coefficients(&self) -> Vec<f64> {
        match self {
            Self::RadialTangential(d) => vec![d.k1, d.k2, d.p1, d.p2, d.k3],
            Self::KannalaBrandt(k) => k.coefficients().to_vec(),
        }
    }

    /// The radial-tangential coefficients, `None` for another model.
    pub fn radial_tangential(&self) -> Option<&Distortion> {
        match self {
            Self::RadialTangential(d) => Some(d),
            Self::KannalaBrandt(_) => None,
        }
    }

    /// True when the lens is an ideal pinhole (radial-tangential with every coefficient zero;
    /// an equidistant lens never is: `theta_d = theta` is not `tan theta`).
    pub fn is_identity(&self) -> bool {
        self.radial_tangential()
            .is_some_and(Distortion::is_identity)
    }

    /// True when the ray of normalized point `x_n` is inside the model's validity range
    /// (always for radial-tangential, `theta < theta_max` for Kannala-Brandt).
    #[inline]
    pub fn contains(&self, x: &Vector2<f64>) -> bool {
        match self {
            Self::RadialTangential(_) => true,
            Self::KannalaBrandt(k) => k.contains(x),
        }
    }

    /// Distorted normalized coordinates `x_d = D(x_n)`.
    #[inline]
    pub fn distort(&self, x: &Vector2<f64>) -> Vector2<f64> {
        match self {
            Self::RadialTangential(d) => d.distort(x),
            Self::KannalaBrandt(k) => k.distort(x),
        }
    }

    /// Jacobian `d x_d / d x_n` of [`Lens::distort`].
    #[inline]
    pub fn distort_jacobian(&self, x: &Vector2<f64>) -> Matrix2<f64> {
        match self {
            Self::RadialTangential(d) => d.distort_jacobian(x),
            Self::KannalaBrandt(k) => k.distort_jacobian(x),
        }
    }

    /// Inverse of [`Lens::distort`], `None` outside the model's validity range or when the
    /// iteration does not converge.
    pub fn undistort(&self, xd: &Vector2<f64>) -> Option<Vector2<f64>> {
        match self {
            Self::RadialTangential(d) => d.undistort(xd),
            Self::KannalaBrandt(k) => k.undistort(xd),
        }
    }

    /// [`CameraError::NotFinite`] when a coefficient is not finite.
    pub fn validate(&self) -> Result<(), CameraError> {
        if self.coefficients().iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(CameraError::NotFinite)
        }
    }
}

/// A calibrated camera: pinhole intrinsics plus a lens model ([`Lens`]).
///
/// ```
/// use nalgebra::{Vector2, Vector3};
/// use vofront_core::camera::{Camera, Distortion, Pinhole};
/// let cam = Camera::new(
///     Pinhole::new(517.3, 516.5, 318.6, 255.3).unwrap(),
///     Distortion::from_array([0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
/// );
/// let p = Vector3::new(0.3, -0.2, 2.0);
/// let px = cam.project(&p).unwrap();
/// let ray = cam.bearing(&px).unwrap();
/// assert!((ray.into_inner() - p.normalize()).norm() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics.
    pub pinhole: Pinhole,
    /// Lens model and its coefficients (no distortion by default).
    pub distortion: Lens,
}

impl Camera {
    /// A camera from intrinsics and a lens ([`Distortion`], [`KannalaBrandt`] or [`Lens`]).
    pub fn new(pinhole: Pinhole, distortion: impl Into<Lens>) -> Self {
        Self {
            pinhole,
            distortion: distortion.into(),
        }
    }

    /// A distortion-free camera.
    pub fn pinhole(pinhole: Pinhole) -> Self {
        Self {
            pinhole,
            distortion: Lens::default(),
        }
    }

    /// Checks intrinsics and distortion for the invariants of [`Pinhole::new`].
    pub fn validate(&self) -> Result<(), CameraError> {
        self.pinhole.validate()?;
        self.distortion.validate()
    }

    /// Normalized coordinates `x_n = (X/Z, Y/Z)` of a camera-frame point, `None` behind the
    /// camera or outside the lens's validity range.
    #[inline]
    fn normalized(&self, p: &Vector3<f64>) -> Option<Vector2<f64>> {
        if p.z <= 0.0 {
            return None;
        }
        let xn = Vector2::new(p.x / p.z, p.y / p.z);
        self.distortion.contains(&xn).then_some(xn)
    }

    /// Pixel of a camera-frame point through the lens, `None` behind the camera or outside
    /// the lens's validity range.
    pub fn project(&self, p: &Vector3<f64>) -> Option<Vector2<f64>> {
        self.normalized(p).map(|xn| self.normalized_to_pixel(&xn))
    }

    /// Pixel `u = K D(x_n)` of a camera-frame point `P` (metres) through the lens, and its
    /// Jacobian `du/dP` (2 x 3, pixels per metre):
    /// `du/dP = diag(fx, fy) (d x_d / d x_n) [[1/Z, 0, -X/Z^2], [0, 1/Z, -Y/Z^2]]`.
    /// `None` where [`Camera::project`] is: behind the camera (`Z <= 0`) or outside the lens's
    /// validity range.
    ///
    /// The one projection Jacobian of vofront: PnP, bundle adjustment and the monocular map's
    /// point refinement all linearise through it.
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use vofront_core::camera::{Camera, Pinhole};
    /// let cam = Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap());
    /// let (px, j) = cam.project_with_jacobian(&Vector3::new(1.0, 0.0, 2.0)).unwrap();
    /// assert_eq!(px.x, 570.0);
    /// // du/dX = fx / Z, du/dZ = -fx X / Z^2.
    /// assert_eq!((j[(0, 0)], j[(0, 2)]), (250.0, -125.0));
    /// assert!(cam.project_with_jacobian(&Vector3::new(1.0, 0.0, -2.0)).is_none());
    /// ```
    #[inline]
    pub fn project_with_jacobian(
        &self,
        p: &Vector3<f64>,
    ) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
        if p.z <= 0.0 {
            return None;
        }
        let iz = 1.0 / p.z;
        let xn = Vector2::new(p.x * iz, p.y * iz);
        if !self.distortion.contains(&xn) {
            return None;
        }
        let dxn = Matrix2x3::new(iz, 0.0, -xn.x * iz, 0.0, iz, -xn.y * iz);
        let k = Matrix2::new(self.pinhole.fx, 0.0, 0.0, self.pinhole.fy);
        let jacobian = k * self.distortion.distort_jacobian(&xn) * dxn;
        Some((self.normalized_to_pixel(&xn), jacobian))
    }

    /// The Jacobian `du/dP` of [`Camera::project_with_jacobian`] alone (2 x 3, pixels per
    /// metre); `None` where [`Camera::project`] is.
    pub fn project_jacobian(&self, p: &Vector3<f64>) -> Option<Matrix2x3<f64>> {
        self.project_with_jacobian(p).map(|(_, j)| j)
    }

    /// Undistorted normalized coordinates `x_n` of an observed pixel.
    pub fn pixel_to_normalized(&self, u: &Vector2<f64>) -> Option<Vector2<f64>> {
        self.distortion.undistort(&self.pinhole.to_normalized(u))
    }

    /// Observed pixel of undistorted normalized coordinates `x_n`.
    pub fn normalized_to_pixel(&self, x: &Vector2<f64>) -> Vector2<f64> {
        self.pinhole.to_pixel(&self.distortion.distort(x))
    }

    /// Unit ray `(x_n, 1) / |(x_n, 1)|` in the camera frame through an observed pixel.
    pub fn bearing(&self, u: &Vector2<f64>) -> Option<Unit<Vector3<f64>>> {
        self.pixel_to_normalized(u)
            .map(|x| Unit::new_normalize(Vector3::new(x.x, x.y, 1.0)))
    }
}

#[cfg(test)]
mod tests;
