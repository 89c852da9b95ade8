//! A saved state of a running shell: [`ShellSnapshot`], taken by
//! [`ShellSimulation::snapshot`] and put back by [`ShellSimulation::restore`] (to undo what a
//! user did to a run, or to try a step two ways from one state).

use balloon_gas::{GasModel, PressureLoad};
use balloon_integrate::decorators::Anchors;
use balloon_integrate::substep::AdaptiveSubsteps;

use super::{History, ShellError, ShellSimulation};
use crate::ShellMaterial;

/// The state of a [`ShellSimulation`] at one moment: positions, velocities, thickness, the gas
/// (its amount, pump content and last state), time and step count, the time step and the
/// sub-step size reached, and the loads set from outside (external forces and anchor
/// springs). Not in it: the mesh, material and integrator settings (a snapshot is put back
/// into the simulation it came from) and the hard pins.
#[derive(Clone, Debug)]
pub struct ShellSnapshot<G: GasModel> {
    x: Vec<f64>,
    v: Vec<f64>,
    x_prev: Vec<f64>,
    thickness: Vec<f64>,
    history: History,
    gas: PressureLoad<G>,
    gas_volume: f64,
    time: f64,
    step: usize,
    dt: f64,
    substeps: AdaptiveSubsteps,
    external_forces: Vec<f64>,
    anchor_springs: Anchors,
}

impl<G: GasModel> ShellSnapshot<G> {
    /// Simulation time of the saved state, s.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Steps taken up to the saved state.
    pub fn steps_taken(&self) -> usize {
        self.step
    }
    /// Positions of the saved state, flat, m.
    pub fn positions(&self) -> &[f64] {
        &self.x
    }
}

impl<M: ShellMaterial, G: GasModel + Clone> ShellSimulation<M, G> {
    /// The current state ([`ShellSnapshot`]), to put back later with
    /// [`ShellSimulation::restore`].
    pub fn snapshot(&self) -> ShellSnapshot<G> {
        ShellSnapshot {
            x: self.x.clone(),
            v: self.v.clone(),
            x_prev: self.x_prev.clone(),
            thickness: self.system.thickness.clone(),
            history: self.history.clone(),
            gas: self.system.gas.clone(),
            gas_volume: self.gas_volume,
            time: self.time,
            step: self.step,
            dt: self.dt,
            substeps: self.substeps,
            external_forces: self.external_forces.clone(),
            anchor_springs: self.anchor_springs.clone(),
        }
    }

    /// Whether `snapshot` fits this simulation (its vertex and element counts).
    ///
    /// # Errors
    /// [`ShellError::InvalidParameter`] (`snapshot`) when it does not.
    pub fn check_snapshot(&self, snapshot: &ShellSnapshot<G>) -> Result<(), ShellError> {
        let elements = self.system.thickness.len();
        if snapshot.x.len() != self.x.len() || snapshot.thickness.len() != elements {
            return Err(ShellError::InvalidParameter {
                name: "snapshot",
                value: format!(
                    "{} vertices, {} elements",
                    snapshot.x.len() / 3,
                    snapshot.thickness.len()
                ),
                reason: format!(
                    "taken from another simulation: this one has {} vertices and {elements} \
                     elements",
                    self.x.len() / 3
                ),
            });
        }
        Ok(())
    }

    /// Puts back the state of `snapshot` (taken from this simulation): the run goes on from
    /// there as it did when the snapshot was taken. With the matrix-free solver, which keeps
    /// nothing between steps, it repeats bit for bit (tested); a solver that keeps a factor
    /// or the last matrix starts from what the steps in between left, so the run repeats to
    /// the Newton tolerance. The integrator forgets what its last step left for the next
    /// ([`balloon_integrate::implicit::BackwardEuler::forget_last_step`]).
    ///
    /// # Errors
    /// [`ShellError::InvalidParameter`] (`snapshot`) when the snapshot has another number of
    /// vertices or elements than this simulation; nothing changes then.
    pub fn restore(&mut self, snapshot: &ShellSnapshot<G>) -> Result<(), ShellError> {
        self.check_snapshot(snapshot)?;
        self.x.clone_from(&snapshot.x);
        self.v.clone_from(&snapshot.v);
        self.x_prev.clone_from(&snapshot.x_prev);
        self.system.thickness.clone_from(&snapshot.thickness);
        self.history = snapshot.history.clone();
        self.system.gas = snapshot.gas.clone();
        self.gas_volume = snapshot.gas_volume;
        self.time = snapshot.time;
        self.step = snapshot.step;
        self.dt = snapshot.dt;
        self.substeps = snapshot.substeps;
        self.external_forces.clone_from(&snapshot.external_forces);
        self.anchor_springs = snapshot.anchor_springs.clone();
        self.integrator.forget_last_step();
        Ok(())
    }
}
