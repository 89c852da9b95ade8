//! Incompressible Ogden membrane with N terms.

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};

use super::{MembraneMaterial, NAN2, ddot, det_inv_tr};
use crate::MaterialError;

/// Incompressible Ogden membrane with `N` terms (Ogden 1972, Proc. R. Soc. Lond. A 326:565;
/// `docs/membranes.md` Eq. M13-M17):
///
/// `W = sum_p mu_p / alpha_p (l1^alpha_p + l2^alpha_p + l3^alpha_p - 3)`, `l3 = 1/(l1 l2)`,
///
/// with `l1^2, l2^2` the eigenvalues `c1, c2` of `C`. Split as `W = phi(c1) + phi(c2) +
/// psi(det C) - const` with `phi(c) = sum_p mu_p/alpha_p c^(alpha_p/2)` and
/// `psi(d) = sum_p mu_p/alpha_p d^(-alpha_p/2)`:
///
/// * `S = 2 [Q diag(phi'(c_i)) Q^T + psi'(d) d C^-1]` (`Q` the eigenvectors of `C`);
/// * `dS = 2 [Q (G o (Q^T dC Q)) Q^T + (g'(d) d (C^-1 : dC)) C^-1 - g(d) C^-1 dC C^-1]` with
///   `g = psi' d`, `G_ii = phi''(c_i)` and `G_12 = (phi'(c1) - phi'(c2)) / (c1 - c2)` (the
///   Daleckii-Krein divided difference).
///
/// Where the principal stretches coincide (equibiaxial stretch, the rest state) the divided
/// difference is evaluated as `m^(k-1) sinh(k u) / sinh(u)` with `m = sqrt(c1 c2)`,
/// `u = ln(c1/c2)/2` and a series for small `u`, so stress and tangent are smooth there (the
/// choice of eigenvectors does not matter at a double eigenvalue).
///
/// Initial shear modulus `mu0 = sum_p mu_p alpha_p / 2`, which must be positive. `N = 1`,
/// `alpha = 2` is the neo-Hookean model with `mu = mu_1`. Parameters: `mu_p` (Pa) and `alpha_p`
/// (dimensionless, non-zero), lists of the same length `N >= 1`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawOgden")]
pub struct MembraneOgden {
    mu: Vec<f64>,
    alpha: Vec<f64>,
}

#[derive(Deserialize)]
struct RawOgden {
    mu: Vec<f64>,
    alpha: Vec<f64>,
}

impl TryFrom<RawOgden> for MembraneOgden {
    type Error = MaterialError;
    fn try_from(r: RawOgden) -> Result<Self, MaterialError> {
        Self::try_new(r.mu, r.alpha)
    }
}

/// `(a^k - b^k) / (a - b)` for `a, b > 0`, accurate when `a` and `b` are close (then it tends
/// to `k a^(k-1)`).
#[inline]
fn power_divided_difference(a: f64, b: f64, k: f64) -> f64 {
    let m = (a * b).sqrt();
    let u = 0.5 * (a / b).ln();
    let ratio = if u.abs() < 1e-4 {
        // sinh(k u)/sinh(u) = k (1 + (k^2-1) u^2/6 + (k^2-1)(3k^2-7) u^4/360 + O(u^6)).
        let u2 = u * u;
        k * (1.0 + (k * k - 1.0) * u2 / 6.0 * (1.0 + (3.0 * k * k - 7.0) * u2 / 60.0))
    } else {
        (k * u).sinh() / u.sinh()
    };
    m.powf(k - 1.0) * ratio
}

impl MembraneOgden {
    /// The model with moduli `mu` (Pa) and exponents `alpha`, one per term.
    ///
    /// # Errors
    /// * [`MaterialError::OgdenTermMismatch`] if the lists differ in length or are empty;
    /// * [`MaterialError::InvalidParameter`] naming `ogden_mu` / `ogden_alpha` for a non-finite
    ///   value or a zero exponent, or naming `ogden_initial_shear_modulus` unless
    ///   `sum mu_p alpha_p / 2 > 0`.
    pub fn try_new(mu: Vec<f64>, alpha: Vec<f64>) -> Result<Self, MaterialError> {
        if mu.len() != alpha.len() || mu.is_empty() {
            return Err(MaterialError::OgdenTermMismatch {
                mu_terms: mu.len(),
                alpha_terms: alpha.len(),
            });
        }
        if let Some(&v) = mu.iter().find(|v| !v.is_finite()) {
            return Err(MaterialError::InvalidParameter {
                name: "ogden_mu",
                value: v,
                allowed: "finite",
            });
        }
        if let Some(&v) = alpha.iter().find(|v| !(v.is_finite() && **v != 0.0)) {
            return Err(MaterialError::InvalidParameter {
                name: "ogden_alpha",
                value: v,
                allowed: "finite and non-zero",
            });
        }
        let mu0 = 0.5 * mu.iter().zip(&alpha).map(|(m, a)| m * a).sum::<f64>();
        if mu0.is_nan() || mu0 <= 0.0 {
            return Err(MaterialError::InvalidParameter {
                name: "ogden_initial_shear_modulus",
                value: mu0,
                allowed: "sum mu_p alpha_p / 2 > 0",
            });
        }
        Ok(Self { mu, alpha })
    }

    /// Builds the model without checks, for the published presets (tested to pass `try_new`).
    pub(crate) fn preset_unchecked(mu: Vec<f64>, alpha: Vec<f64>) -> Self {
        Self { mu, alpha }
    }

    /// The moduli `mu_p` (Pa).
    pub fn mu(&self) -> &[f64] {
        &self.mu
    }

    /// The exponents `alpha_p` (dimensionless).
    pub fn alpha(&self) -> &[f64] {
        &self.alpha
    }

    #[inline]
    fn terms(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.mu.iter().copied().zip(self.alpha.iter().copied())
    }

    /// `phi(c) = sum mu/alpha c^(alpha/2)`.
    #[inline]
    fn phi(&self, c: f64) -> f64 {
        self.terms().map(|(m, a)| m / a * c.powf(0.5 * a)).sum()
    }

    /// `phi'(c) = sum mu/2 c^(alpha/2 - 1)`.
    #[inline]
    fn dphi(&self, c: f64) -> f64 {
        self.terms()
            .map(|(m, a)| 0.5 * m * c.powf(0.5 * a - 1.0))
            .sum()
    }

    /// `(phi'(a) - phi'(b)) / (a - b)`, `phi''(a)` when `a == b`.
    #[inline]
    fn dphi_divided(&self, a: f64, b: f64) -> f64 {
        self.terms()
            .map(|(m, al)| 0.5 * m * power_divided_difference(a, b, 0.5 * al - 1.0))
            .sum()
    }

    /// `psi(d) - sum 3 mu/alpha` with `psi(d) = sum mu/alpha d^(-alpha/2)`.
    #[inline]
    fn psi_minus_rest(&self, d: f64) -> f64 {
        self.terms()
            .map(|(m, a)| m / a * (d.powf(-0.5 * a) - 3.0))
            .sum()
    }

    /// `g(d) = psi'(d) d = -sum mu/2 d^(-alpha/2)`.
    #[inline]
    fn g(&self, d: f64) -> f64 {
        -self
            .terms()
            .map(|(m, a)| 0.5 * m * d.powf(-0.5 * a))
            .sum::<f64>()
    }

    /// `g'(d) = sum mu alpha/4 d^(-alpha/2 - 1)`.
    #[inline]
    fn dg(&self, d: f64) -> f64 {
        self.terms()
            .map(|(m, a)| 0.25 * m * a * d.powf(-0.5 * a - 1.0))
            .sum()
    }
}

/// Eigenvalues (ascending order not guaranteed) and orthonormal eigenvectors (columns) of a
/// symmetric positive definite 2x2 matrix.
#[inline]
fn eigen(c: &Matrix2<f64>) -> ([f64; 2], Matrix2<f64>) {
    let (a, b, d) = (c[(0, 0)], 0.5 * (c[(0, 1)] + c[(1, 0)]), c[(1, 1)]);
    let half_diff = 0.5 * (a - d);
    let r = half_diff.hypot(b);
    let mean = 0.5 * (a + d);
    // Larger eigenvalue first, computed without cancellation; the smaller from the determinant.
    let l1 = mean + r;
    let l2 = if l1 > 0.0 {
        (a * d - b * b) / l1
    } else {
        mean - r
    };
    if r == 0.0 {
        return ([l1, l2], Matrix2::identity());
    }
    // Eigenvector of l1: rotation angle theta with tan(2 theta) = 2b / (a - d).
    let theta = 0.5 * b.atan2(half_diff);
    let (s, co) = theta.sin_cos();
    ([l1, l2], Matrix2::new(co, -s, s, co))
}

impl MembraneMaterial for MembraneOgden {
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        self.energy_and_stress(c).0
    }

    fn stress(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        self.energy_and_stress(c).1
    }

    fn energy_and_stress(&self, c: &Matrix2<f64>) -> (f64, Matrix2<f64>) {
        let Some((det, cinv, _)) = det_inv_tr(c) else {
            return (f64::INFINITY, NAN2);
        };
        let ([c1, c2], q) = eigen(c);
        if !(c1 > 0.0 && c2 > 0.0) {
            return (f64::INFINITY, NAN2);
        }
        let w = self.phi(c1) + self.phi(c2) + self.psi_minus_rest(det);
        let diag = Matrix2::new(self.dphi(c1), 0.0, 0.0, self.dphi(c2));
        let s = (q * diag * q.transpose() + cinv * self.g(det)) * 2.0;
        (w, s)
    }

    fn stress_differential(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        let Some((det, cinv, _)) = det_inv_tr(c) else {
            return NAN2;
        };
        let ([c1, c2], q) = eigen(c);
        if !(c1 > 0.0 && c2 > 0.0) {
            return NAN2;
        }
        let mut h = q.transpose() * dc * q;
        h[(0, 0)] *= self.dphi_divided(c1, c1);
        h[(1, 1)] *= self.dphi_divided(c2, c2);
        let off = self.dphi_divided(c1, c2);
        h[(0, 1)] *= off;
        h[(1, 0)] *= off;
        let tau = ddot(&cinv, dc);
        (q * h * q.transpose() + cinv * (self.dg(det) * det * tau) - cinv * dc * cinv * self.g(det))
            * 2.0
    }

    fn initial_shear_modulus(&self) -> f64 {
        0.5 * self.terms().map(|(m, a)| m * a).sum::<f64>()
    }

    fn is_admissible(&self, c: &Matrix2<f64>) -> bool {
        det_inv_tr(c).is_some() && {
            let ([c1, c2], _) = eigen(c);
            c1 > 0.0 && c2 > 0.0
        }
    }
}
