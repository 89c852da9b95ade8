//! A running shell balloon: [`ShellSimulation`] (Wang et al. 2015, "Cute Balloons with
//! Thickness", Algorithms 1 and 2).
//!
//! Each step solves backward Euler with Newton-Raphson (Eq. 18-23) on the [`ShellSystem`]
//! (wrapped by the anchor and pin decorators of `balloon_integrate::decorators` when set), then
//! the shell-volume projection (Eq. 24-28, Algorithm 2, any [`ShellProjector`]) restores the
//! material volume by moving the vertices and the thickness, and the velocities become
//! `(x_new - x_old) / dt` (Algorithm 1, lines 11-12). A step that fails numerically is rolled
//! back and retried in halved sub-steps ([`balloon_integrate::substep::AdaptiveSubsteps`]).
//!
//! One concern per file: `mod.rs` the state, its constructor and accessors; `step.rs` the step;
//! `substeps.rs` the sub-step driver; `substep.rs` one sub-step and the state check; `controls.rs`
//! and `gas.rs` the live controls; `pins.rs` the hard pins; `snapshot.rs` a saved state to go
//! back to; `stats.rs` the statistics; `error.rs` the error. The static rest shape is
//! [`crate::statics`].
//!
//! ```
//! use balloon_gas::{IdealGas, PressureLoad};
//! use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
//! use balloon_material::{Lame, StVenantKirchhoff};
//! use balloon_shell::{ShellSimulation, ShellSystem};
//!
//! let mesh = balloon_mesh::generate::icosphere(0.1, 2)?;
//! let x = mesh.positions_flat();
//! let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
//! // Latex 0.3 mm thick, an ideal gas 2 kPa over the atmosphere.
//! let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
//! let gas = PressureLoad::new(IdealGas::try_new(103_325.0, v0)?).with_ambient_pressure(101_325.0)?;
//! let thickness = vec![3e-4; mesh.num_triangles()];
//! let system =
//!     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
//! let mut params = BackwardEulerParams::default();
//! params.mass_damping = 10.0;
//! let integrator = BackwardEuler::new(params)?;
//! // No projection (`None`); `ShellVolumeProjection` of `balloon-constraint` is the paper's.
//! let mut sim = ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10)?;
//! for _ in 0..3 {
//!     sim.step()?;
//! }
//! assert!(sim.gas_volume() > v0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod controls;
mod error;
mod gas;
mod pins;
mod snapshot;
mod stats;
mod step;
mod substep;
mod substeps;
#[cfg(test)]
mod tests;

pub use error::{RUNAWAY_VOLUME_FACTOR, ShellError, check_dt};
pub use snapshot::ShellSnapshot;
pub use stats::ShellStepStats;

use balloon_constraint::projector::ShellProjector;
use balloon_constraint::shell_volume::shell_volume;
use balloon_gas::{Gas, GasModel};
use balloon_integrate::ForceSystem;
use balloon_integrate::decorators::Anchors;
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::substep::AdaptiveSubsteps;
use balloon_material::MaterialModel;
use balloon_mesh::TriMesh;
use nalgebra::{Point3, Vector3};

use crate::{ShellMaterial, ShellSystem};

/// The thickness before the last accepted (sub-)step and its size.
#[derive(Clone, Debug, Default)]
pub(crate) struct History {
    pub(crate) thickness: Vec<f64>,
    /// `None` until a step was taken (and after anything that moved the state from outside).
    pub(crate) dt: Option<f64>,
}

/// A running shell balloon simulation (module docs).
#[derive(Debug)]
pub struct ShellSimulation<M: ShellMaterial = MaterialModel, G: GasModel = Gas> {
    pub(crate) system: ShellSystem<M, G>,
    pub(crate) integrator: BackwardEuler,
    pub(crate) projection: Option<Box<dyn ShellProjector>>,
    /// Rest material volume per element, `A0_e H_e` (m^3), for per-element projectors.
    pub(crate) rest_element_volumes: Vec<f64>,
    pub(crate) x: Vec<f64>,
    pub(crate) v: Vec<f64>,
    pub(crate) x_prev: Vec<f64>,
    /// Whether the solve uses the thickness extrapolated to the end of the step
    /// ([`ShellSimulation::set_thickness_prediction`]; `None`: off).
    pub(crate) thickness_prediction: Option<bool>,
    /// The thickness before the last accepted (sub-)step and its size (the thickness
    /// prediction's history).
    pub(crate) history: History,
    /// The velocities at the start of the (sub-)step (scratch: a step solved again starts
    /// from them).
    pub(crate) v_start: Vec<f64>,
    /// The thickness at `t_n` and the one the solve uses (scratch).
    pub(crate) h_n: Vec<f64>,
    pub(crate) h_used: Vec<f64>,
    pub(crate) vertex_inv_mass: Vec<f64>,
    pub(crate) element_inv_mass: Vec<f64>,
    pub(crate) rest_shell_volume: f64,
    pub(crate) rest_gas_volume: f64,
    /// Enclosed gas volume of the current positions (m^3), computed once per (sub-)step by the
    /// state check.
    pub(crate) gas_volume: f64,
    pub(crate) rest_positions: Vec<f64>,
    pub(crate) time: f64,
    pub(crate) step: usize,
    pub(crate) dt: f64,
    /// The sub-step controller: halvings allowed, the sub-step size reached, when it grows.
    pub(crate) substeps: AdaptiveSubsteps,
    /// External forces per degree of freedom (N), held constant over each step; empty = none.
    pub(crate) external_forces: Vec<f64>,
    /// Zero-length springs to fixed anchors, part of the implicit solve; empty = none.
    pub(crate) anchor_springs: Anchors,
    /// Hard pins: vertices removed from the solve (`pins.rs`); none by default.
    pub(crate) pins: pins::Pins,
    /// Wall-clock time of every shell-volume projection so far (also of sub-steps rolled
    /// back), ms: with [`BackwardEuler::phase_times`] the running total of
    /// [`ShellStepStats::times`].
    pub(crate) projection_ms: f64,
}

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// A simulation at rest from its parts: the `system` (elements, thickness, gas) at its
    /// `rest_positions` (flat, m, 3 per vertex), the shell's `density` (kg/m^3: the masses of
    /// the projection, [`ShellMaterial::projection_masses`], Eq. 27), the `integrator`, the
    /// `projector` run after every solve (`None`: none), the time step `dt` (s) and the most
    /// halvings of a step that fails numerically (`max_step_halvings`, `dt / 2^n` at the
    /// smallest; 0 reports the first failure).
    ///
    /// # Errors
    /// [`ShellError::InvalidParameter`] when `rest_positions` does not hold 3 coordinates per
    /// vertex of the system, `density` is not positive and finite or `dt` is not a valid
    /// time step ([`check_dt`]); [`ShellError::Gas`] when the enclosed volume of the rest
    /// shape cannot be computed.
    pub fn new(
        system: ShellSystem<M, G>,
        rest_positions: Vec<f64>,
        density: f64,
        integrator: BackwardEuler,
        projector: Option<Box<dyn ShellProjector>>,
        dt: f64,
        max_step_halvings: usize,
    ) -> Result<Self, ShellError> {
        let x = rest_positions;
        if x.len() != system.masses().len() {
            return Err(ShellError::InvalidParameter {
                name: "rest_positions",
                value: format!("{} values", x.len()),
                reason: format!("need 3 per vertex ({})", system.masses().len()),
            });
        }
        if !(density.is_finite() && density > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "density",
                value: density.to_string(),
                reason: "must be a positive finite number".into(),
            });
        }
        check_dt(dt)?;
        let nv = x.len() / 3;
        let mut vertex_proj_mass = vec![0.0; nv];
        let mut element_inv_mass = Vec::with_capacity(system.triangles().len());
        for (t, el) in system.triangles().iter().zip(system.elements()) {
            let (mp, m4) = system.material().projection_masses(el, density);
            for c in 0..3 {
                vertex_proj_mass[t[c]] += mp[c];
            }
            element_inv_mass.push(1.0 / m4);
        }
        let rest_gas_volume = balloon_gas::enclosed_volume(&x, system.triangles())?;
        let rest_shell_volume = shell_volume(system.triangles(), &x, &system.thickness);
        let vertex = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        // A0_e H_e, conserved per element by `ProjectionScope::PerElement`.
        let rest_element_volumes = system
            .triangles()
            .iter()
            .zip(&system.thickness)
            .map(|(t, h)| {
                0.5 * (vertex(t[1]) - vertex(t[0]))
                    .cross(&(vertex(t[2]) - vertex(t[0])))
                    .norm()
                    * h
            })
            .collect();
        Ok(Self {
            v: vec![0.0; x.len()],
            x_prev: x.clone(),
            thickness_prediction: None,
            history: History::default(),
            v_start: vec![0.0; x.len()],
            h_n: system.thickness.clone(),
            h_used: system.thickness.clone(),
            rest_positions: x.clone(),
            x,
            system,
            integrator,
            projection: projector,
            rest_element_volumes,
            vertex_inv_mass: vertex_proj_mass.iter().map(|m| 1.0 / m).collect(),
            element_inv_mass,
            rest_shell_volume,
            rest_gas_volume,
            gas_volume: rest_gas_volume,
            time: 0.0,
            step: 0,
            dt,
            substeps: AdaptiveSubsteps::new(max_step_halvings).with_size(dt),
            external_forces: Vec::new(),
            anchor_springs: Anchors::default(),
            pins: pins::Pins::default(),
            projection_ms: 0.0,
        })
    }

    /// Current positions, flat `[x0, y0, z0, ...]`, m.
    pub fn positions(&self) -> &[f64] {
        &self.x
    }
    /// Rest positions, flat, m.
    pub fn rest_positions(&self) -> &[f64] {
        &self.rest_positions
    }
    /// Current velocities, flat, m/s.
    pub fn velocities(&self) -> &[f64] {
        &self.v
    }
    /// Current thickness per element, m.
    pub fn thickness(&self) -> &[f64] {
        &self.system.thickness
    }
    /// Triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        self.system.triangles()
    }
    /// The current surface as a mesh.
    pub fn mesh(&self) -> TriMesh {
        TriMesh::new(
            self.x
                .chunks_exact(3)
                .map(|c| Point3::new(c[0], c[1], c[2]))
                .collect(),
            self.system.triangles().to_vec(),
        )
    }
    /// Simulation time, s.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Steps taken.
    pub fn steps_taken(&self) -> usize {
        self.step
    }
    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Enclosed gas volume at the rest shape, m^3.
    pub fn rest_gas_volume(&self) -> f64 {
        self.rest_gas_volume
    }
    /// Current enclosed gas volume, m^3.
    pub fn gas_volume(&self) -> f64 {
        self.gas_volume
    }
    /// Whether the Newton tangent includes the pressure follower term (the gas load's
    /// setting, `PressureLoad::with_follower_term`).
    pub fn follower_term(&self) -> bool {
        self.system.gas.follower_term()
    }
    /// Gauge pressure at the last force evaluation, Pa.
    pub fn gauge_pressure(&self) -> f64 {
        self.system.gas.state().gauge_pressure
    }
    /// The gas state at the last force evaluation.
    pub fn gas_state(&self) -> balloon_gas::GasState {
        self.system.gas.state()
    }
    /// Current shell material volume `sum_e A_e h_e` (Eq. 26), m^3.
    pub fn shell_volume(&self) -> f64 {
        shell_volume(self.system.triangles(), &self.x, &self.system.thickness)
    }
    /// Rest shell material volume, m^3.
    pub fn rest_shell_volume(&self) -> f64 {
        self.rest_shell_volume
    }
    /// The gas model (its kind and parameters, or the user's own model).
    pub fn gas(&self) -> &G {
        self.system.gas.gas()
    }
    /// The force system (for diagnostics: energies, forces).
    pub fn system(&self) -> &ShellSystem<M, G> {
        &self.system
    }
    /// The integrator's parameters (change them with [`ShellSimulation::configure_integrator`]).
    pub fn integrator_params(&self) -> &BackwardEulerParams {
        self.integrator.params()
    }
    /// Vertex lumped masses per degree of freedom, kg.
    pub fn masses(&self) -> &[f64] {
        self.system.masses()
    }
}
