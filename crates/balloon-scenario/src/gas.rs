//! The shell's gas (the `[gas]` table): how it is held (`model`) and the parameters of each
//! gas law, checked against the model ([`GasLaws::params`]).
//!
//! ```
//! use balloon_scenario::gas::{GasControl, GasLaws, VolumeRatios};
//! let laws = GasLaws { gamma: Some(1.2), ..GasLaws::default() };
//! assert_eq!(laws.params(GasControl::Polytropic).unwrap().gamma, 1.2);
//! assert_eq!(
//!     laws.params(GasControl::Pump).unwrap_err(),
//!     "`gamma` = 1.2 is a parameter of `gas` = polytropic, but `gas` is pump"
//! );
//! let r: VolumeRatios = "1:2:0.5".parse().unwrap();
//! assert_eq!(r.0, vec![1.0, 1.5, 2.0]);
//! ```

use crate::output::choices;
use balloon::gas::{GasKind, GasLawParams};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// How the gas is held (`model`): the gas laws, or a given volume (static solves only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum GasControl {
    /// Ambient air added at `pump_rate` from the rest shape (the amount at the current time
    /// for a static solve).
    #[default]
    Pump,
    /// Isothermal ideal gas, a fixed amount (Wang et al. 2015, Eq. 12-14).
    Ideal,
    /// A fixed pressure.
    Constant,
    /// Polytropic (adiabatic) gas, `p V^gamma` constant.
    Polytropic,
    /// Ideal gas leaking to ambient through `leak_conductance`.
    Leak,
    /// A pump at `pump_rate` that stops at `supply_pressure`.
    SupplyPump,
    /// A given enclosed volume (static solves only): the pressure is its Lagrange multiplier.
    Volume,
}

choices!(
    GasControl,
    "a gas model",
    [
        (GasControl::Pump, "pump"),
        (GasControl::Ideal, "ideal"),
        (GasControl::Constant, "constant"),
        (GasControl::Polytropic, "polytropic"),
        (GasControl::Leak, "leak"),
        (GasControl::SupplyPump, "supply-pump"),
        (GasControl::Volume, "volume"),
    ]
);

impl GasControl {
    /// The gas model the simulation is built with (volume control builds a constant-pressure
    /// gas at `pressure`, which the static solve does not use).
    pub fn kind(self) -> GasKind {
        match self {
            Self::Pump => GasKind::Pump,
            Self::Ideal => GasKind::Ideal,
            Self::Constant | Self::Volume => GasKind::Constant,
            Self::Polytropic => GasKind::Polytropic,
            Self::Leak => GasKind::Leak,
            Self::SupplyPump => GasKind::SupplyPump,
        }
    }
}

/// The parameters of the gas laws beyond the isothermal ones (`balloon::gas::laws`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GasLaws {
    /// Polytropic exponent of `polytropic`, `p V^gamma` constant (> 0) [default: 1.4].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Leak conductance of `leak`, m^3/s (>= 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leak_conductance: Option<f64>,
    /// Gauge supply pressure of `supply-pump`, Pa (> 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supply_pressure: Option<f64>,
}

impl GasLaws {
    /// The gas-law parameters for `gas`: each parameter only with its gas, the required ones
    /// present, every value in range; an error names the parameter and its value.
    pub fn params(&self, gas: GasControl) -> Result<GasLawParams, String> {
        let mut law = GasLawParams::default();
        let params = [
            ("gamma", self.gamma, GasControl::Polytropic),
            ("leak_conductance", self.leak_conductance, GasControl::Leak),
            (
                "supply_pressure",
                self.supply_pressure,
                GasControl::SupplyPump,
            ),
        ];
        for (name, value, owner) in params {
            if let Some(v) = value
                && gas != owner
            {
                return Err(format!(
                    "`{name}` = {v} is a parameter of `gas` = {owner}, but `gas` is {gas}"
                ));
            }
        }
        if let Some(g) = self.gamma {
            if !(g.is_finite() && g > 0.0) {
                return Err(format!(
                    "invalid `gamma` = {g}: the polytropic exponent must be positive and finite"
                ));
            }
            law.gamma = g;
        }
        match (gas, self.leak_conductance) {
            (GasControl::Leak, None) => {
                return Err("`gas` = leak needs `leak_conductance` C (m^3/s)".into());
            }
            (_, Some(c)) if !(c.is_finite() && c >= 0.0) => {
                return Err(format!(
                    "invalid `leak_conductance` = {c}: must be a finite conductance >= 0 m^3/s"
                ));
            }
            (_, c) => law.leak_conductance = c,
        }
        match (gas, self.supply_pressure) {
            (GasControl::SupplyPump, None) => {
                return Err("`gas` = supply-pump needs `supply_pressure` P (gauge, Pa)".into());
            }
            (_, Some(p)) if !(p.is_finite() && p > 0.0) => {
                return Err(format!(
                    "invalid `supply_pressure` = {p}: the gauge supply pressure must be positive"
                ));
            }
            (_, p) => law.supply_pressure = p,
        }
        Ok(law)
    }
}

/// Volume ratios of a static continuation `START:END:STEP` (to the rest volume), from START to
/// END inclusive in steps of STEP (either direction).
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeRatios(pub Vec<f64>);

impl FromStr for VolumeRatios {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let parts: Vec<&str> = s.split(':').collect();
        let bad =
            || format!("`{s}` is not START:END:STEP with positive ratios and a non-zero step");
        if parts.len() != 3 {
            return Err(bad());
        }
        let v: Vec<f64> = parts
            .iter()
            .map(|p| p.trim().parse::<f64>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        let (start, end, step) = (v[0], v[1], v[2]);
        let finite = [start, end, step].iter().all(|v| v.is_finite());
        if !(finite && start > 0.0 && end > 0.0 && step != 0.0) || (end - start) * step < 0.0 {
            return Err(bad());
        }
        if step.abs() < 1e-9 * start.max(end) {
            return Err(format!(
                "`{s}`: the step {step} is below 1e-9 of the ratios, so the points would not \
                 differ (or not beyond the solver's tolerance); give a larger STEP"
            ));
        }
        // Counted in f64 first: a tiny step must not overflow the count.
        let count = ((end - start) / step + 1e-9).floor() + 1.0;
        if count > 100_000.0 {
            return Err(format!("`{s}` asks for {count} points; at most 100000"));
        }
        let count = count as usize;
        Ok(Self((0..count).map(|i| start + i as f64 * step).collect()))
    }
}

impl fmt::Display for VolumeRatios {
    /// `START:END:STEP` of the points (the step of the first two; one point repeats itself).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = &self.0;
        match v.as_slice() {
            [] => Ok(()),
            [a] => write!(f, "{a:?}:{a:?}:1.0"),
            [a, b, ..] => write!(f, "{a:?}:{:?}:{:?}", v[v.len() - 1], b - a),
        }
    }
}

impl Serialize for VolumeRatios {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for VolumeRatios {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volume_ratios_parse_both_directions_and_reject_nonsense() {
        let p = |s: &str| s.parse::<VolumeRatios>().map(|r| r.0);
        assert_eq!(p("1:2:0.5").unwrap(), vec![1.0, 1.5, 2.0]);
        assert_eq!(p("3:2:-0.5").unwrap(), vec![3.0, 2.5, 2.0]);
        assert_eq!(p("1:1.05:0.1").unwrap(), vec![1.0]);
        for bad in ["1:2", "1:2:0", "2:1:0.5", "0:1:0.1", "a:b:c", "1:2:inf"] {
            assert!(p(bad).is_err(), "{bad}");
        }
        // A step that underflows: no overflowing count, no run of identical points.
        for tiny in ["1:2:1e-300", "1:1.0000000000000002:1e-17", "2:1:-1e-12"] {
            let e = p(tiny).unwrap_err();
            assert!(e.contains("would not differ"), "{tiny}: {e}");
        }
        assert!(p("1:3:1e-6").unwrap_err().contains("at most 100000"));
    }

    #[test]
    fn gas_law_parameters_belong_to_their_gas() {
        let leak = GasLaws::default().params(GasControl::Leak).unwrap_err();
        assert_eq!(leak, "`gas` = leak needs `leak_conductance` C (m^3/s)");
        let bad = GasLaws {
            supply_pressure: Some(-5.0),
            ..GasLaws::default()
        };
        assert!(
            bad.params(GasControl::SupplyPump)
                .unwrap_err()
                .starts_with("invalid `supply_pressure` = -5")
        );
    }
}
