//! The live controls of a running shell, applied from the next step on: the time step, the
//! integrator's parameters and linear solver, external forces, anchor springs and hard pins.
//! The gas controls of the built-in gases are in `gas.rs`.

use balloon_gas::GasModel;
use balloon_integrate::decorators::{AnchorSpring, Anchors};
use balloon_integrate::implicit::BackwardEulerParams;

use super::pins::Pins;
use super::{ShellError, ShellSimulation, check_dt};
use crate::ShellMaterial;

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Edits the integrator's parameters from the next step on (`edit` gets a copy); refused,
    /// with nothing changed, when an edited parameter is out of range
    /// ([`BackwardEulerParams::validate`]).
    pub fn configure_integrator(
        &mut self,
        edit: impl FnOnce(&mut BackwardEulerParams),
    ) -> Result<(), ShellError> {
        let mut params = *self.integrator.params();
        edit(&mut params);
        self.integrator
            .set_params(params)
            .map_err(ShellError::from_integrator_setup)
    }
    /// Solves Newton's linear systems with `solver` from the next step on: any
    /// [`balloon_integrate::linear::LinearSolver`], the library's own (`CholeskySolver`,
    /// `FactorizedPcg`, `AssembledPcg`, `MatrixFreeCg`) or a user's type. It stays until
    /// [`ShellSimulation::use_configured_linear_solver`].
    pub fn set_linear_solver(&mut self, solver: Box<dyn balloon_integrate::linear::LinearSolver>) {
        self.integrator.set_linear_solver(solver);
    }
    /// Goes back to the linear solver the integrator parameters name.
    pub fn use_configured_linear_solver(&mut self) {
        self.integrator.use_configured_linear_solver();
    }

    /// Sets external forces (N) per degree of freedom, flat `[fx0, fy0, fz0, ...]`, applied in
    /// every following step as the `f_ext` of backward Euler (Eq. 18-19) until changed; `None`
    /// removes them. Used by the live viewer for grabbing and pinching. The length must be
    /// `3 * vertices` and every value finite.
    pub fn set_external_forces(&mut self, forces: Option<&[f64]>) -> Result<(), ShellError> {
        match forces {
            None => self.external_forces.clear(),
            Some(f) => {
                if f.len() != self.x.len() {
                    return Err(ShellError::InvalidParameter {
                        name: "external_forces",
                        value: format!("{} values", f.len()),
                        reason: format!("need 3 per vertex ({})", self.x.len()),
                    });
                }
                if let Some(i) = f.iter().position(|v| !v.is_finite()) {
                    return Err(ShellError::InvalidParameter {
                        name: "external_forces",
                        value: f[i].to_string(),
                        reason: format!("component {i} must be finite"),
                    });
                }
                self.external_forces.clear();
                self.external_forces.extend_from_slice(f);
            }
        }
        Ok(())
    }

    /// The external forces set by [`ShellSimulation::set_external_forces`] (empty when none).
    pub fn external_forces(&self) -> &[f64] {
        &self.external_forces
    }

    /// Whether each solve uses the thickness extrapolated linearly to the end of its step
    /// (`Some(true)`) or the thickness at its start (`Some(false)`, Wang et al. 2015,
    /// Algorithm 1, and `None`, the default). Not the default yet: it changes every default
    /// result by the splitting error, costs 1.5 to 3 times the Newton iterations of a
    /// pumped run (3.3 times on a pressurised Teddy), and a pressurised shell overshoots
    /// slightly where the lagged thickness creeps (`docs/benchmarks.md`). The shell-volume
    /// projection after the solve thins the wall by what the step stretched it (Eq. 24-28),
    /// so a solve with the thickness at its start sees a wall one step thicker than at its end: a splitting error of first order in `dt`, which
    /// raises the pressure of a slowly pumped balloon at 10 ms steps by several per cent
    /// against 2 ms steps (`docs/benchmarks.md`). With the prediction the solve uses
    /// `h_{n+1} ~ 2 h_n - h_{n-1}` (clamped to `[h_n / 2, 2 h_n]`; after a step of the same
    /// size, `h_n` otherwise), and where the projection's thickness then differs from it by
    /// more than 1e-3, or than a hundredth of the step's own change of the thickness
    /// (relative, at any element), the step is solved again, first with the projection's
    /// thickness, then with secant steps on the fixed point, up to eight solves in all: the
    /// solve and the projection agree on the thickness at the end of the step. The projection itself starts from the thickness
    /// of `t_n` either way. Membranes (whose thickness follows their stretch) and runs
    /// without a projection are not affected.
    pub fn set_thickness_prediction(&mut self, on: impl Into<Option<bool>>) {
        self.thickness_prediction = on.into();
    }

    /// Whether the solves use the predicted thickness, as resolved for the current
    /// integrator parameters ([`ShellSimulation::set_thickness_prediction`]).
    pub fn thickness_prediction(&self) -> bool {
        self.thickness_prediction.unwrap_or(false)
    }

    /// Changes the time step (s, positive and finite) for the following steps. The sub-step
    /// size reached so far (the old `dt`, or less after a hard step) is kept: a larger `dt` is
    /// reached by doubling it after easy sub-steps (see [`EASY_NEWTON_ITERATIONS`](balloon_integrate::substep::EASY_NEWTON_ITERATIONS)), a smaller
    /// one caps it at once.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), ShellError> {
        self.dt = check_dt(dt)?;
        Ok(())
    }

    /// Replaces the anchor springs acting in the following steps (an empty list removes them):
    /// zero-length springs from vertices to fixed points, integrated implicitly with the shell
    /// (backward Euler, Eq. 18-23) so stiff springs stay stable
    /// ([`balloon_integrate::decorators::Anchored`]). The live viewer grabs and pinches the
    /// shell with them. Every vertex must exist, every anchor be finite and every stiffness
    /// finite and >= 0.
    pub fn set_anchor_springs(&mut self, springs: Vec<AnchorSpring>) -> Result<(), ShellError> {
        self.anchor_springs = Anchors::new(self.x.len() / 3, springs)
            .map_err(|e| ShellError::from_decorator("anchor_springs", e))?;
        Ok(())
    }

    /// The anchor springs set by [`ShellSimulation::set_anchor_springs`].
    pub fn anchor_springs(&self) -> &[AnchorSpring] {
        self.anchor_springs.springs()
    }

    /// Pins `vertices` hard from the next step on (an empty list frees them): a pinned vertex
    /// does not move at all. Its degrees of freedom are removed from the backward Euler solve
    /// (Eq. 18-23: zero residual, identity rows and columns of the Newton matrix, zero
    /// velocity; [`balloon_integrate::decorators::Pinned`]) and from the shell-volume
    /// projection (Algorithm 2: zero inverse mass), so its position stays bit for bit what it
    /// was. Duplicates are ignored; every vertex must exist. The static solve
    /// ([`ShellSimulation::solve_static`]) keeps them in place too.
    ///
    /// ```
    /// use balloon_constraint::shell_volume::{ShellVolumeParams, ShellVolumeProjection};
    /// use balloon_gas::{IdealGas, PressureLoad};
    /// use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
    /// use balloon_material::{Lame, StVenantKirchhoff};
    /// use balloon_shell::{ShellSimulation, ShellSystem};
    ///
    /// let mesh = balloon_mesh::generate::icosphere(0.1, 2)?;
    /// let x = mesh.positions_flat();
    /// let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
    /// let gas = PressureLoad::new(IdealGas::try_new(104_325.0, v0)?)
    ///     .with_ambient_pressure(101_325.0)?;
    /// let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
    /// let thickness = vec![3e-4; mesh.num_triangles()];
    /// let system =
    ///     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
    /// let integrator = BackwardEuler::new(BackwardEulerParams::default())?;
    /// let projection = ShellVolumeProjection::new(ShellVolumeParams::default());
    /// let mut sim =
    ///     ShellSimulation::new(system, x, 950.0, integrator, Some(Box::new(projection)), 0.01, 10)?;
    /// let bottom: Vec<usize> = (0..sim.positions().len() / 3)
    ///     .filter(|&v| sim.positions()[3 * v + 2] < -0.09)
    ///     .collect();
    /// sim.set_pinned_vertices(bottom.clone())?;
    /// let before = sim.positions().to_vec();
    /// for _ in 0..5 {
    ///     sim.step()?;
    /// }
    /// for &v in &bottom {
    ///     assert_eq!(sim.positions()[3 * v..3 * v + 3], before[3 * v..3 * v + 3]);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_pinned_vertices(&mut self, vertices: Vec<usize>) -> Result<(), ShellError> {
        self.pins = Pins::new(vertices, &self.vertex_inv_mass)
            .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
        for &p in self.pins.dofs.vertices() {
            self.v[3 * p..3 * p + 3].fill(0.0);
        }
        Ok(())
    }

    /// The hard-pinned vertices ([`ShellSimulation::set_pinned_vertices`]), sorted.
    pub fn pinned_vertices(&self) -> &[usize] {
        self.pins.dofs.vertices()
    }
}
