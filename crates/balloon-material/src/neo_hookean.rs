//! Compressible neo-Hookean material.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::{Lame, Material, MaterialError};

/// Compressible neo-Hookean material (Bonet and Wood, *Nonlinear Continuum Mechanics for Finite
/// Element Analysis*, Eq. 6.27), an alternative to the St. Venant-Kirchhoff law of Wang et al. 2015, Eq. 6
/// that resists compression and inversion.
///
/// With `J = det F` and `I1 = tr(F^T F)`:
///
/// * `psi(F) = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2` (J/m^3);
/// * `P(F) = mu (F - F^-T) + lambda ln(J) F^-T` (Pa);
/// * `dP = mu dF + (mu - lambda ln J) F^-T dF^T F^-T + lambda tr(F^-1 dF) F^-T`.
///
/// Behaviour near and beyond inversion: as `J -> 0+` the energy tends to `+infinity` (the `-mu ln J`
/// and `(ln J)^2` terms). For `J <= 0` (or a non-finite `F`) the model is undefined:
/// [`Material::energy_density`] returns `f64::INFINITY`, so an energy-based line search rejects the
/// state, while [`Material::first_piola`] and [`Material::first_piola_differential`] return a matrix
/// filled with `f64::NAN`, which a solver's NaN check reports. Call
/// [`Material::is_admissible`] (`J > 0` and finite) to test a state before using the stress.
/// Its small-strain limit is linear elasticity with the same Lame parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct NeoHookean {
    lame: Lame,
}

impl NeoHookean {
    /// The material with the given Lame parameters.
    pub fn new(lame: Lame) -> Self {
        Self { lame }
    }

    /// The material from Young's modulus (Pa) and Poisson's ratio.
    ///
    /// # Errors
    /// See [`Lame::try_from_young_poisson`].
    pub fn try_from_young_poisson(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        Lame::try_from_young_poisson(young, poisson).map(Self::new)
    }

    /// The Lame parameters.
    pub fn lame(&self) -> Lame {
        self.lame
    }

    /// `(ln J, F^-T)` when `J > 0` and everything is finite.
    #[inline]
    fn log_j_inv_t(f: &Matrix3<f64>) -> Option<(f64, Matrix3<f64>)> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let inv = f.try_inverse()?;
        let lnj = j.ln();
        let inv_t = inv.transpose();
        inv_t.iter().all(|v| v.is_finite()).then_some((lnj, inv_t))
    }

    /// `dP` given `ln J` and `F^-T`; `tr(F^-1 dF) = F^-T : dF`.
    #[inline]
    fn differential_with(&self, lnj: f64, fit: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        let (mu, lambda) = (self.lame.mu(), self.lame.lambda());
        let tr = fit.dot(df);
        df * mu + fit * df.transpose() * fit * (mu - lambda * lnj) + fit * (lambda * tr)
    }
}

impl Material for NeoHookean {
    #[inline]
    fn energy_density(&self, f: &Matrix3<f64>) -> f64 {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return f64::INFINITY;
        }
        let lnj = j.ln();
        let (mu, lambda) = (self.lame.mu(), self.lame.lambda());
        0.5 * mu * (f.norm_squared() - 3.0) - mu * lnj + 0.5 * lambda * lnj * lnj
    }

    #[inline]
    fn first_piola(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        match Self::log_j_inv_t(f) {
            Some((lnj, fit)) => {
                let (mu, lambda) = (self.lame.mu(), self.lame.lambda());
                (f - fit) * mu + fit * (lambda * lnj)
            }
            None => Matrix3::from_element(f64::NAN),
        }
    }

    #[inline]
    fn first_piola_differential(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        match Self::log_j_inv_t(f) {
            Some((lnj, fit)) => self.differential_with(lnj, &fit, df),
            None => Matrix3::from_element(f64::NAN),
        }
    }

    #[inline]
    fn first_piola_differentials<const N: usize>(
        &self,
        f: &Matrix3<f64>,
        dfs: &[Matrix3<f64>; N],
    ) -> [Matrix3<f64>; N] {
        match Self::log_j_inv_t(f) {
            Some((lnj, fit)) => std::array::from_fn(|k| self.differential_with(lnj, &fit, &dfs[k])),
            None => [Matrix3::from_element(f64::NAN); N],
        }
    }

    #[inline]
    fn energy_and_piola(&self, f: &Matrix3<f64>) -> (f64, Matrix3<f64>) {
        match Self::log_j_inv_t(f) {
            Some((lnj, fit)) => {
                let (mu, lambda) = (self.lame.mu(), self.lame.lambda());
                let psi = 0.5 * mu * (f.norm_squared() - 3.0) - mu * lnj + 0.5 * lambda * lnj * lnj;
                (psi, (f - fit) * mu + fit * (lambda * lnj))
            }
            None => (f64::INFINITY, Matrix3::from_element(f64::NAN)),
        }
    }

    #[inline]
    fn is_admissible(&self, f: &Matrix3<f64>) -> bool {
        Self::log_j_inv_t(f).is_some()
    }
}
