//! Setting a shell run up from its scenario: the one place that turns a [`ShellScenario`] into
//! the builder calls of `balloon::shell::ShellBalloon`.

use super::types::{ProjectionMode, ShellScenario};
use crate::mesh::LoadError;
use crate::selection::{SelectionError, ShellLoads, apply::shell_anchors, thickness_map};
use balloon::constraint::shell_volume::{ProjectionScope, ShellVolumeParams};
use balloon::integrate::implicit::BackwardEulerParams;
use balloon::mesh::TriMesh;
use balloon::shell::statics::StaticOptions;
use balloon::shell::{
    self, ShellBalloon, ShellError, ShellMaterial, ShellMaterialModel, ShellSimulation,
};

/// The shell simulation a scenario builds.
pub type ShellSim = ShellSimulation<ShellMaterialModel>;

/// Why a shell scenario could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum ShellBuildError {
    /// The keys do not make a run (the message names them).
    #[error("{0}")]
    Invalid(String),
    /// The mesh cannot be loaded.
    #[error(transparent)]
    Mesh(#[from] LoadError),
    /// A thickness map, an anchor or a load cannot be used.
    #[error(transparent)]
    Selection(#[from] SelectionError),
    /// The builder refuses the balloon.
    #[error("cannot set up the balloon for `{mesh}`")]
    Setup {
        /// The mesh's path or built-in name.
        mesh: String,
        /// Why.
        #[source]
        source: ShellError,
    },
}

impl ShellScenario {
    /// The integrator of the run: `balloon::shell::default_integrator_params` with the
    /// scenario's Newton, damping and linear-solver keys.
    pub fn integrator_params(&self) -> BackwardEulerParams {
        let r = &self.run;
        let mut p = shell::default_integrator_params();
        p.newton_iterations = r.newton_iters;
        p.newton_tolerance = r.newton_tol;
        p.linear.kind = r.linear_solver;
        p.linear.max_iterations = r.cg_max_iters;
        p.linear.relative_tolerance = r.cg_tol;
        p.mass_damping = r.mass_damping;
        p.stiffness_damping = r.stiffness_damping;
        p.pcg_preconditioner = r.pcg_preconditioner;
        p.tangent = r.tangent;
        p.inexact_forcing = r.inexact_forcing;
        p
    }

    /// The options of a static solve (`static`, and the pre-inflation of connected balloons):
    /// the defaults with the scenario's Newton and linear-solver keys (a `newton_tol` of 0
    /// keeps the static solve's own tolerance).
    pub fn static_options(&self) -> StaticOptions {
        let r = &self.run;
        let mut options = StaticOptions::default();
        if r.newton_tol > 0.0 {
            options.solver.tolerance = r.newton_tol;
        }
        options.solver.tangent = r.tangent;
        options.solver.inexact_forcing = r.inexact_forcing;
        options.solver.solver.linear.kind = r.linear_solver;
        options.solver.solver.linear.max_iterations = r.cg_max_iters;
        options.solver.solver.pcg_preconditioner = r.pcg_preconditioner;
        options.stability = r.stability;
        options
    }

    /// The shell-volume projection: `volume_projection`, or global (off for a membrane, whose
    /// thickness already keeps every element's volume).
    pub fn projection(&self, membrane: bool) -> Option<ShellVolumeParams> {
        let mode = self.shell.volume_projection.unwrap_or(if membrane {
            ProjectionMode::Off
        } else {
            ProjectionMode::Global
        });
        match mode {
            ProjectionMode::Global => Some(Default::default()),
            ProjectionMode::PerElement => Some(ShellVolumeParams {
                scope: ProjectionScope::PerElement,
                ..Default::default()
            }),
            ProjectionMode::Off => None,
        }
    }

    /// The material of the run ([`crate::material::MaterialSpec::resolve`]).
    pub fn material(&self) -> Result<ShellMaterialModel, ShellBuildError> {
        self.shell
            .material
            .resolve()
            .map_err(ShellBuildError::Invalid)
    }

    /// Builds the shell balloon of this scenario: loads `mesh.path` (or takes `mesh`, an
    /// in-memory mesh such as the Python package's arrays), scales and moves it, and sets up the
    /// balloon (material, wall and thickness map, gas, integrator, projection, time step), its
    /// anchors and the loads of time 0. Returns the simulation and the anchors' springs and
    /// scheduled loads: call [`ShellLoads::before_step`] before every step to apply them.
    /// Writes nothing. Call [`ShellScenario::validate`] first: the ranges are not checked here.
    pub fn build(&self, mesh: Option<TriMesh>) -> Result<(ShellSim, ShellLoads), ShellBuildError> {
        let material = self.material()?;
        let membrane = material.thickness_follows_stretch();
        let mut mesh = match mesh {
            Some(m) => m,
            None => self.mesh.read()?,
        };
        self.mesh
            .place(&mut mesh)
            .map_err(ShellBuildError::Invalid)?;
        let name = &self.mesh.path;
        let laws = self
            .gas
            .laws
            .params(self.gas.model)
            .map_err(ShellBuildError::Invalid)?;
        let map = thickness_map(
            self.shell.thickness_file.as_deref(),
            self.shell.thickness_rule,
            name,
            &mesh,
        )?;
        let builder = match map {
            Some(map) => ShellBalloon::new(mesh).with_thickness_per_face(map),
            None => ShellBalloon::new(mesh).with_thickness(self.shell.thickness),
        };
        let builder = match self.gas.pump_rate {
            Some(rate) => builder.with_pump_rate(rate),
            None => builder.with_relative_pump_rate(shell::DEFAULT_PUMP_VOLUMES_PER_SECOND),
        };
        let mut sim = builder
            .with_material(material)
            .with_density(self.shell.density)
            .with_gas(self.gas.model.kind())
            .with_gauge_pressure(self.gas.pressure)
            .with_ambient_pressure(self.gas.ambient)
            .with_gas_law(laws)
            .with_follower_term(self.run.follower_term)
            .with_wall_bending(self.shell.bending)
            .with_thickness_prediction(self.run.thickness_prediction)
            .with_integrator(self.integrator_params())
            .with_projection(self.projection(membrane))
            .with_dt(self.run.dt)
            .build()
            .map_err(|source| ShellBuildError::Setup {
                mesh: name.clone(),
                source,
            })?;
        let loads = shell_anchors(
            &mut sim,
            &self.anchors,
            self.shell.pin_stiffness,
            &self.loads,
        )?;
        Ok((sim, loads))
    }
}
