//! Gas models: how the absolute pressure depends on the enclosed volume and on time.
//!
//! All pressures are absolute, in pascals; volumes in m^3; time in seconds. The pressure
//! *load* on the surface uses the gauge pressure `p - p_ambient` (see [`crate::PressureLoad`]).

use std::fmt::Debug;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::GasError;
use crate::laws::{LeakyGas, Polytropic, SupplyPump};

/// Standard atmospheric pressure, 101 325 Pa: the default ambient pressure outside a balloon.
pub const STANDARD_ATMOSPHERE: f64 = 101_325.0;

/// A uniform gas filling a closed volume (seed 000, Sec. 5: the pressure is the same everywhere
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
    /// incremental potential of backward Euler, seed 000 Eq. 18, evaluated at the end-of-step
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

/// Isothermal ideal gas with a fixed amount of gas: `p V = nRT = p0 V0` (seed 000, Eq. 12 and
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

/// The closed set of gas models, chosen by name in a scenario file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GasKind {
    /// [`IdealGas`] (`"ideal"`).
    Ideal,
    /// [`ConstantPressure`] (`"constant"`).
    Constant,
    /// [`Pump`] (`"pump"`).
    Pump,
    /// [`Polytropic`] (`"polytropic"`): `p V^gamma` constant.
    Polytropic,
    /// [`LeakyGas`] (`"leak"`): an ideal gas leaking in proportion to its gauge pressure.
    Leak,
    /// [`SupplyPump`] (`"supply-pump"`): a pump that stops at its supply pressure.
    SupplyPump,
}

impl FromStr for GasKind {
    type Err = GasError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "ideal" => Ok(Self::Ideal),
            "constant" => Ok(Self::Constant),
            "pump" => Ok(Self::Pump),
            "polytropic" | "adiabatic" => Ok(Self::Polytropic),
            "leak" => Ok(Self::Leak),
            "supply-pump" => Ok(Self::SupplyPump),
            _ => Err(GasError::UnknownKind(s.to_string())),
        }
    }
}

impl std::fmt::Display for GasKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Ideal => "ideal",
            Self::Constant => "constant",
            Self::Pump => "pump",
            Self::Polytropic => "polytropic",
            Self::Leak => "leak",
            Self::SupplyPump => "supply-pump",
        })
    }
}

/// Any of the built-in gas models, dispatching [`GasModel`] by `match` (no `dyn`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Gas {
    /// Isothermal ideal gas.
    Ideal(IdealGas),
    /// Constant pressure.
    Constant(ConstantPressure),
    /// Pump.
    Pump(Pump),
    /// Polytropic (adiabatic) gas.
    Polytropic(Polytropic),
    /// Leaking ideal gas.
    Leak(LeakyGas),
    /// Pump with a supply pressure.
    SupplyPump(SupplyPump),
}

impl Gas {
    /// Which kind this is.
    pub fn kind(&self) -> GasKind {
        match self {
            Self::Ideal(_) => GasKind::Ideal,
            Self::Constant(_) => GasKind::Constant,
            Self::Pump(_) => GasKind::Pump,
            Self::Polytropic(_) => GasKind::Polytropic,
            Self::Leak(_) => GasKind::Leak,
            Self::SupplyPump(_) => GasKind::SupplyPump,
        }
    }

    /// Builds a model of `kind` for a balloon whose rest volume is `rest_volume` (m^3):
    /// `Ideal` and `Constant` start at absolute pressure `ambient + gauge_pressure`; `Pump` starts
    /// at ambient pressure and adds `pump_rate` J/s (`gauge_pressure` is then unused). The laws
    /// of [`crate::laws`] take their parameters from [`GasLawParams::default`]; see
    /// [`Gas::try_from_kind_with`].
    pub fn try_from_kind(
        kind: GasKind,
        rest_volume: f64,
        gauge_pressure: f64,
        ambient_pressure: f64,
        pump_rate: f64,
    ) -> Result<Self, GasError> {
        Self::try_from_kind_with(
            kind,
            rest_volume,
            gauge_pressure,
            ambient_pressure,
            pump_rate,
            &GasLawParams::default(),
        )
    }

    /// [`Gas::try_from_kind`] with the parameters of the other gas laws: `Polytropic` starts at
    /// `ambient + gauge_pressure` with `law.gamma`; `Leak` is the ideal gas of `Ideal` leaking
    /// through `law.leak_conductance`; `SupplyPump` starts at ambient pressure, adds `pump_rate`
    /// J/s and stops at the gauge pressure `law.supply_pressure`.
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] for a parameter out of range, or naming
    /// `leak_conductance` / `supply_pressure` when the kind needs it and it is `None`.
    pub fn try_from_kind_with(
        kind: GasKind,
        rest_volume: f64,
        gauge_pressure: f64,
        ambient_pressure: f64,
        pump_rate: f64,
        law: &GasLawParams,
    ) -> Result<Self, GasError> {
        let required = |name: &'static str, v: Option<f64>| {
            v.ok_or(GasError::InvalidParameter {
                name,
                value: f64::NAN,
                requirement: "is required by this gas kind",
            })
        };
        Ok(match kind {
            GasKind::Ideal => Self::Ideal(IdealGas::try_from_gauge(
                gauge_pressure,
                ambient_pressure,
                rest_volume,
            )?),
            GasKind::Constant => Self::Constant(ConstantPressure::try_from_gauge(
                gauge_pressure,
                ambient_pressure,
            )?),
            GasKind::Pump => Self::Pump(Pump::try_from_rest(
                rest_volume,
                ambient_pressure,
                pump_rate,
            )?),
            GasKind::Polytropic => Self::Polytropic(Polytropic::try_new(
                gauge_pressure + ambient_pressure,
                rest_volume,
                law.gamma,
            )?),
            GasKind::Leak => {
                let ideal = IdealGas::try_new(gauge_pressure + ambient_pressure, rest_volume)?;
                Self::Leak(LeakyGas::try_new(
                    ideal.amount(),
                    ambient_pressure,
                    required("leak_conductance", law.leak_conductance)?,
                )?)
            }
            GasKind::SupplyPump => {
                let pump = Pump::try_from_rest(rest_volume, ambient_pressure, pump_rate)?;
                let supply = required("supply_pressure", law.supply_pressure)?;
                Self::SupplyPump(SupplyPump::try_new(
                    pump.initial_amount,
                    pump.rate,
                    supply + ambient_pressure,
                )?)
            }
        })
    }
}

/// The parameters of the gas laws beyond the isothermal ones ([`crate::laws`]), for
/// [`Gas::try_from_kind_with`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GasLawParams {
    /// Polytropic exponent `gamma` of [`GasKind::Polytropic`] (default 1.4: adiabatic air).
    pub gamma: f64,
    /// Leak conductance `C` of [`GasKind::Leak`], m^3/s (`dN/dt = -C (p - p_ambient)`; no
    /// default).
    pub leak_conductance: Option<f64>,
    /// Gauge supply pressure of [`GasKind::SupplyPump`], Pa (no default).
    pub supply_pressure: Option<f64>,
}

impl Default for GasLawParams {
    fn default() -> Self {
        Self {
            gamma: 1.4,
            leak_conductance: None,
            supply_pressure: None,
        }
    }
}

impl GasModel for Gas {
    fn absolute_pressure(&self, volume: f64, time: f64) -> f64 {
        match self {
            Self::Ideal(g) => g.absolute_pressure(volume, time),
            Self::Constant(g) => g.absolute_pressure(volume, time),
            Self::Pump(g) => g.absolute_pressure(volume, time),
            Self::Polytropic(g) => g.absolute_pressure(volume, time),
            Self::Leak(g) => g.absolute_pressure(volume, time),
            Self::SupplyPump(g) => g.absolute_pressure(volume, time),
        }
    }

    fn dpressure_dvolume(&self, volume: f64, time: f64) -> f64 {
        match self {
            Self::Ideal(g) => g.dpressure_dvolume(volume, time),
            Self::Constant(g) => g.dpressure_dvolume(volume, time),
            Self::Pump(g) => g.dpressure_dvolume(volume, time),
            Self::Polytropic(g) => g.dpressure_dvolume(volume, time),
            Self::Leak(g) => g.dpressure_dvolume(volume, time),
            Self::SupplyPump(g) => g.dpressure_dvolume(volume, time),
        }
    }

    fn potential(&self, volume: f64, time: f64) -> Option<f64> {
        match self {
            Self::Ideal(g) => g.potential(volume, time),
            Self::Constant(g) => g.potential(volume, time),
            Self::Pump(g) => g.potential(volume, time),
            Self::Polytropic(g) => g.potential(volume, time),
            Self::Leak(g) => g.potential(volume, time),
            Self::SupplyPump(g) => g.potential(volume, time),
        }
    }

    fn end_step(&mut self, volume: f64, time: f64) {
        match self {
            Self::Ideal(g) => g.end_step(volume, time),
            Self::Constant(g) => g.end_step(volume, time),
            Self::Pump(g) => g.end_step(volume, time),
            Self::Polytropic(g) => g.end_step(volume, time),
            Self::Leak(g) => g.end_step(volume, time),
            Self::SupplyPump(g) => g.end_step(volume, time),
        }
    }

    fn reset_reference(&mut self, volume: f64, time: f64) {
        match self {
            Self::Ideal(g) => g.reset_reference(volume, time),
            Self::Constant(g) => g.reset_reference(volume, time),
            Self::Pump(g) => g.reset_reference(volume, time),
            Self::Polytropic(g) => g.reset_reference(volume, time),
            Self::Leak(g) => g.reset_reference(volume, time),
            Self::SupplyPump(g) => g.reset_reference(volume, time),
        }
    }
}

impl From<IdealGas> for Gas {
    fn from(g: IdealGas) -> Self {
        Self::Ideal(g)
    }
}

impl From<ConstantPressure> for Gas {
    fn from(g: ConstantPressure) -> Self {
        Self::Constant(g)
    }
}

impl From<Pump> for Gas {
    fn from(g: Pump) -> Self {
        Self::Pump(g)
    }
}

impl From<Polytropic> for Gas {
    fn from(g: Polytropic) -> Self {
        Self::Polytropic(g)
    }
}

impl From<LeakyGas> for Gas {
    fn from(g: LeakyGas) -> Self {
        Self::Leak(g)
    }
}

impl From<SupplyPump> for Gas {
    fn from(g: SupplyPump) -> Self {
        Self::SupplyPump(g)
    }
}
