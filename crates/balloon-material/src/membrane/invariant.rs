//! Membrane models written in the invariants `I1`, `I2` of `C3 = diag(C, 1/det C)`:
//! neo-Hookean, Mooney-Rivlin, Gent and Yeoh.
//!
//! With `J2 = det C`, `C^-1` and `tr C` (see `docs/membranes.md`, Eq. M3-M8):
//!
//! * `I1 = tr C + 1/J2`, `A1 = dI1/dC = I - C^-1 / J2`;
//! * `I2 = J2 + tr C / J2`, `A2 = dI2/dC = J2 C^-1 + I / J2 - tr C C^-1 / J2`;
//! * `S = 2 (W1 A1 + W2 A2)` with `Wk = dW/dIk`;
//! * `dS = 2 [(W11 A1:dC + W12 A2:dC) A1 + (W12 A1:dC + W22 A2:dC) A2 + W1 dA1 + W2 dA2]`,
//!   `dA1 = (C^-1 dC C^-1 + tau C^-1) / J2`, `tau = C^-1 : dC`, and `dA2` from Eq. M8.

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};

use super::{MembraneMaterial, NAN2, ddot, det_inv_tr};
use crate::MaterialError;

/// `W(I1, I2)` and its first and second partial derivatives.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct InvariantDerivatives {
    pub w: f64,
    pub w1: f64,
    pub w2: f64,
    pub w11: f64,
    pub w12: f64,
    pub w22: f64,
}

/// A membrane energy given as a function of the invariants of `C3`.
pub(crate) trait InvariantEnergy {
    /// `W` and its derivatives at `(I1, I2)`, or `None` outside the model's admissible set.
    fn derivatives(&self, i1: f64, i2: f64) -> Option<InvariantDerivatives>;
}

/// Kinematic quantities of `C` shared by the stress and its differential.
struct Invariants {
    j2: f64,
    cinv: Matrix2<f64>,
    trc: f64,
    i1: f64,
    i2: f64,
    a1: Matrix2<f64>,
    a2: Matrix2<f64>,
}

#[inline]
fn invariants(c: &Matrix2<f64>) -> Option<Invariants> {
    let (j2, cinv, trc) = det_inv_tr(c)?;
    let id = Matrix2::identity();
    let i1 = trc + 1.0 / j2;
    let i2 = j2 + trc / j2;
    let a1 = id - cinv / j2;
    let a2 = cinv * j2 + id / j2 - cinv * (trc / j2);
    Some(Invariants {
        j2,
        cinv,
        trc,
        i1,
        i2,
        a1,
        a2,
    })
}

#[inline]
fn energy_of<T: InvariantEnergy>(m: &T, c: &Matrix2<f64>) -> f64 {
    invariants(c)
        .and_then(|k| m.derivatives(k.i1, k.i2))
        .map_or(f64::INFINITY, |d| d.w)
}

#[inline]
fn energy_and_stress_of<T: InvariantEnergy>(m: &T, c: &Matrix2<f64>) -> (f64, Matrix2<f64>) {
    match invariants(c).and_then(|k| m.derivatives(k.i1, k.i2).map(|d| (k, d))) {
        Some((k, d)) => (d.w, (k.a1 * d.w1 + k.a2 * d.w2) * 2.0),
        None => (f64::INFINITY, NAN2),
    }
}

#[inline]
fn stress_differential_of<T: InvariantEnergy>(
    m: &T,
    c: &Matrix2<f64>,
    dc: &Matrix2<f64>,
) -> Matrix2<f64> {
    let Some((k, d)) = invariants(c).and_then(|k| m.derivatives(k.i1, k.i2).map(|d| (k, d))) else {
        return NAN2;
    };
    let id = Matrix2::identity();
    let tau = ddot(&k.cinv, dc);
    let cdc = k.cinv * dc * k.cinv;
    let da1 = (cdc + k.cinv * tau) / k.j2;
    // d(J2 C^-1) + d(I/J2) + d(-trC C^-1/J2), Eq. M8.
    let da2 = k.cinv * (k.j2 * tau) - cdc * k.j2 - id * (tau / k.j2) - k.cinv * (dc.trace() / k.j2)
        + cdc * (k.trc / k.j2)
        + k.cinv * (k.trc * tau / k.j2);
    let di1 = ddot(&k.a1, dc);
    let di2 = ddot(&k.a2, dc);
    (k.a1 * (d.w11 * di1 + d.w12 * di2)
        + k.a2 * (d.w12 * di1 + d.w22 * di2)
        + da1 * d.w1
        + da2 * d.w2)
        * 2.0
}

#[inline]
fn admissible_of<T: InvariantEnergy>(m: &T, c: &Matrix2<f64>) -> bool {
    invariants(c)
        .and_then(|k| m.derivatives(k.i1, k.i2))
        .is_some()
}

macro_rules! impl_membrane_material {
    ($t:ty, $mu0:expr) => {
        impl MembraneMaterial for $t {
            #[inline]
            fn energy(&self, c: &Matrix2<f64>) -> f64 {
                energy_of(self, c)
            }
            #[inline]
            fn stress(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
                energy_and_stress_of(self, c).1
            }
            #[inline]
            fn stress_differential(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
                stress_differential_of(self, c, dc)
            }
            #[inline]
            fn energy_and_stress(&self, c: &Matrix2<f64>) -> (f64, Matrix2<f64>) {
                energy_and_stress_of(self, c)
            }
            #[inline]
            fn initial_shear_modulus(&self) -> f64 {
                let f: fn(&Self) -> f64 = $mu0;
                f(self)
            }
            #[inline]
            fn is_admissible(&self, c: &Matrix2<f64>) -> bool {
                admissible_of(self, c)
            }
        }
    };
}

fn positive(name: &'static str, value: f64) -> Result<f64, MaterialError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(MaterialError::InvalidParameter {
            name,
            value,
            allowed: "finite and > 0",
        })
    }
}

fn finite(name: &'static str, value: f64) -> Result<f64, MaterialError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(MaterialError::InvalidParameter {
            name,
            value,
            allowed: "finite",
        })
    }
}

/// Incompressible neo-Hookean membrane, `W = mu/2 (I1 - 3)` with `I1 = tr C + 1/det C`
/// (`docs/membranes.md` Eq. M9).
///
/// The simplest rubber model (Treloar's Gaussian network). On the inflated sphere it has a
/// pressure maximum at `l = 7^(1/6)` and no minimum: past the maximum the pressure keeps falling.
/// Parameter: `mu` > 0, the shear modulus (Pa).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawNeoHookean")]
pub struct MembraneNeoHookean {
    mu: f64,
}

#[derive(Deserialize)]
struct RawNeoHookean {
    mu: f64,
}

impl TryFrom<RawNeoHookean> for MembraneNeoHookean {
    type Error = MaterialError;
    fn try_from(r: RawNeoHookean) -> Result<Self, MaterialError> {
        Self::try_new(r.mu)
    }
}

impl MembraneNeoHookean {
    /// The model with shear modulus `mu` (Pa).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `mu` unless finite and `> 0`.
    pub fn try_new(mu: f64) -> Result<Self, MaterialError> {
        Ok(Self {
            mu: positive("mu", mu)?,
        })
    }

    /// Shear modulus `mu` (Pa).
    pub fn mu(&self) -> f64 {
        self.mu
    }
}

impl InvariantEnergy for MembraneNeoHookean {
    #[inline]
    fn derivatives(&self, i1: f64, _i2: f64) -> Option<InvariantDerivatives> {
        Some(InvariantDerivatives {
            w: 0.5 * self.mu * (i1 - 3.0),
            w1: 0.5 * self.mu,
            ..Default::default()
        })
    }
}
impl_membrane_material!(MembraneNeoHookean, |m| m.mu);

/// Incompressible Mooney-Rivlin membrane, `W = c1 (I1 - 3) + c2 (I2 - 3)` (Mooney 1940,
/// Rivlin 1948; `docs/membranes.md` Eq. M10).
///
/// Initial shear modulus `2 (c1 + c2)`; `c2 = 0` is the neo-Hookean model with `mu = 2 c1`. On
/// the inflated sphere `P ~ (1/l - 1/l^7)(1 + (c2/c1) l^2)`: for `0 < c2/c1` below about 0.21
/// the curve has a maximum and then a minimum, above it the pressure rises monotonically.
/// Parameters: `c1 > 0`, `c2 >= 0` (Pa), the usual conditions for a stable (Baker-Ericksen)
/// response.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawMooneyRivlin")]
pub struct MembraneMooneyRivlin {
    c1: f64,
    c2: f64,
}

#[derive(Deserialize)]
struct RawMooneyRivlin {
    c1: f64,
    c2: f64,
}

impl TryFrom<RawMooneyRivlin> for MembraneMooneyRivlin {
    type Error = MaterialError;
    fn try_from(r: RawMooneyRivlin) -> Result<Self, MaterialError> {
        Self::try_new(r.c1, r.c2)
    }
}

impl MembraneMooneyRivlin {
    /// The model with constants `c1`, `c2` (Pa).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `c1` unless finite and `> 0`, or `c2` unless
    /// finite and `>= 0`.
    pub fn try_new(c1: f64, c2: f64) -> Result<Self, MaterialError> {
        let c1 = positive("c1", c1)?;
        if !(c2.is_finite() && c2 >= 0.0) {
            return Err(MaterialError::InvalidParameter {
                name: "c2",
                value: c2,
                allowed: "finite and >= 0",
            });
        }
        Ok(Self { c1, c2 })
    }

    /// `c1` (Pa).
    pub fn c1(&self) -> f64 {
        self.c1
    }

    /// `c2` (Pa).
    pub fn c2(&self) -> f64 {
        self.c2
    }
}

impl InvariantEnergy for MembraneMooneyRivlin {
    #[inline]
    fn derivatives(&self, i1: f64, i2: f64) -> Option<InvariantDerivatives> {
        Some(InvariantDerivatives {
            w: self.c1 * (i1 - 3.0) + self.c2 * (i2 - 3.0),
            w1: self.c1,
            w2: self.c2,
            ..Default::default()
        })
    }
}
impl_membrane_material!(MembraneMooneyRivlin, |m| 2.0 * (m.c1 + m.c2));

/// Incompressible Gent membrane, `W = -mu jm/2 ln(1 - (I1 - 3)/jm)` (Gent 1996, Rubber Chem.
/// Technol. 69:59; `docs/membranes.md` Eq. M11).
///
/// Neo-Hookean with shear modulus `mu` at small strain, with a limiting chain extensibility:
/// the energy becomes infinite as `I1 - 3 -> jm`, so the sphere's pressure curve has a maximum
/// and then, for the usual `jm` (tens to about a hundred), a minimum followed by steep
/// stiffening. States with `I1 - 3 >= jm` are inadmissible (energy `+infinity`, NaN stress). As
/// `jm -> infinity` the model tends to neo-Hookean. Parameters: `mu > 0` (Pa), `jm` at least
/// [`MembraneGent::MIN_JM`] (dimensionless).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawGent")]
pub struct MembraneGent {
    mu: f64,
    jm: f64,
}

#[derive(Deserialize)]
struct RawGent {
    mu: f64,
    jm: f64,
}

impl TryFrom<RawGent> for MembraneGent {
    type Error = MaterialError;
    fn try_from(r: RawGent) -> Result<Self, MaterialError> {
        Self::try_new(r.mu, r.jm)
    }
}

impl MembraneGent {
    /// The smallest accepted extensibility limit `jm`. Near the rest shape `I1 - 3` is about
    /// `12 e^2` for an equibiaxial stretch `1 + e`, so `jm = 1e-6` still lets the membrane stretch
    /// by about 0.03 %; a much smaller `jm` is swamped by the rounding of `I1 - 3` (about
    /// `1e-15`), which makes even the rest shape inadmissible (infinite energy) and leaves a
    /// solver nothing honest to report.
    pub const MIN_JM: f64 = 1e-6;

    /// The model with shear modulus `mu` (Pa) and extensibility limit `jm` (dimensionless).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `mu` unless finite and `> 0`, or `jm` unless
    /// finite and at least [`MembraneGent::MIN_JM`].
    pub fn try_new(mu: f64, jm: f64) -> Result<Self, MaterialError> {
        let mu = positive("mu", mu)?;
        if !(jm.is_finite() && jm >= Self::MIN_JM) {
            return Err(MaterialError::InvalidParameter {
                name: "jm",
                value: jm,
                allowed: "finite and at least 1e-6 (> 0; a smaller limit leaves the membrane no \
                          stretch beyond rounding; rubber is about 30-100)",
            });
        }
        Ok(Self { mu, jm })
    }

    /// Shear modulus `mu` (Pa).
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// Extensibility limit `jm` (dimensionless): the largest admissible `I1 - 3`.
    pub fn jm(&self) -> f64 {
        self.jm
    }
}

impl InvariantEnergy for MembraneGent {
    #[inline]
    fn derivatives(&self, i1: f64, _i2: f64) -> Option<InvariantDerivatives> {
        let x = (i1 - 3.0) / self.jm;
        let r = 1.0 - x;
        if !(r > 0.0 && r.is_finite()) {
            return None;
        }
        let w1 = 0.5 * self.mu / r;
        Some(InvariantDerivatives {
            // ln(1 - x) through ln_1p: no cancellation for a large jm.
            w: -0.5 * self.mu * self.jm * (-x).ln_1p(),
            w1,
            w11: w1 / (r * self.jm),
            ..Default::default()
        })
    }
}
impl_membrane_material!(MembraneGent, |m| m.mu);

/// Incompressible Yeoh membrane, `W = c1 (I1-3) + c2 (I1-3)^2 + c3 (I1-3)^3` (Yeoh 1993,
/// Rubber Chem. Technol. 66:754; `docs/membranes.md` Eq. M12).
///
/// Initial shear modulus `2 c1`; `c2 = c3 = 0` is neo-Hookean with `mu = 2 c1`. Positive `c2`,
/// `c3` stiffen the response at large stretch (a pressure minimum on the sphere); published fits
/// of soft silicones sometimes have a negative `c2` or `c3`, which is accepted (such a model can
/// lose stability at large stretch). Parameters: `c1 > 0`, `c2`, `c3` finite (Pa).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawYeoh")]
pub struct MembraneYeoh {
    c1: f64,
    c2: f64,
    c3: f64,
}

#[derive(Deserialize)]
struct RawYeoh {
    c1: f64,
    #[serde(default)]
    c2: f64,
    #[serde(default)]
    c3: f64,
}

impl TryFrom<RawYeoh> for MembraneYeoh {
    type Error = MaterialError;
    fn try_from(r: RawYeoh) -> Result<Self, MaterialError> {
        Self::try_new(r.c1, r.c2, r.c3)
    }
}

impl MembraneYeoh {
    /// The model with constants `c1`, `c2`, `c3` (Pa).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `c1` unless finite and `> 0`, or `c2` / `c3`
    /// unless finite.
    pub fn try_new(c1: f64, c2: f64, c3: f64) -> Result<Self, MaterialError> {
        Ok(Self {
            c1: positive("c1", c1)?,
            c2: finite("c2", c2)?,
            c3: finite("c3", c3)?,
        })
    }

    /// Builds the model without checks, for the published presets (tested to pass `try_new`).
    pub(crate) fn preset_unchecked(c1: f64, c2: f64, c3: f64) -> Self {
        Self { c1, c2, c3 }
    }

    /// `[c1, c2, c3]` (Pa).
    pub fn coefficients(&self) -> [f64; 3] {
        [self.c1, self.c2, self.c3]
    }
}

impl InvariantEnergy for MembraneYeoh {
    #[inline]
    fn derivatives(&self, i1: f64, _i2: f64) -> Option<InvariantDerivatives> {
        let x = i1 - 3.0;
        Some(InvariantDerivatives {
            w: x * (self.c1 + x * (self.c2 + x * self.c3)),
            w1: self.c1 + x * (2.0 * self.c2 + 3.0 * self.c3 * x),
            w11: 2.0 * self.c2 + 6.0 * self.c3 * x,
            ..Default::default()
        })
    }
}
impl_membrane_material!(MembraneYeoh, |m| 2.0 * m.c1);
