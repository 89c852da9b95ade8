//! The shell scenario's checks: every key's range and the keys that go together.

use super::keys::SHELL_KEYS;
use super::types::{SHELL_COLORS, ShellScenario};
use crate::error::ScenarioError;
use crate::gas::GasControl;

impl ShellScenario {
    /// Checks every value against its range and the keys together (the material, the gas
    /// laws, the static solve's gas, the pictures), before anything is read or built. Errors
    /// name the parameters in backticks and their values.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        crate::keys::check_all(SHELL_KEYS, self)?;
        self.check_together().map_err(ScenarioError::Invalid)
    }

    /// The checks of [`ShellScenario::validate`] across keys.
    pub(crate) fn check_together(&self) -> Result<(), String> {
        self.shell.material.resolve()?;
        self.mesh.check_transform()?;
        if self.shell.thickness_file.is_some() && self.shell.thickness_rule.is_some() {
            return Err(
                "`thickness_file` and `thickness_rule` are two thickness maps: give one".into(),
            );
        }
        self.output.check_pictures("inflate", SHELL_COLORS)?;
        if self.output.frame_every == 0 && self.run.steps == 0 {
            return Err("nothing to do: `steps` is 0".into());
        }
        let gas = self.gas.model;
        if !self.run.static_solve && gas == GasControl::Volume {
            return Err("`gas` = volume is a static control: add `static`".into());
        }
        if !self.run.static_solve && self.run.stability {
            return Err(
                "`stability` reports the eigenvalues of a static equilibrium: add `static`".into(),
            );
        }
        self.gas.laws.params(gas)?;
        if self.run.static_solve {
            self.static_points()?;
        }
        Ok(())
    }

    /// The points of a static solve: one volume ratio each (`None`: the gas holds the load),
    /// or why the gas and the volume keys do not make a static solve.
    pub fn static_points(&self) -> Result<Vec<Option<f64>>, String> {
        let gas = self.gas.model;
        if matches!(gas, GasControl::Pump | GasControl::SupplyPump) {
            // The amount of a pump at the start is the rest amount: the equilibrium is the mesh
            // itself, a run that "succeeds" with nothing solved.
            return Err(format!(
                "`static` with `gas` = {gas} solves at the gas amount at the start, which is the \
                 rest amount (no gauge pressure): the rest shape would be the mesh itself. For an \
                 inflated rest shape give `gas` = constant `pressure` = P (a gauge pressure, Pa), \
                 `gas` = ideal `pressure` = P (that gauge pressure in the rest volume, then \
                 expanding), or `gas` = volume `volume_ratio` = R"
            ));
        }
        let ratios: Vec<Option<f64>> = match (gas, self.gas.volume_ratio, &self.gas.volume_ratios) {
            (GasControl::Volume, Some(r), None) => vec![Some(r)],
            (GasControl::Volume, None, Some(list)) => list.0.iter().map(|r| Some(*r)).collect(),
            (GasControl::Volume, Some(_), Some(_)) => {
                return Err("give either `volume_ratio` or `volume_ratios`, not both".into());
            }
            (GasControl::Volume, None, None) => {
                return Err(
                    "`gas` = volume needs `volume_ratio` R or `volume_ratios` START:END:STEP"
                        .into(),
                );
            }
            (_, None, None) => vec![None],
            _ => return Err("`volume_ratio` and `volume_ratios` need `gas` = volume".into()),
        };
        if let Some(r) = ratios
            .iter()
            .flatten()
            .find(|r| !(r.is_finite() && **r > 0.0))
        {
            return Err(format!("invalid volume ratio {r}: must be positive"));
        }
        Ok(ratios)
    }
}
