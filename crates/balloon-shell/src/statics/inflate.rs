//! A shell inflated statically to a volume and left holding its own gas:
//! [`ShellSimulation::inflate_to_volume`], how connected balloons are pre-inflated
//! ([`crate::connected`]).

use balloon_gas::Gas;

use super::{StaticControl, StaticOptions, StaticReport};
use crate::{ShellError, ShellMaterial, ShellSimulation};

impl<M: ShellMaterial> ShellSimulation<M, Gas> {
    /// Inflates the balloon statically to the enclosed volume `target` (m^3) and leaves it
    /// holding that gas: a static solve under volume control (the gauge pressure is the
    /// volume constraint's multiplier, [`StaticControl::Volume`]), then the isothermal ideal
    /// gas amount is set to `nRT = (p_ambient + p_gauge) V` (Wang et al. 2015, Eq. 12) so that
    /// the balloon is at rest at that volume with its own gas, ready to be connected. `options`
    /// gives the solver settings; its `control` is replaced by the volume target.
    ///
    /// To pre-inflate to a linear stretch `l` of a sphere, pass
    /// `target = l^3 * rest_gas_volume()`.
    ///
    /// ```
    /// use balloon_gas::{Gas, IdealGas, PressureLoad};
    /// use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
    /// use balloon_material::{Lame, StVenantKirchhoff};
    /// use balloon_shell::statics::StaticOptions;
    /// use balloon_shell::{ShellSimulation, ShellSystem};
    ///
    /// let mesh = balloon_mesh::generate::icosphere(0.1, 1)?;
    /// let x = mesh.positions_flat();
    /// let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
    /// let gas = Gas::Ideal(IdealGas::try_new(103_325.0, v0)?);
    /// let gas = PressureLoad::new(gas).with_ambient_pressure(101_325.0)?;
    /// let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
    /// let thickness = vec![3e-4; mesh.num_triangles()];
    /// let system =
    ///     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
    /// let integrator = BackwardEuler::new(BackwardEulerParams::default())?;
    /// let mut sim = ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10)?;
    /// let target = 1.2 * sim.rest_gas_volume();
    /// let report = sim.inflate_to_volume(target, &StaticOptions::default())?;
    /// assert!((sim.gas_volume() / target - 1.0).abs() < 1e-6);
    /// let amount = (sim.ambient_pressure() + report.gauge_pressure) * report.gas_volume;
    /// assert_eq!(sim.gas_amount(), Some(amount));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`ShellError::InvalidParameter`] when the gas is not the isothermal ideal gas or
    /// `target` is not positive and finite; the static solve's error when it fails (the
    /// simulation is then left as it was), [`ShellError::StaticNotConverged`] when it ends
    /// without meeting its tolerances.
    pub fn inflate_to_volume(
        &mut self,
        target: f64,
        options: &StaticOptions,
    ) -> Result<StaticReport, ShellError> {
        if self.gas_amount().is_none() {
            return Err(ShellError::InvalidParameter {
                name: "gas",
                value: format!("{:?}", self.gas().kind()).to_lowercase(),
                reason: "inflating to a volume and holding the gas needs the isothermal ideal \
                         gas (`gas` = ideal)"
                    .into(),
            });
        }
        if !(target.is_finite() && target > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "target",
                value: target.to_string(),
                reason: "the target volume must be positive and finite (m^3)".into(),
            });
        }
        let report = self.solve_static(&StaticOptions {
            control: StaticControl::Volume { target },
            ..*options
        })?;
        if !report.converged {
            return Err(ShellError::StaticNotConverged {
                outer_iterations: report.outer_iterations,
                newton_iterations: report.newton_iterations,
                residual: report.relative_residual,
                thickness_change: report.thickness_change,
                volume_error: report.volume_error,
            });
        }
        self.set_gas_amount((self.ambient_pressure() + report.gauge_pressure) * report.gas_volume)?;
        Ok(report)
    }
}
