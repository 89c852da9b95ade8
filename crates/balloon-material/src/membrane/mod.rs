//! Incompressible hyperelastic membranes: energy densities of the in-plane right Cauchy-Green
//! tensor `C` (2x2) with the thickness following incompressibility exactly (plane stress).
//!
//! A thin sheet of rubber is incompressible, so the through-thickness stretch is not free:
//! `l3 = 1 / (l1 l2)`, the current thickness is `h = H / (l1 l2) = H / sqrt(det C)`, and the
//! through-thickness stress vanishes (plane stress). Eliminating the pressure of the 3D
//! incompressible model with these two conditions gives an energy of the 2x2 tensor alone,
//!
//! `W(C) = W3(C3)`, `C3 = diag(C, 1 / det C)`,
//!
//! whose derivative `S = 2 dW/dC` is the in-plane second Piola-Kirchhoff stress of the membrane
//! (the pressure term is already contained in the `1 / det C` entry). The invariants of `C3` are
//!
//! * `I1 = tr C + 1 / det C`,
//! * `I2 = det C + tr C / det C`,
//! * `I3 = 1`.
//!
//! | type | energy `W` (J/m^3 per unit rest volume) | parameters |
//! |---|---|---|
//! | [`MembraneNeoHookean`] | `mu/2 (I1 - 3)` | `mu` (Pa) |
//! | [`MembraneMooneyRivlin`] | `c1 (I1 - 3) + c2 (I2 - 3)` | `c1`, `c2` (Pa) |
//! | [`MembraneGent`] | `-mu jm/2 ln(1 - (I1 - 3)/jm)` | `mu` (Pa), `jm` (-) |
//! | [`MembraneOgden`] | `sum_p mu_p/alpha_p (l1^a_p + l2^a_p + l3^a_p - 3)` | `mu_p` (Pa), `alpha_p` (-) |
//! | [`MembraneYeoh`] | `c1 (I1-3) + c2 (I1-3)^2 + c3 (I1-3)^3` | `c1, c2, c3` (Pa) |
//! | [`MembraneModel`] | closed serde enum over the above, `FromStr` names `membrane-*` | |
//! | [`MembranePreset`] | published fits (natural rubber, a silicone) with their sources | |
//! | [`ThinSphere`] | the analytic inflated thin sphere `P(l)` and its extrema | |
//!
//! The derivation, equation by equation, is in `docs/membranes.md`. These models replace the
//! St. Venant-Kirchhoff law of Wang et al. 2015 (Eq. 6-9) for a shell that must show the pressure
//! maximum of a real balloon; the element that uses them is `balloon_element::HyperMembrane`.
//!
//! ```
//! use balloon_material::membrane::{MembraneMaterial, MembraneNeoHookean, ThinSphere};
//! use nalgebra::Matrix2;
//!
//! let rubber = MembraneNeoHookean::try_new(4.0e5)?;
//! // No energy and no stress at rest.
//! assert_eq!(rubber.energy(&Matrix2::identity()), 0.0);
//! assert!(rubber.stress(&Matrix2::identity()).norm() < 1e-9);
//! // The inflated sphere has its pressure maximum at l = 7^(1/6).
//! let sphere = ThinSphere::try_new(0.1, 1.0e-3)?;
//! let peaks = sphere.extrema(&rubber, 5.0)?;
//! assert!((peaks[0].stretch - 7f64.powf(1.0 / 6.0)).abs() < 1e-9);
//! # Ok::<(), balloon_material::MaterialError>(())
//! ```

mod invariant;
mod model;
mod ogden;
mod sphere;

#[cfg(test)]
mod tests;

pub use invariant::{MembraneGent, MembraneMooneyRivlin, MembraneNeoHookean, MembraneYeoh};
pub use model::{MembraneKind, MembraneModel, MembranePreset};
pub use ogden::MembraneOgden;
pub use sphere::{ExtremumKind, PressureExtremum, ThinSphere};

use nalgebra::{Matrix2, Matrix3};

/// An incompressible hyperelastic membrane: energy density `W(C)` of the 2x2 in-plane right
/// Cauchy-Green tensor `C = Fm^T Fm` (in an orthonormal frame of the rest plane), with the
/// thickness following incompressibility exactly (`h = H / sqrt(det C)`, plane stress).
///
/// Units: `W` in J/m^3 per unit **rest** volume, stresses in Pa. `C` is dimensionless,
/// symmetric and positive definite in every admissible state.
///
/// Implementors keep [`MembraneMaterial::stress`] the exact derivative `2 dW/dC` of
/// [`MembraneMaterial::energy`] and [`MembraneMaterial::stress_differential`] the exact
/// directional derivative of the stress; the crate's finite-difference tests check it for every
/// model, and the element and Newton solver rely on it (Wang et al. 2015, Eq. 8, 11).
///
/// Outside the admissible set ([`MembraneMaterial::is_admissible`]: `det C > 0`, finite, and a
/// model-specific limit such as Gent's `I1 - 3 < jm`) the energy is `+infinity` and the stresses
/// are filled with NaN, so an energy-based line search rejects the state and a NaN check reports
/// it.
pub trait MembraneMaterial: Clone + Send + Sync + std::fmt::Debug {
    /// Energy density `W(C)` (J/m^3 per unit rest volume).
    fn energy(&self, c: &Matrix2<f64>) -> f64;

    /// In-plane second Piola-Kirchhoff stress `S = 2 dW/dC` (Pa), symmetric.
    fn stress(&self, c: &Matrix2<f64>) -> Matrix2<f64>;

    /// Directional derivative `dS = (dS/dC) : dC` of the stress at `C` along a symmetric `dC`
    /// (Pa per unit of `dC`).
    fn stress_differential(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64>;

    /// `(W(C), S(C))` together; override when the two share work (every built-in model does).
    fn energy_and_stress(&self, c: &Matrix2<f64>) -> (f64, Matrix2<f64>) {
        (self.energy(c), self.stress(c))
    }

    /// The tangent `D = 4 d^2W/dC^2` as a symmetric 3x3 matrix in Voigt notation with engineering
    /// shear: with `E = (C - I)/2`, `[dS11, dS22, dS12] = D [dE11, dE22, 2 dE12]` (Pa).
    ///
    /// The provided implementation evaluates [`MembraneMaterial::stress_differential`] along the
    /// three unit Voigt strains.
    fn tangent(&self, c: &Matrix2<f64>) -> Matrix3<f64> {
        let dirs = [
            Matrix2::new(2.0, 0.0, 0.0, 0.0),
            Matrix2::new(0.0, 0.0, 0.0, 2.0),
            Matrix2::new(0.0, 1.0, 1.0, 0.0),
        ];
        let mut d = Matrix3::zeros();
        for (k, dc) in dirs.iter().enumerate() {
            let ds = self.stress_differential(c, dc);
            d[(0, k)] = ds[(0, 0)];
            d[(1, k)] = ds[(1, 1)];
            d[(2, k)] = 0.5 * (ds[(0, 1)] + ds[(1, 0)]);
        }
        d
    }

    /// The initial (small-strain) shear modulus `mu0` (Pa): `W ~ mu0 tr(e^2)` for small strains
    /// of the incompressible 3D material. For example `mu` for neo-Hookean and Gent,
    /// `2 (c1 + c2)` for Mooney-Rivlin, `sum mu_p alpha_p / 2` for Ogden, `2 c1` for Yeoh.
    fn initial_shear_modulus(&self) -> f64;

    /// Whether the model is defined at `C`: `det C > 0`, all entries finite, and the model's own
    /// limit (Gent: `I1 - 3 < jm`).
    fn is_admissible(&self, c: &Matrix2<f64>) -> bool;
}

/// Current thickness `h = H / sqrt(det C)` (m) of an incompressible sheet of rest thickness `H`
/// (m) at in-plane right Cauchy-Green tensor `C`: the through-thickness stretch is
/// `l3 = 1 / (l1 l2) = 1 / sqrt(det C)`. NaN when `det C <= 0`.
pub fn incompressible_thickness(rest_thickness: f64, c: &Matrix2<f64>) -> f64 {
    let det = c.determinant();
    if det > 0.0 {
        rest_thickness / det.sqrt()
    } else {
        f64::NAN
    }
}

/// The determinant, inverse and trace of an admissible (`det > 0`, finite) 2x2 `C`.
#[inline]
pub(crate) fn det_inv_tr(c: &Matrix2<f64>) -> Option<(f64, Matrix2<f64>, f64)> {
    if !c.iter().all(|v| v.is_finite()) {
        return None;
    }
    let det = c[(0, 0)] * c[(1, 1)] - c[(0, 1)] * c[(1, 0)];
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let inv = Matrix2::new(c[(1, 1)], -c[(0, 1)], -c[(1, 0)], c[(0, 0)]) / det;
    Some((det, inv, c[(0, 0)] + c[(1, 1)]))
}

/// Frobenius inner product `A : B`.
#[inline]
pub(crate) fn ddot(a: &Matrix2<f64>, b: &Matrix2<f64>) -> f64 {
    a.component_mul(b).sum()
}

pub(crate) const NAN2: Matrix2<f64> = Matrix2::new(f64::NAN, f64::NAN, f64::NAN, f64::NAN);
