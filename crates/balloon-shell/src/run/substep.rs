//! One sub-step of a running shell: the implicit solve (backward Euler, Eq. 18-23, on the
//! shell wrapped by the anchor and pin decorators), the shell-volume projection (Eq. 24-28,
//! Algorithm 2), the velocity update (Algorithm 1, lines 11-12) and the check of the state
//! after it.

use balloon_constraint::projector::ShellProjectionInput;
use balloon_gas::GasModel;
use balloon_integrate::decorators::{Anchored, Pinned};
use balloon_integrate::implicit::StepInfo;

use super::{RUNAWAY_VOLUME_FACTOR, ShellError, ShellSimulation};
use crate::ShellMaterial;

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// One sub-step of `dt` from `time` (of step `step`, for the errors), from `x_prev`: the
    /// implicit solve, the thickness refresh and the projection, the velocities, the state
    /// check (which sets `gas_volume`). Returns the solve's information and the projection's
    /// iterations; on error the caller restores the state.
    pub(crate) fn step_inner(
        &mut self,
        step: usize,
        time: f64,
        dt: f64,
    ) -> Result<(StepInfo, usize), ShellError> {
        let gravity = self.integrator.params().gravity;
        let integrator = &mut self.integrator;
        let (x, v) = (&mut self.x, &mut self.v);
        let info = if self.pins.active() {
            let pins = &mut self.pins;
            pins.prepare(v, &self.external_forces, gravity);
            let external = (!pins.external.is_empty()).then_some(&pins.external[..]);
            if self.anchor_springs.is_empty() {
                let mut system = Pinned::new(&mut self.system, &mut pins.dofs)
                    .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            } else {
                let mut anchored = Anchored::new(&mut self.system, &self.anchor_springs)
                    .map_err(|e| ShellError::from_decorator("anchor_springs", e))?;
                let mut system = Pinned::new(&mut anchored, &mut pins.dofs)
                    .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        } else {
            let external = (!self.external_forces.is_empty()).then_some(&self.external_forces[..]);
            if self.anchor_springs.is_empty() {
                integrator.step(&mut self.system, time, dt, x, v, external)
            } else {
                let mut system = Anchored::new(&mut self.system, &self.anchor_springs)
                    .map_err(|e| ShellError::from_decorator("anchor_springs", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        }
        .map_err(|source| ShellError::Integrate { step, time, source })?;
        // A membrane's thickness is `H / (l1 l2)` of the new positions (a no-op for the
        // three-prism, whose thickness only the projection moves).
        self.system.refresh_thickness(&self.x);
        let mut proj_iters = 0;
        if let Some(proj) = &mut self.projection {
            let (triangles, thickness) = self.system.triangles_and_thickness_mut();
            let input = ShellProjectionInput {
                triangles,
                vertex_inverse_mass: if self.pins.active() {
                    &self.pins.vertex_inverse_mass
                } else {
                    &self.vertex_inv_mass
                },
                element_inverse_mass: &self.element_inv_mass,
                rest_shell_volume: self.rest_shell_volume,
                rest_element_volumes: &self.rest_element_volumes,
            };
            let started = std::time::Instant::now();
            let projected = proj.project(&input, &mut self.x, thickness);
            self.projection_ms += started.elapsed().as_secs_f64() * 1e3;
            let pi = projected.map_err(|source| ShellError::Projection { step, source })?;
            proj_iters = pi.iterations;
            self.system.refresh_thickness(&self.x);
        }
        // Algorithm 1, lines 11-12.
        for ((v, x), x0) in self.v.iter_mut().zip(&self.x).zip(&self.x_prev) {
            *v = (x - x0) / dt;
        }
        self.gas_volume = self.check_state(step, time)?;
        Ok((info, proj_iters))
    }

    /// Checks the state after a (sub-)step and returns the enclosed gas volume.
    pub(crate) fn check_state(&self, step: usize, time: f64) -> Result<f64, ShellError> {
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("position of vertex {}", i / 3),
                detail: "became NaN or infinite; reduce `dt`".into(),
            });
        }
        if let Some((e, h)) = self
            .system
            .thickness
            .iter()
            .enumerate()
            .find(|(_, h)| !(h.is_finite() && **h > 0.0))
        {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("thickness of element {e}"),
                detail: format!(
                    "{h:e} m is not positive; the element inverted or degenerated; reduce `dt` or the pressure"
                ),
            });
        }
        let vol =
            balloon_gas::enclosed_volume(&self.x, self.system.triangles()).unwrap_or(f64::NAN);
        // A surface that turned inside out (or a volume that is not a number) is a numerical
        // failure of the step, retried at a smaller sub-step; only growth beyond the runaway
        // factor is the physical runaway, which is not.
        if !(vol.is_finite() && vol > 0.0) {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: "gas volume".into(),
                detail: format!(
                    "{vol:e} m^3 (rest {:e} m^3) is not positive: the surface turned inside out or tangled; reduce `dt`",
                    self.rest_gas_volume
                ),
            });
        }
        if vol >= RUNAWAY_VOLUME_FACTOR * self.rest_gas_volume {
            return Err(ShellError::RunawayVolume {
                step,
                time,
                volume: vol,
                rest_volume: self.rest_gas_volume,
            });
        }
        Ok(vol)
    }
}
