//! The analytic inflated thin sphere: pressure against stretch and its extrema.

use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};

use super::MembraneMaterial;
use crate::MaterialError;

/// A thin spherical membrane of rest radius `R` (m) and rest thickness `H` (m), inflated
/// uniformly to radius `l R` (`docs/membranes.md` Eq. M18-M21).
///
/// The stretch is equibiaxial, `C = l^2 I`, so the energy per unit rest volume is
/// `w(l) = W(l, l, 1/l^2)` and the balance of the elastic energy `4 pi R^2 H w(l)` against the
/// pressure work `P dV`, `V = 4/3 pi R^3 l^3`, gives
///
/// `P(l) = H / (R l^2) w'(l)`, with `w'(l) = dW/dC : dC/dl = l tr S(l^2 I)`,
///
/// so the pressure comes from the model's own stress (not a restatement of a closed form) and
/// the tests check it against a finite difference of the energy. For the neo-Hookean membrane
/// `P = 2 mu H / R (1/l - 1/l^7)`, with its maximum at `l = 7^(1/6)`, `P = 1.2395 mu H / R`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThinSphere {
    radius: f64,
    thickness: f64,
}

/// Whether a pressure extremum is a maximum (the limit point where pressure control snaps
/// through) or a minimum (where a stiffening material takes over again).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ExtremumKind {
    /// `dP/dl` changes from positive to negative.
    Maximum,
    /// `dP/dl` changes from negative to positive.
    Minimum,
}

/// A stationary point of the sphere's pressure curve `P(l)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PressureExtremum {
    /// The stretch `l = r / R` (dimensionless).
    pub stretch: f64,
    /// The gauge pressure `P(l)` (Pa).
    pub pressure: f64,
    /// Maximum or minimum.
    pub kind: ExtremumKind,
}

impl ThinSphere {
    /// A sphere of rest radius `radius` (m) and rest thickness `thickness` (m).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `radius` or `thickness` unless finite and
    /// `> 0`.
    pub fn try_new(radius: f64, thickness: f64) -> Result<Self, MaterialError> {
        for (name, value) in [("radius", radius), ("thickness", thickness)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(MaterialError::InvalidParameter {
                    name,
                    value,
                    allowed: "finite and > 0 m",
                });
            }
        }
        Ok(Self { radius, thickness })
    }

    /// Rest radius `R` (m).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Rest thickness `H` (m).
    pub fn thickness(&self) -> f64 {
        self.thickness
    }

    /// Current thickness `H / l^2` (m) at stretch `l` (incompressibility).
    pub fn current_thickness(&self, stretch: f64) -> f64 {
        self.thickness / (stretch * stretch)
    }

    /// Enclosed volume `4/3 pi R^3 l^3` (m^3) at stretch `l`.
    pub fn volume(&self, stretch: f64) -> f64 {
        4.0 / 3.0 * std::f64::consts::PI * (self.radius * stretch).powi(3)
    }

    /// Energy density `w(l) = W(l^2 I)` (J/m^3 per unit rest volume).
    pub fn energy_density<M: MembraneMaterial>(&self, material: &M, stretch: f64) -> f64 {
        material.energy(&(Matrix2::identity() * (stretch * stretch)))
    }

    /// `w'(l) = l tr S(l^2 I)` (J/m^3), from the model's stress.
    pub fn energy_density_slope<M: MembraneMaterial>(&self, material: &M, stretch: f64) -> f64 {
        let s = material.stress(&(Matrix2::identity() * (stretch * stretch)));
        stretch * s.trace()
    }

    /// Gauge pressure `P(l) = H / (R l^2) w'(l)` (Pa) that holds the sphere at stretch `l`.
    /// NaN where the model is not admissible (for example past Gent's limit).
    pub fn pressure<M: MembraneMaterial>(&self, material: &M, stretch: f64) -> f64 {
        self.thickness / (self.radius * stretch * stretch)
            * self.energy_density_slope(material, stretch)
    }

    /// `dP/dl` (Pa), from the model's stress differential:
    /// `P = (H/R) tr S / l`, `dP/dl = (H/R) (tr dS[2 l I] / l - tr S / l^2)`.
    pub fn pressure_slope<M: MembraneMaterial>(&self, material: &M, stretch: f64) -> f64 {
        let c = Matrix2::identity() * (stretch * stretch);
        let tr_s = material.stress(&c).trace();
        let tr_ds = material
            .stress_differential(&c, &(Matrix2::identity() * (2.0 * stretch)))
            .trace();
        self.thickness / self.radius * (tr_ds / stretch - tr_s / (stretch * stretch))
    }

    /// The extrema of `P(l)` for `1 < l <= max_stretch`, in increasing stretch: the sign of
    /// [`ThinSphere::pressure_slope`] is sampled on 4000 equal steps and every sign change is
    /// refined by bisection to machine precision. The scan stops where the model stops being
    /// admissible (Gent's limit). Extrema closer together than one sampling step
    /// (`(max_stretch - 1) / 4000`) can be missed.
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `max_stretch` unless finite and `> 1`.
    pub fn extrema<M: MembraneMaterial>(
        &self,
        material: &M,
        max_stretch: f64,
    ) -> Result<Vec<PressureExtremum>, MaterialError> {
        if !(max_stretch.is_finite() && max_stretch > 1.0) {
            return Err(MaterialError::InvalidParameter {
                name: "max_stretch",
                value: max_stretch,
                allowed: "finite and > 1",
            });
        }
        const STEPS: usize = 4000;
        let slope = |l: f64| self.pressure_slope(material, l);
        let step = (max_stretch - 1.0) / STEPS as f64;
        let mut out = Vec::new();
        let mut a = 1.0 + 1e-3 * step;
        let mut sa = slope(a);
        for k in 1..=STEPS {
            let b = 1.0 + step * k as f64;
            let sb = slope(b);
            if !(sa.is_finite() && sb.is_finite()) {
                break;
            }
            if (sa > 0.0) != (sb > 0.0) && sa != 0.0 {
                let kind = if sa > 0.0 {
                    ExtremumKind::Maximum
                } else {
                    ExtremumKind::Minimum
                };
                let (mut lo, mut hi) = (a, b);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if (slope(mid) > 0.0) == (sa > 0.0) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let l = 0.5 * (lo + hi);
                out.push(PressureExtremum {
                    stretch: l,
                    pressure: self.pressure(material, l),
                    kind,
                });
            }
            a = b;
            sa = sb;
        }
        Ok(out)
    }
}
