//! Gas models: how the absolute pressure depends on the enclosed volume and on time.
//!
//! All pressures are absolute, in pascals; volumes in m^3; time in seconds. The pressure
//! *load* on the surface uses the gauge pressure `p - p_ambient` (see [`crate::PressureLoad`]).

use std::fmt::Debug;

use serde::{Deserialize, Serialize};

use crate::GasError;

/// Standard atmospheric pressure, 101 325 Pa: the default ambient pressure outside a balloon.
pub const STANDARD_ATMOSPHERE: f64 = 101_325.0;

/// A uniform gas filling a closed volume (Wang et al. 2015, Sec. 5: the pressure is the same everywhere
/// inside, Eq. 12).
///
/// Implementations must be cheap to evaluate; they are called once per Newton iteration.
pub trait GasModel: Send + Sync + Debug {
    /// Absolute pressure `p(V, t)`, Pa, at enclosed volume `volume` (m^3, > 0) and time `time`
    /// (s).
    fn absolute_pressure(&self, volume: f64, time: f64) -> f64;

    /// `dp/dV` at fixed time, Pa / m^3. Non-positive for every physical gas (compressing a gas
    /// raises its pressure).
    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64;

    /// Potential energy `Phi(V, t)` of the gas at time `time`, J, with `-dPhi/dV = p(V, t)`
    /// (absolute pressure) at fixed time, or `None` when the model has none (a user's model
    /// whose pressure is not integrable in closed form). The value may carry any constant
    /// offset in `V`. This is what lets an implicit step be an energy minimisation (the
    /// incremental potential of backward Euler, Wang et al. 2015, Eq. 18, evaluated at the end-of-step
    /// time).
    ///
    /// * isothermal ideal gas: `Phi = -p0 V0 ln V` (Eq. 14 integrated),
    /// * constant pressure: `Phi = -p V`,
    /// * pump: `Phi = -nRT(t) ln V`, the ideal gas with the amount pumped in by time `t`
    ///   (the gas is conservative at each instant; the pump adds energy over time).
    ///
    /// The load on the surface adds the ambient term `p_ambient V`
    /// ([`crate::PressureLoad::potential`]), so the pressure potential of the constant gas is
    /// `-(p - p_ambient) V`.
    fn potential(&self, volume: f64, time: f64) -> Option<f64>;

    /// Re-anchors the reference state at the current `volume` (m^3) and `time` (s), e.g. once the
    /// rest volume of the mesh is known. The default does nothing; see each model for its
    /// meaning.
    fn reset_reference(&mut self, volume: f64, time: f64) {
        let _ = (volume, time);
    }

    /// Commits the state at the end of an accepted time step: the enclosed `volume` (m^3)
    /// reached at `time` (s). Gases with a history (a leak, a pump with a supply pressure,
    /// [`crate::laws`]) integrate their amount over the step implicitly in
    /// [`GasModel::absolute_pressure`] and store it here; the simulation calls this once per
    /// accepted step, never for a rejected one. The default does nothing (the gas has no
    /// history beyond `time`).
    fn end_step(&mut self, volume: f64, time: f64) {
        let _ = (volume, time);
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

fn non_negative(name: &'static str, value: f64) -> Result<f64, GasError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(GasError::InvalidParameter {
            name,
            value,
            requirement: "must be non-negative and finite",
        })
    }
}

/// Isothermal ideal gas with a fixed amount of gas: `p V = nRT = p0 V0` (Wang et al. 2015, Eq. 12 and
/// Eq. 14), so `p = p0 V0 / V` and `dp/dV = -p0 V0 / V^2`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IdealGas {
    /// Absolute pressure `p0` at the reference volume, Pa.
    pub initial_pressure: f64,
    /// Reference volume `V0`, m^3.
    pub initial_volume: f64,
}

impl IdealGas {
    /// From the absolute initial pressure `p0` (Pa) and the initial volume `V0` (m^3). Both must
    /// be positive and finite.
    pub fn try_new(initial_pressure: f64, initial_volume: f64) -> Result<Self, GasError> {
        Ok(Self {
            initial_pressure: positive("initial_pressure", initial_pressure)?,
            initial_volume: positive("initial_volume", initial_volume)?,
        })
    }

    /// From a gauge pressure (over `ambient`, both Pa) and the initial volume (m^3). The absolute
    /// pressure `gauge + ambient` must be positive.
    pub fn try_from_gauge(
        gauge_pressure: f64,
        ambient_pressure: f64,
        initial_volume: f64,
    ) -> Result<Self, GasError> {
        positive("ambient_pressure", ambient_pressure)?;
        Self::try_new(gauge_pressure + ambient_pressure, initial_volume)
    }

    /// The invariant `p0 V0 = nRT`, J.
    pub fn amount(&self) -> f64 {
        self.initial_pressure * self.initial_volume
    }
}

impl GasModel for IdealGas {
    fn absolute_pressure(&self, volume: f64, _time: f64) -> f64 {
        self.amount() / volume
    }

    fn dpressure_dvolume(&self, volume: f64, _time: f64) -> f64 {
        -self.amount() / (volume * volume)
    }

    fn potential(&self, volume: f64, _time: f64) -> Option<f64> {
        Some(-self.amount() * volume.ln())
    }

    /// Keeps `p0` and takes `volume` as the new `V0` (the mesh volume replaces a guessed one).
    fn reset_reference(&mut self, volume: f64, _time: f64) {
        if volume.is_finite() && volume > 0.0 {
            self.initial_volume = volume;
        }
    }
}

/// A gas held at a constant absolute pressure whatever its volume (an open valve on a large
/// reservoir): `dp/dV = 0`, so it adds no stiffness.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConstantPressure {
    /// Absolute pressure, Pa.
    pub pressure: f64,
}

impl ConstantPressure {
    /// From an absolute pressure (Pa, positive and finite).
    pub fn try_new(pressure: f64) -> Result<Self, GasError> {
        Ok(Self {
            pressure: positive("pressure", pressure)?,
        })
    }

    /// From a gauge pressure over `ambient` (both Pa).
    pub fn try_from_gauge(gauge_pressure: f64, ambient_pressure: f64) -> Result<Self, GasError> {
        positive("ambient_pressure", ambient_pressure)?;
        Self::try_new(gauge_pressure + ambient_pressure)
    }
}

impl GasModel for ConstantPressure {
    fn absolute_pressure(&self, _volume: f64, _time: f64) -> f64 {
        self.pressure
    }

    fn dpressure_dvolume(&self, _volume: f64, _time: f64) -> f64 {
        0.0
    }

    fn potential(&self, volume: f64, _time: f64) -> Option<f64> {
        Some(-self.pressure * volume)
    }
}

/// A pump adding gas at a constant rate: the gas content `nRT(t) = nRT_0 + rate * (t - t0)`
/// (J, i.e. Pa m^3) grows linearly from `nRT_0 = p_ambient V_rest` (the rest shape at ambient
/// pressure), and `p = nRT(t) / V` (Eq. 12 with a time-dependent amount). This simulates the
/// *process* of inflating rather than a prescribed final pressure.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pump {
    /// Gas content at `start_time`, J (Pa m^3).
    pub initial_amount: f64,
    /// Pumping rate, J/s (Pa m^3 / s), non-negative.
    pub rate: f64,
    /// Time at which pumping starts, s. Before it the content is `initial_amount`.
    pub start_time: f64,
    /// Ambient pressure used to (re-)anchor the content at rest, Pa.
    pub ambient_pressure: f64,
}

impl Pump {
    /// A pump starting at `t = 0` from the rest volume `rest_volume` (m^3) at `ambient_pressure`
    /// (Pa), adding `rate` J/s.
    pub fn try_from_rest(
        rest_volume: f64,
        ambient_pressure: f64,
        rate: f64,
    ) -> Result<Self, GasError> {
        let v = positive("rest_volume", rest_volume)?;
        let pa = positive("ambient_pressure", ambient_pressure)?;
        Ok(Self {
            initial_amount: pa * v,
            rate: non_negative("rate", rate)?,
            start_time: 0.0,
            ambient_pressure: pa,
        })
    }

    /// Gas content `nRT(t)`, J.
    pub fn amount(&self, time: f64) -> f64 {
        self.initial_amount + self.rate * (time - self.start_time).max(0.0)
    }
}

impl GasModel for Pump {
    fn absolute_pressure(&self, volume: f64, time: f64) -> f64 {
        self.amount(time) / volume
    }

    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64 {
        -self.amount(time) / (volume * volume)
    }

    /// `-nRT(t) ln V`: the ideal gas's potential with the amount at time `t` (Eq. 12, 14).
    fn potential(&self, volume: f64, time: f64) -> Option<f64> {
        Some(-self.amount(time) * volume.ln())
    }

    /// Restarts pumping at `time` from ambient pressure at `volume`.
    fn reset_reference(&mut self, volume: f64, time: f64) {
        if volume.is_finite() && volume > 0.0 {
            self.initial_amount = self.ambient_pressure * volume;
            self.start_time = time;
        }
    }
}
