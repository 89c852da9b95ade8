//! The live gas controls of a running shell with a built-in gas ([`Gas`]): the gauge pressure,
//! the amount of an ideal gas, the pump rate.

use balloon_gas::Gas;

use super::{ShellError, ShellSimulation};
use crate::ShellMaterial;

impl<M: ShellMaterial> ShellSimulation<M, Gas> {
    /// Changes the gas while the simulation runs (the pressure control of the live viewer):
    /// for a constant-pressure gas the held gauge pressure becomes `gauge` (Pa); for the ideal
    /// gas the amount `nRT = p0 V0` (Eq. 12, 14) is set so that the gas would have gauge pressure
    /// `gauge` at the rest volume, `nRT = (p_ambient + gauge) V_rest` (likewise the polytropic
    /// invariant and the leaking gas's amount, which then leaks from now on); for the supply
    /// pump it is the supply pressure; for the pump it is an error (use
    /// [`ShellSimulation::set_pump_rate`]). The absolute pressure must stay positive.
    pub fn set_gauge_pressure(&mut self, gauge: f64) -> Result<(), ShellError> {
        let ambient = self.system.gas.ambient_pressure();
        let p_abs = ambient + gauge;
        if !(gauge.is_finite() && p_abs > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "gauge_pressure",
                value: gauge.to_string(),
                reason: format!("the absolute pressure {ambient} Pa + gauge must be positive"),
            });
        }
        let rest_volume = self.rest_gas_volume;
        match self.system.gas.gas_mut() {
            Gas::Constant(c) => c.pressure = p_abs,
            Gas::Ideal(g) => g.initial_pressure = p_abs * rest_volume / g.initial_volume,
            Gas::Polytropic(g) => {
                g.initial_pressure = p_abs * (rest_volume / g.initial_volume).powf(g.gamma);
            }
            Gas::Leak(g) => {
                g.amount = p_abs * rest_volume;
                g.time = self.time;
            }
            Gas::SupplyPump(g) => g.supply_pressure = p_abs,
            Gas::Pump(_) => {
                return Err(ShellError::InvalidParameter {
                    name: "gauge_pressure",
                    value: gauge.to_string(),
                    reason: "the pump gas has no set pressure; change its pump rate".into(),
                });
            }
        }
        Ok(())
    }

    /// The amount of an isothermal ideal gas, `nRT = p V` (J; Wang et al. 2015, Eq. 12), or `None` for
    /// the other gases.
    pub fn gas_amount(&self) -> Option<f64> {
        match self.system.gas.gas() {
            Gas::Ideal(g) => Some(g.amount()),
            _ => None,
        }
    }

    /// The ambient (outside) pressure, Pa.
    pub fn ambient_pressure(&self) -> f64 {
        self.system.gas.ambient_pressure()
    }

    /// Sets the amount `nRT` (J, positive and finite) of an isothermal ideal gas from now on
    /// (gas let in or out between steps, as [`ConnectedBalloons`](crate::connected::ConnectedBalloons) does); the pressure
    /// at volume `V` becomes `amount / V`. Errors for the other gases.
    pub fn set_gas_amount(&mut self, amount: f64) -> Result<(), ShellError> {
        if !(amount.is_finite() && amount > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "gas_amount",
                value: amount.to_string(),
                reason: "must be a positive, finite amount nRT in J".into(),
            });
        }
        match self.system.gas.gas_mut() {
            Gas::Ideal(g) => {
                g.initial_pressure = amount / g.initial_volume;
                Ok(())
            }
            _ => Err(ShellError::InvalidParameter {
                name: "gas_amount",
                value: amount.to_string(),
                reason: "only the isothermal ideal gas (`gas` = ideal) has a settable amount"
                    .into(),
            }),
        }
    }

    /// Changes the pump rate (m^3/s of ambient air, >= 0) of a [`Gas::Pump`] gas from now
    /// on: the gas content pumped so far is kept and grows by `p_ambient * rate` J/s from the
    /// current time. Errors for the other gases.
    pub fn set_pump_rate(&mut self, rate: f64) -> Result<(), ShellError> {
        if !(rate.is_finite() && rate >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "pump_rate",
                value: rate.to_string(),
                reason: "must be a finite flow >= 0 m^3/s".into(),
            });
        }
        let now = self.time;
        let ambient = self.system.gas.ambient_pressure();
        match self.system.gas.gas_mut() {
            Gas::Pump(p) => {
                p.initial_amount = p.amount(now);
                p.start_time = now;
                p.rate = rate * ambient;
                Ok(())
            }
            _ => Err(ShellError::InvalidParameter {
                name: "pump_rate",
                value: rate.to_string(),
                reason: "only the pump gas has a pump rate".into(),
            }),
        }
    }
}
