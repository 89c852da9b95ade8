//! Gas laws beyond the isothermal ideal gas (issue 14, item 5): a polytropic (adiabatic) gas, a
//! leaking balloon and a pump that stops at its supply pressure.
//!
//! Equation numbers G1-G9 refer to `docs/gas-and-integration.md`, section "Gas laws beyond
//! isothermal". Amounts are gas contents `N = nRT` in joules (Pa m^3), as for [`crate::Pump`].
//!
//! The leak and the supply pump have a history: the amount changes with the pressure, which
//! depends on the volume the surface reaches. Over a time step from the committed state
//! `(N0, t0)` to the time `t` (`tau = t - t0`) the amount is integrated by backward Euler with
//! the end-of-step volume `V`, which makes the pressure a function `p(V, t)` at fixed `t` with a
//! potential (so the implicit step stays an energy minimisation, Wang et al. 2015, Eq. 18), and
//! [`GasModel::end_step`] commits the amount reached when a step is accepted.

use serde::{Deserialize, Serialize};

use crate::GasError;
use crate::model::GasModel;

fn finite_at_least(
    name: &'static str,
    value: f64,
    min: f64,
    requirement: &'static str,
) -> Result<f64, GasError> {
    if value.is_finite() && value >= min {
        Ok(value)
    } else {
        Err(GasError::InvalidParameter {
            name,
            value,
            requirement,
        })
    }
}

fn positive(name: &'static str, value: f64) -> Result<f64, GasError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(GasError::InvalidParameter {
            name,
            value,
            requirement: "must be positive and finite",
        })
    }
}

/// A polytropic gas: `p V^gamma = p0 V0^gamma` (G1). `gamma = 1.4` is the adiabatic (isentropic)
/// compression of air, `gamma = 1` the isothermal ideal gas of Wang et al. 2015, Eq. 14.
///
/// `p = K V^-gamma` with `K = p0 V0^gamma`, `dp/dV = -gamma p / V` (G2, the coefficient of the
/// rank-1 tangent of Eq. 16-17), potential `Phi = K V^(1-gamma) / (gamma - 1)` (G3; `-K ln V`
/// at `gamma = 1`), so `-dPhi/dV = p`.
///
/// ```
/// use balloon_gas::{GasModel, Polytropic};
/// let air = Polytropic::try_new(1.2e5, 0.01, 1.4).unwrap();
/// // Halving the volume adiabatically multiplies the pressure by 2^1.4.
/// let p = air.absolute_pressure(0.005, 0.0);
/// assert!((p / 1.2e5 - 2f64.powf(1.4)).abs() < 1e-12);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polytropic {
    /// Absolute pressure `p0` at the reference volume, Pa.
    pub initial_pressure: f64,
    /// Reference volume `V0`, m^3.
    pub initial_volume: f64,
    /// The polytropic exponent `gamma` (> 0; 1.4 for adiabatic air, 1 isothermal).
    pub gamma: f64,
}

/// `gamma` this close to 1 uses the logarithmic potential of the isothermal gas.
const ISOTHERMAL_GAP: f64 = 1e-12;

impl Polytropic {
    /// From the absolute pressure `p0` (Pa) at the volume `V0` (m^3) and the exponent `gamma`.
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] unless `p0`, `V0` and `gamma` are positive and finite.
    pub fn try_new(
        initial_pressure: f64,
        initial_volume: f64,
        gamma: f64,
    ) -> Result<Self, GasError> {
        Ok(Self {
            initial_pressure: positive("initial_pressure", initial_pressure)?,
            initial_volume: positive("initial_volume", initial_volume)?,
            gamma: positive("gamma", gamma)?,
        })
    }

    /// The invariant `K = p V^gamma` (Pa m^(3 gamma)).
    pub fn invariant(&self) -> f64 {
        self.initial_pressure * self.initial_volume.powf(self.gamma)
    }
}

impl GasModel for Polytropic {
    fn absolute_pressure(&self, volume: f64, _time: f64) -> f64 {
        // Written relative to V0 so that large exponents do not overflow.
        self.initial_pressure * (self.initial_volume / volume).powf(self.gamma)
    }

    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64 {
        -self.gamma * self.absolute_pressure(volume, time) / volume
    }

    /// `p0 V0 / (gamma - 1) (V0 / V)^(gamma - 1)` (G3, `K V^(1-gamma) / (gamma - 1)`), or
    /// `-p0 V0 ln V` at `gamma = 1`.
    fn potential(&self, volume: f64, _time: f64) -> Option<f64> {
        let g1 = self.gamma - 1.0;
        let pv = self.initial_pressure * self.initial_volume;
        Some(if g1.abs() < ISOTHERMAL_GAP {
            -pv * volume.ln()
        } else {
            pv / g1 * (self.initial_volume / volume).powf(g1)
        })
    }

    /// Keeps `p0` and takes `volume` as the new `V0` (the mesh volume replaces a guessed one).
    fn reset_reference(&mut self, volume: f64, _time: f64) {
        if volume.is_finite() && volume > 0.0 {
            self.initial_volume = volume;
        }
    }
}

/// An ideal gas leaking through a small hole: the amount flows out in proportion to the gauge
/// pressure, `dN/dt = -C (p - p_ambient)` with `N = nRT` (J) and the conductance `C` (m^3/s;
/// G4). A rigid balloon of volume `V` loses its gauge pressure as `exp(-C t / V)`.
///
/// Over a step of length `tau = t - t0` from the committed amount `N0` with the end-of-step
/// volume `V`, backward Euler gives `N = (N0 + tau C p_a) V / (V + tau C)`, so
///
/// `p(V, t) = (N0 + tau C p_a) / (V + tau C)`,
/// `dp/dV = -p / (V + tau C)`,
/// `Phi = -(N0 + tau C p_a) ln(V + tau C)` (G5),
///
/// the isothermal gas of the amount `N0` at `tau = 0`. [`GasModel::end_step`] commits
/// `N0 <- p V`, `t0 <- t`.
///
/// ```
/// use balloon_gas::{GasModel, LeakyGas};
/// let mut gas = LeakyGas::try_new(1.1e5 * 0.01, 1.0e5, 1.0e-3).unwrap();
/// let before = gas.absolute_pressure(0.01, 0.0) - 1.0e5;
/// gas.end_step(0.01, 1.0);
/// let after = gas.absolute_pressure(0.01, 1.0) - 1.0e5;
/// assert!(after < before && after > 0.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeakyGas {
    /// Committed gas content `N0 = nRT`, J.
    pub amount: f64,
    /// Time of the committed content, s.
    pub time: f64,
    /// Leak conductance `C`, m^3/s (>= 0; 0 is the isothermal ideal gas).
    pub conductance: f64,
    /// Ambient pressure the gas leaks to, Pa.
    pub ambient_pressure: f64,
}

impl LeakyGas {
    /// A gas of content `amount` (J, `p V`) at `t = 0` leaking with `conductance` (m^3/s) to
    /// `ambient_pressure` (Pa).
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] unless the amount is positive, the ambient pressure
    /// non-negative and the conductance non-negative, all finite.
    pub fn try_new(amount: f64, ambient_pressure: f64, conductance: f64) -> Result<Self, GasError> {
        Ok(Self {
            amount: positive("amount", amount)?,
            time: 0.0,
            conductance: finite_at_least(
                "leak_conductance",
                conductance,
                0.0,
                "must be a finite conductance >= 0 m^3/s",
            )?,
            ambient_pressure: finite_at_least(
                "ambient_pressure",
                ambient_pressure,
                0.0,
                "must be non-negative and finite",
            )?,
        })
    }

    /// `(tau C, N0 + tau C p_a)` at `time`.
    fn implicit(&self, time: f64) -> (f64, f64) {
        let tc = (time - self.time).max(0.0) * self.conductance;
        (tc, self.amount + tc * self.ambient_pressure)
    }

    /// The gas content `N = p V` (J) the step to `time` reaches at `volume` (G5).
    pub fn amount_at(&self, volume: f64, time: f64) -> f64 {
        self.absolute_pressure(volume, time) * volume
    }
}

impl GasModel for LeakyGas {
    fn absolute_pressure(&self, volume: f64, time: f64) -> f64 {
        let (tc, n) = self.implicit(time);
        n / (volume + tc)
    }

    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64 {
        let (tc, n) = self.implicit(time);
        -n / ((volume + tc) * (volume + tc))
    }

    fn potential(&self, volume: f64, time: f64) -> Option<f64> {
        let (tc, n) = self.implicit(time);
        Some(-n * (volume + tc).ln())
    }

    /// Keeps the pressure and re-anchors the content at `volume` and `time`.
    fn reset_reference(&mut self, volume: f64, time: f64) {
        if volume.is_finite() && volume > 0.0 {
            let p = self.absolute_pressure(volume, time);
            self.amount = p * volume;
            self.time = time;
        }
    }

    fn end_step(&mut self, volume: f64, time: f64) {
        if volume.is_finite() && volume > 0.0 && time >= self.time {
            self.amount = self.amount_at(volume, time);
            self.time = time;
        }
    }
}

/// A pump with a supply pressure: it adds gas at `rate` (J/s of `nRT`) until the balloon's
/// absolute pressure reaches the supply pressure `p_s`, and then stops (a check valve keeps the
/// gas in; nothing is vented when the balloon is above `p_s`). G6-G9.
///
/// Over a step of length `tau` from the committed content `N0`, the pump can deliver up to
/// `N0 + rate tau`; with `V1 = N0 / p_s` and `V2 = (N0 + rate tau) / p_s`:
///
/// * `V <= V1`: `p = N0 / V` (at or above the supply: stopped),
/// * `V1 < V < V2`: `p = p_s` (the pump delivers exactly what brings the balloon to `p_s`),
/// * `V >= V2`: `p = (N0 + rate tau) / V` (the full rate),
///
/// continuous in `V`, `dp/dV = -N0 / V^2`, `0`, `-(N0 + rate tau) / V^2` on the three parts, and
/// the potential (continuous, `-dPhi/dV = p`) `-N0 ln V + N0 ln V1 - N0`, `-p_s V`,
/// `-(N0 + rate tau) ln V + (N0 + rate tau) ln V2 - (N0 + rate tau)`.
/// [`GasModel::end_step`] commits `N0 <- p V`, `t0 <- t`.
///
/// ```
/// use balloon_gas::{GasModel, SupplyPump};
/// // From 1e5 Pa in 0.01 m^3, 100 J/s, supply at 1.02e5 Pa.
/// let pump = SupplyPump::try_new(1.0e3, 100.0, 1.02e5).unwrap();
/// assert!((pump.absolute_pressure(0.01, 0.1) - 1.01e5).abs() < 1e-6);
/// // Given time, the pressure stops at the supply.
/// assert_eq!(pump.absolute_pressure(0.01, 10.0), 1.02e5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SupplyPump {
    /// Committed gas content `N0 = nRT`, J.
    pub amount: f64,
    /// Time of the committed content, s.
    pub time: f64,
    /// Largest pumping rate, J/s of `nRT` (>= 0).
    pub rate: f64,
    /// Absolute supply pressure `p_s`, Pa (> 0).
    pub supply_pressure: f64,
}

impl SupplyPump {
    /// A pump starting at `t = 0` with the content `amount` (J), the rate `rate` (J/s) and the
    /// absolute supply pressure `supply_pressure` (Pa).
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] unless the amount and the supply pressure are positive and
    /// the rate non-negative, all finite.
    pub fn try_new(amount: f64, rate: f64, supply_pressure: f64) -> Result<Self, GasError> {
        Ok(Self {
            amount: positive("amount", amount)?,
            time: 0.0,
            rate: finite_at_least("rate", rate, 0.0, "must be non-negative and finite")?,
            supply_pressure: positive("supply_pressure", supply_pressure)?,
        })
    }

    /// The content the pump can have delivered by `time`, `N0 + rate tau` (J).
    fn available(&self, time: f64) -> f64 {
        self.amount + self.rate * (time - self.time).max(0.0)
    }

    /// The gas content `N = p V` (J) the step to `time` reaches at `volume`.
    pub fn amount_at(&self, volume: f64, time: f64) -> f64 {
        self.absolute_pressure(volume, time) * volume
    }

    /// Whether the pump has stopped at `volume` and `time`: the balloon is at or above the
    /// supply pressure.
    pub fn stopped(&self, volume: f64, time: f64) -> bool {
        self.absolute_pressure(volume, time) >= self.supply_pressure
    }
}

impl GasModel for SupplyPump {
    fn absolute_pressure(&self, volume: f64, time: f64) -> f64 {
        let ps = self.supply_pressure;
        if self.amount >= ps * volume {
            self.amount / volume
        } else {
            (self.available(time) / volume).min(ps)
        }
    }

    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64 {
        let ps = self.supply_pressure;
        let full = self.available(time);
        if self.amount >= ps * volume {
            -self.amount / (volume * volume)
        } else if full <= ps * volume {
            -full / (volume * volume)
        } else {
            0.0
        }
    }

    fn potential(&self, volume: f64, time: f64) -> Option<f64> {
        let ps = self.supply_pressure;
        let n0 = self.amount;
        let full = self.available(time);
        Some(if n0 >= ps * volume {
            let v1 = n0 / ps;
            -n0 * volume.ln() + n0 * v1.ln() - n0
        } else if full <= ps * volume {
            let v2 = full / ps;
            -full * volume.ln() + full * v2.ln() - full
        } else {
            -ps * volume
        })
    }

    /// Keeps the pressure and restarts pumping at `time` from the content at `volume`.
    fn reset_reference(&mut self, volume: f64, time: f64) {
        if volume.is_finite() && volume > 0.0 {
            self.amount = self.amount_at(volume, time);
            self.time = time;
        }
    }

    fn end_step(&mut self, volume: f64, time: f64) {
        if volume.is_finite() && volume > 0.0 && time >= self.time {
            self.amount = self.amount_at(volume, time);
            self.time = time;
        }
    }
}
