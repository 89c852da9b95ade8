//! One interface for the three systems: [`Simulation`].
//!
//! The shell balloon ([`ShellSimulation`], Wang et al. 2015) and its connected sets
//! ([`ConnectedBalloons`]), the volume-conserving body ([`VolumetricSimulation`], Diziol, Bender
//! and Bayer 2011) and the two-layer body ([`TwoLayerSimulation`], Song 2009) are stepped, timed,
//! read and drawn the same way through this trait, so a run loop, a viewer or a benchmark is
//! written once for all of them:
//!
//! - [`Simulation::step`] advances one time step and returns [`SimulationStats`]: the numbers
//!   every system has (steps taken, time, the dt used, kinetic energy) plus the system's own
//!   statistics in [`SimulationStats::detail`];
//! - positions and velocities are flat `[x0, y0, z0, x1, ...]` slices in metres (m/s) for every
//!   system;
//! - [`Simulation::surface`] is what is drawn (triangles and the positions of their vertices);
//! - a failure is a [`SimulationError`], which keeps the system's own typed error.
//!
//! What the trait is not: it does not build systems (the builders do) and it does not hold the
//! system-specific controls (gas pressure, anchor springs, drag); those stay inherent methods of
//! each simulation, reachable from generic code that knows the concrete type.
//!
//! ```
//! use balloon::Simulation;
//! use balloon::two_layer::{ExplicitMethod, TwoLayerBody};
//!
//! /// Steps any system until `t_end` and returns the largest kinetic energy seen.
//! fn run<S: Simulation>(sim: &mut S, t_end: f64) -> Result<f64, balloon::SimulationError> {
//!     let mut peak = sim.kinetic_energy();
//!     while sim.time() < t_end {
//!         let stats = sim.step()?;
//!         peak = peak.max(stats.kinetic_energy);
//!     }
//!     Ok(peak)
//! }
//!
//! let mut sim = TwoLayerBody::circle(12)
//!     .with_gravity(9.81)
//!     .simulate(ExplicitMethod::Rk4, 1e-3)
//!     .unwrap();
//! let peak = run(&mut sim, 0.05).unwrap();
//! assert!(peak > 0.0);
//! assert_eq!(Simulation::steps(&sim), 50);
//! let surface = sim.surface();
//! assert_eq!(surface.positions.len(), Simulation::positions(&sim).len());
//! ```

use crate::two_layer::{TwoLayerError, TwoLayerSimulation, TwoLayerStats};
use crate::volumetric::{StepStats, VolumetricError, VolumetricSimulation};
use balloon_gas::GasModel;
use balloon_shell::connected::{ConnectedBalloons, ConnectedError, ConnectedStepStats};
use balloon_shell::{ShellError, ShellMaterial, ShellSimulation, ShellStepStats};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use thiserror::Error;

/// A failed step (or a rejected setting) of any system, keeping the system's own error.
///
/// Its message is the system error's message, unchanged.
#[derive(Debug, Error)]
pub enum SimulationError {
    /// A shell balloon failed.
    #[error(transparent)]
    Shell(#[from] ShellError),
    /// A volumetric body failed.
    #[error(transparent)]
    Volumetric(#[from] VolumetricError),
    /// A two-layer body failed.
    #[error(transparent)]
    TwoLayer(#[from] TwoLayerError),
    /// A set of connected balloons failed ([`ConnectedBalloons`]).
    #[error(transparent)]
    Connected(#[from] ConnectedError),
}

/// What one step did: the numbers every system has, and the system's own statistics in
/// `detail` (serialised as the system's stats rows are, e.g. in the CLI's `stats.jsonl`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulationStats<D> {
    /// Steps taken so far, this one included.
    pub steps: usize,
    /// Simulated time at the end of the step, s.
    pub time: f64,
    /// The time step this step covered, s (sub-steps, if any, are inside it).
    pub dt: f64,
    /// Kinetic energy `sum_i m_i |v_i|^2 / 2` at the end of the step, J (with the rigid sphere
    /// of a volumetric scene, if any).
    pub kinetic_energy: f64,
    /// The system's own statistics.
    pub detail: D,
}

/// The surface a system draws: triangles over the drawn vertices and their positions (flat, m).
///
/// For a shell it is the shell's mid-surface; for a volumetric body the input soup deformed with
/// the lattice (so its vertices are not the simulated particles); for a two-layer body both
/// layers (3D) or the band between them (2D).
#[derive(Clone, Debug, PartialEq)]
pub struct DrawnSurface<'a> {
    /// Positions of the drawn vertices, flat `[x0, y0, z0, ...]`, m.
    pub positions: Cow<'a, [f64]>,
    /// Triangles indexing the drawn vertices.
    pub triangles: Cow<'a, [[usize; 3]]>,
}

impl DrawnSurface<'_> {
    /// Number of drawn vertices.
    pub fn num_vertices(&self) -> usize {
        self.positions.len() / 3
    }
}

/// A running simulation of any of the three systems (see the [module docs](self)).
pub trait Simulation {
    /// The system's own per-step statistics (`ShellStepStats`, `StepStats`, `TwoLayerStats`).
    type Detail: Clone + std::fmt::Debug + Serialize;

    /// `shell`, `volumetric` or `two-layer`.
    fn name(&self) -> &'static str;
    /// Advances one time step. On error the system is left in a consistent state (rolled back to
    /// the start of the step, or, for the two-layer body, as the failed step left it) so what was
    /// written before stays valid.
    fn step(&mut self) -> Result<SimulationStats<Self::Detail>, SimulationError>;
    /// Simulated time, s.
    fn time(&self) -> f64;
    /// The time step of the following steps, s.
    fn dt(&self) -> f64;
    /// Changes the time step (positive and finite; each system may bound it further).
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError>;
    /// Steps taken since the start.
    fn steps(&self) -> usize;
    /// Simulated positions (shell vertices, lattice particles, two-layer particles), flat, m.
    fn positions(&self) -> &[f64];
    /// Simulated velocities, flat, m/s (same layout as [`Simulation::positions`]).
    fn velocities(&self) -> &[f64];
    /// Kinetic energy of the current state, J.
    fn kinetic_energy(&self) -> f64;
    /// The drawn surface of the current state.
    fn surface(&self) -> DrawnSurface<'_>;
}

/// Views points or vectors of `f64` as a flat slice (`[x0, y0, z0, x1, ...]`) without copying.
fn flat<T: bytemuck::Pod>(v: &[T]) -> &[f64] {
    bytemuck::cast_slice(v)
}

impl<M: ShellMaterial, G: GasModel> Simulation for ShellSimulation<M, G> {
    type Detail = ShellStepStats;

    fn name(&self) -> &'static str {
        "shell"
    }
    fn step(&mut self) -> Result<SimulationStats<ShellStepStats>, SimulationError> {
        let dt = ShellSimulation::dt(self);
        let detail = ShellSimulation::step(self)?;
        Ok(SimulationStats {
            steps: self.steps_taken(),
            time: detail.time,
            dt,
            kinetic_energy: Simulation::kinetic_energy(self),
            detail,
        })
    }
    fn time(&self) -> f64 {
        ShellSimulation::time(self)
    }
    fn dt(&self) -> f64 {
        ShellSimulation::dt(self)
    }
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError> {
        Ok(ShellSimulation::set_dt(self, dt)?)
    }
    fn steps(&self) -> usize {
        self.steps_taken()
    }
    fn positions(&self) -> &[f64] {
        ShellSimulation::positions(self)
    }
    fn velocities(&self) -> &[f64] {
        ShellSimulation::velocities(self)
    }
    fn kinetic_energy(&self) -> f64 {
        // `masses` holds the lumped vertex mass once per degree of freedom.
        0.5 * self
            .masses()
            .iter()
            .zip(ShellSimulation::velocities(self))
            .map(|(m, v)| m * v * v)
            .sum::<f64>()
    }
    fn surface(&self) -> DrawnSurface<'_> {
        DrawnSurface {
            positions: Cow::Borrowed(ShellSimulation::positions(self)),
            triangles: Cow::Borrowed(self.triangles()),
        }
    }
}

impl<M: ShellMaterial> Simulation for ConnectedBalloons<M> {
    type Detail = ConnectedStepStats;

    fn name(&self) -> &'static str {
        "connected"
    }
    fn step(&mut self) -> Result<SimulationStats<ConnectedStepStats>, SimulationError> {
        let dt = ConnectedBalloons::dt(self);
        let detail = ConnectedBalloons::step(self)?;
        Ok(SimulationStats {
            steps: ConnectedBalloons::steps(self),
            time: detail.time,
            dt,
            kinetic_energy: Simulation::kinetic_energy(self),
            detail,
        })
    }
    fn time(&self) -> f64 {
        ConnectedBalloons::time(self)
    }
    fn dt(&self) -> f64 {
        ConnectedBalloons::dt(self)
    }
    /// Sets the time step of every balloon ([`ConnectedBalloons::set_dt`]).
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError> {
        Ok(ConnectedBalloons::set_dt(self, dt)?)
    }
    fn steps(&self) -> usize {
        ConnectedBalloons::steps(self)
    }
    fn positions(&self) -> &[f64] {
        self.merged_positions()
    }
    fn velocities(&self) -> &[f64] {
        self.merged_velocities()
    }
    fn kinetic_energy(&self) -> f64 {
        self.balloons().iter().map(Simulation::kinetic_energy).sum()
    }
    fn surface(&self) -> DrawnSurface<'_> {
        DrawnSurface {
            positions: Cow::Borrowed(self.merged_positions()),
            triangles: Cow::Borrowed(self.merged_triangles()),
        }
    }
}

impl Simulation for VolumetricSimulation {
    type Detail = StepStats;

    fn name(&self) -> &'static str {
        "volumetric"
    }
    fn step(&mut self) -> Result<SimulationStats<StepStats>, SimulationError> {
        let dt = Simulation::dt(self);
        let detail = VolumetricSimulation::step(self)?;
        Ok(SimulationStats {
            steps: VolumetricSimulation::steps(self),
            time: detail.time,
            dt,
            kinetic_energy: detail.kinetic_energy,
            detail,
        })
    }
    fn time(&self) -> f64 {
        VolumetricSimulation::time(self)
    }
    fn dt(&self) -> f64 {
        self.body().params.dt
    }
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError> {
        Ok(VolumetricSimulation::set_dt(self, dt)?)
    }
    fn steps(&self) -> usize {
        VolumetricSimulation::steps(self)
    }
    fn positions(&self) -> &[f64] {
        flat(VolumetricSimulation::positions(self))
    }
    fn velocities(&self) -> &[f64] {
        flat(VolumetricSimulation::velocities(self))
    }
    fn kinetic_energy(&self) -> f64 {
        VolumetricSimulation::kinetic_energy(self)
    }
    fn surface(&self) -> DrawnSurface<'_> {
        let embedding = &self.lattice().embedding;
        let points = embedding.positions(VolumetricSimulation::positions(self));
        DrawnSurface {
            positions: Cow::Owned(flat(&points).to_vec()),
            triangles: Cow::Borrowed(&embedding.triangles),
        }
    }
}

impl Simulation for TwoLayerSimulation {
    type Detail = TwoLayerStats;

    fn name(&self) -> &'static str {
        "two-layer"
    }
    fn step(&mut self) -> Result<SimulationStats<TwoLayerStats>, SimulationError> {
        let dt = TwoLayerSimulation::dt(self);
        let detail = TwoLayerSimulation::step(self)?;
        Ok(SimulationStats {
            steps: detail.step,
            time: detail.time,
            dt,
            kinetic_energy: detail.kinetic,
            detail,
        })
    }
    fn time(&self) -> f64 {
        TwoLayerSimulation::time(self)
    }
    fn dt(&self) -> f64 {
        TwoLayerSimulation::dt(self)
    }
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError> {
        Ok(TwoLayerSimulation::set_dt(self, dt)?)
    }
    fn steps(&self) -> usize {
        self.step_count()
    }
    fn positions(&self) -> &[f64] {
        TwoLayerSimulation::positions(self)
    }
    fn velocities(&self) -> &[f64] {
        TwoLayerSimulation::velocities(self)
    }
    fn kinetic_energy(&self) -> f64 {
        self.energies().kinetic
    }
    fn surface(&self) -> DrawnSurface<'_> {
        DrawnSurface {
            positions: Cow::Borrowed(TwoLayerSimulation::positions(self)),
            triangles: Cow::Owned(self.model().draw_triangles()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gas::GasKind;
    use crate::shell::ShellBalloon;
    use crate::volumetric::{VolumetricBody, VolumetricParams, cube_soup};
    use balloon_mesh::lattice::LatticeParams;
    use nalgebra::Point3;

    /// Steps `sim` twice through the trait and checks what every system must agree on.
    fn check<S: Simulation>(sim: &mut S, name: &str) {
        assert_eq!(sim.name(), name);
        let n = sim.positions().len();
        assert_eq!(n % 3, 0);
        assert_eq!(sim.velocities().len(), n);
        let dt = sim.dt();
        let a = sim.step().unwrap();
        let b = sim.step().unwrap();
        assert_eq!((a.steps, b.steps, sim.steps()), (1, 2, 2), "{name}");
        assert_eq!(a.dt, dt);
        assert!(
            (b.time - 2.0 * dt).abs() < 1e-12 && sim.time() == b.time,
            "{name}"
        );
        assert!((b.kinetic_energy - sim.kinetic_energy()).abs() <= 1e-12 * b.kinetic_energy);
        let s = sim.surface();
        assert!(!s.triangles.is_empty());
        assert!(s.triangles.iter().flatten().all(|&i| i < s.num_vertices()));
        sim.set_dt(0.5 * dt).unwrap();
        assert_eq!(sim.dt(), 0.5 * dt);
        assert!(sim.set_dt(-1.0).is_err());
        assert_eq!(sim.dt(), 0.5 * dt);
        serde_json::to_string(&b).unwrap();
    }

    #[test]
    fn every_system_steps_through_the_trait() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        let mut shell = ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .build()
            .unwrap();
        check(&mut shell, "shell");
        // Positions and velocities are the shell's own flat arrays.
        assert_eq!(
            Simulation::positions(&shell).as_ptr(),
            shell.positions().as_ptr()
        );

        let params = VolumetricParams {
            lattice: LatticeParams {
                resolution: 8,
                voxels_per_cell: 2,
                smoothing_iterations: 0,
                ..LatticeParams::default()
            },
            gravity: [0.0, 0.0, -9.81],
            ..VolumetricParams::default()
        };
        let body = VolumetricBody::build(&cube_soup(Point3::origin(), 1.0), params).unwrap();
        let mut vol = VolumetricSimulation::new(body);
        check(&mut vol, "volumetric");
        // The flat view is the particles' coordinates, in order.
        let p = VolumetricSimulation::positions(&vol)[1];
        assert_eq!(&Simulation::positions(&vol)[3..6], &[p.x, p.y, p.z]);
        assert!(Simulation::kinetic_energy(&vol) > 0.0);

        let mut two = crate::two_layer::TwoLayerBody::octahedron_sphere(1)
            .with_gravity(9.81)
            .simulate(crate::two_layer::ExplicitMethod::Rk4, 1e-3)
            .unwrap();
        check(&mut two, "two-layer");
    }

    #[test]
    fn errors_keep_their_type_and_message() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        let mut shell = ShellBalloon::new(mesh).build().unwrap();
        let e = Simulation::set_dt(&mut shell, f64::NAN).unwrap_err();
        let direct = shell.set_dt(f64::NAN).unwrap_err();
        assert_eq!(e.to_string(), direct.to_string());
        assert!(matches!(
            e,
            SimulationError::Shell(ShellError::InvalidParameter { name: "dt", .. })
        ));
    }
}
