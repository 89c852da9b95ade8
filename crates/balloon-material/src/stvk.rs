//! St. Venant-Kirchhoff material, Wang et al. 2015, Eq. 6, 7, 9.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::{Lame, Material, MaterialError};

/// St. Venant-Kirchhoff hyperelastic material (Wang et al. 2015, Eq. 6-9).
///
/// With the Green strain `E = (F^T F - I) / 2` (Eq. 7):
///
/// * energy density `psi(F) = mu E:E + lambda/2 tr(E)^2` (Eq. 6), in J/m^3;
/// * first Piola-Kirchhoff stress `P = F S`, `S = 2 mu E + lambda tr(E) I` (Eq. 9), in Pa;
/// * differential `dP = dF S + F dS` with `dE = sym(F^T dF)` and
///   `dS = 2 mu dE + lambda tr(dE) I` (the `P(F; dF)` of Eq. 11).
///
/// The model is defined for every `F`; it does not resist inversion (`psi` is finite at `J <= 0`
/// and vanishes at every `F` with `F^T F = I`, reflections included), so
/// [`Material::is_admissible`] is always `true`. Its small-strain limit is linear elasticity
/// with the same Lame parameters.
#[doc(alias = "StVK")]
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct StVenantKirchhoff {
    lame: Lame,
}

impl StVenantKirchhoff {
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

    /// Green strain `E` and second Piola-Kirchhoff stress `S` at `F`.
    #[inline]
    fn strain_stress(&self, f: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
        let mut e = f.tr_mul(f);
        e.m11 -= 1.0;
        e.m22 -= 1.0;
        e.m33 -= 1.0;
        e *= 0.5;
        let tr = e.trace();
        let mut s = e * (2.0 * self.lame.mu());
        let lt = self.lame.lambda() * tr;
        s.m11 += lt;
        s.m22 += lt;
        s.m33 += lt;
        (e, s)
    }

    /// `dP = dF S + F dS` given the second Piola stress `S` at `F`.
    #[inline]
    fn differential_with_stress(
        &self,
        f: &Matrix3<f64>,
        s: &Matrix3<f64>,
        df: &Matrix3<f64>,
    ) -> Matrix3<f64> {
        let ftdf = f.tr_mul(df);
        let de = (ftdf + ftdf.transpose()) * 0.5;
        let mut ds = de * (2.0 * self.lame.mu());
        let lt = self.lame.lambda() * de.trace();
        ds.m11 += lt;
        ds.m22 += lt;
        ds.m33 += lt;
        df * s + f * ds
    }
}

impl Material for StVenantKirchhoff {
    #[inline]
    fn energy_density(&self, f: &Matrix3<f64>) -> f64 {
        let (e, _) = self.strain_stress(f);
        let tr = e.trace();
        self.lame.mu() * e.norm_squared() + 0.5 * self.lame.lambda() * tr * tr
    }

    #[inline]
    fn first_piola(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        let (_, s) = self.strain_stress(f);
        f * s
    }

    #[inline]
    fn first_piola_differential(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        let (_, s) = self.strain_stress(f);
        self.differential_with_stress(f, &s, df)
    }

    #[inline]
    fn first_piola_differentials<const N: usize>(
        &self,
        f: &Matrix3<f64>,
        dfs: &[Matrix3<f64>; N],
    ) -> [Matrix3<f64>; N] {
        let (_, s) = self.strain_stress(f);
        std::array::from_fn(|k| self.differential_with_stress(f, &s, &dfs[k]))
    }

    #[inline]
    fn energy_and_piola(&self, f: &Matrix3<f64>) -> (f64, Matrix3<f64>) {
        let (e, s) = self.strain_stress(f);
        let tr = e.trace();
        let psi = self.lame.mu() * e.norm_squared() + 0.5 * self.lame.lambda() * tr * tr;
        (psi, f * s)
    }
}
