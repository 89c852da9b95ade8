//! The closed set of built-in gas models: [`GasKind`] names one in a scenario file, [`Gas`]
//! holds any of them and dispatches [`GasModel`] by `match`, [`GasLawParams`] carries the
//! parameters of the laws beyond the isothermal ones ([`crate::laws`]).

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::GasError;
use crate::laws::{LeakyGas, Polytropic, SupplyPump};
use crate::model::{ConstantPressure, GasModel, IdealGas, Pump};

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

impl GasKind {
    /// Every kind, in documentation order.
    pub const ALL: [GasKind; 6] = [
        Self::Ideal,
        Self::Constant,
        Self::Pump,
        Self::Polytropic,
        Self::Leak,
        Self::SupplyPump,
    ];

    /// The name parsed by [`FromStr`] and written by [`Display`](std::fmt::Display), e.g.
    /// `supply-pump`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Constant => "constant",
            Self::Pump => "pump",
            Self::Polytropic => "polytropic",
            Self::Leak => "leak",
            Self::SupplyPump => "supply-pump",
        }
    }
}

impl std::fmt::Display for GasKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
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
