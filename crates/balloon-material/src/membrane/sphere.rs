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

    /// The end state of two such spheres joined by a tube (the two-balloon experiment): each
    /// holds the same isothermal ideal gas at one gauge pressure `P`, one on the rising branch
    /// below the first pressure maximum and one on the falling branch beyond it, with the total
    /// amount `sum (p_ambient + P) V0 l^3 = amount` (J). `rest_volume` is `V0`, the enclosed
    /// volume at `l = 1` (m^3; pass the mesh's own to compare with a simulation), and the
    /// falling branch is searched up to `max_stretch` (or the next minimum of `P`). Returns
    /// `(l_small, l_large, P)`, or `None` when no such state exists (no maximum, or `amount`
    /// out of reach). Both stretches by bisection to machine precision.
    ///
    /// # Errors
    /// As [`ThinSphere::extrema`].
    pub fn joined_pair<M: MembraneMaterial>(
        &self,
        material: &M,
        ambient: f64,
        rest_volume: f64,
        amount: f64,
        max_stretch: f64,
    ) -> Result<Option<(f64, f64, f64)>, MaterialError> {
        let extrema = self.extrema(material, max_stretch)?;
        let Some(k) = extrema.iter().position(|e| e.kind == ExtremumKind::Maximum) else {
            return Ok(None);
        };
        let l_max = extrema[k].stretch;
        let l_end = extrema.get(k + 1).map_or(max_stretch, |e| e.stretch);
        let p = |l: f64| self.pressure(material, l);
        // The point of [lo, hi] where `below` turns from true to false (`below(lo)` is taken
        // as true and `below(hi)` as false), to machine precision.
        let bisect = |mut lo: f64, mut hi: f64, below: &dyn Fn(f64) -> bool| {
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if below(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        // The falling-branch stretch at gauge pressure `target` (`P` decreases there).
        let falling =
            |target: f64| (p(l_end) <= target).then(|| bisect(l_max, l_end, &|l| p(l) > target));
        let residual = |ls: f64| {
            let pressure = p(ls);
            falling(pressure)
                .map(|ll| (ambient + pressure) * rest_volume * (ls.powi(3) + ll.powi(3)) - amount)
        };
        // The rising branch reaches the pressures the falling one has from `l_lo` on.
        let p_end = p(l_end);
        let l_lo = if p_end > 0.0 {
            bisect(1.0, l_max, &|l| p(l) < p_end)
        } else {
            1.0
        };
        let (lo, hi) = (l_lo * (1.0 + 1e-12), l_max * (1.0 - 1e-12));
        match (residual(lo), residual(hi)) {
            (Some(a), Some(b)) if (a > 0.0) != (b > 0.0) => {
                let ls = bisect(lo, hi, &|l| {
                    residual(l).is_some_and(|r| (r > 0.0) == (a > 0.0))
                });
                let pressure = p(ls);
                Ok(falling(pressure).map(|ll| (ls, ll, pressure)))
            }
            _ => Ok(None),
        }
    }
}
