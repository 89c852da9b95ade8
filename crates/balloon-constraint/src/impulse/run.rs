//! A running impulse-stepped body ([`ImpulseRun`]): the state, the scene and the loads, stepped
//! on a borrowed [`CellBody`], with input checks and the statistics of every step
//! ([`StepStats`]).

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::stepper::{ImpulseModel, ImpulseParams, ImpulseState, ImpulseStepper};
use crate::ConstraintError;
use crate::cell_volume::{CellSprings, CellVolumeConstraints};
use crate::rigid::{Plane, RigidSphere};

/// The body an [`ImpulseRun`] steps, borrowed: particle masses and the cell constraints and
/// springs over them (all indexed like the run's particles).
#[derive(Clone, Copy, Debug)]
pub struct CellBody<'a> {
    /// Particle masses (kg).
    pub masses: &'a [f64],
    /// Cell-volume constraints.
    pub constraints: &'a CellVolumeConstraints,
    /// Cell springs.
    pub springs: &'a CellSprings,
}

/// Numbers reported after each step.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepStats {
    /// Step index (0-based) just completed.
    pub step: usize,
    /// Simulated time after the step (s).
    pub time: f64,
    /// Step halvings needed in this step.
    pub halvings: u32,
    /// Smallest sub-step used (s).
    pub min_dt: f64,
    /// Gauss-Seidel sweeps over all cells, or Newton iterations of the global solver (summed
    /// over sub-steps and contact rounds).
    pub sweeps: usize,
    /// Largest relative cell-volume error `|V - V0| / V0` after the step.
    pub max_cell_volume_error: f64,
    /// Total volume over rest volume.
    pub total_volume_ratio: f64,
    /// Total momentum of particles and sphere (kg m/s).
    pub momentum: [f64; 3],
    /// Total angular momentum of particles and sphere about the origin (kg m^2/s).
    pub angular_momentum: [f64; 3],
    /// Impulse from outside the body and sphere in this step (N s): gravity, external forces
    /// and the floor's contacts ([`super::ImpulseStepInfo::external_impulse`]).
    pub external_impulse: [f64; 3],
    /// Kinetic energy of particles and sphere (J).
    pub kinetic_energy: f64,
    /// Active contacts (summed over sub-steps and rounds).
    pub contacts: usize,
    /// Largest spring strain `|l / L0 - 1|` over all springs.
    pub max_strain: f64,
    /// The rigid sphere after the step (`None`, and left out of the JSON, without a sphere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sphere: Option<SphereStep>,
}

/// The rigid sphere's state after a step ([`StepStats::sphere`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SphereStep {
    /// Centre (m).
    pub centre: [f64; 3],
    /// Velocity (m/s).
    pub velocity: [f64; 3],
    /// Whether any particle touched the sphere during the step.
    pub contact: bool,
    /// Sphere-particle contacts resolved in the step (summed over sub-steps and contact
    /// rounds).
    pub contacts: usize,
    /// Impulse the body gave the sphere through the contacts in the step (N s); the body
    /// received the opposite.
    pub contact_impulse: [f64; 3],
}

/// A running impulse-stepped body without its [`CellBody`]: particle state, rigid sphere and
/// static planes, external forces and fixed particles, the step counters and the stepper's
/// caches. Every setter checks its input against the particle count.
///
/// ```
/// use balloon_constraint::cell_volume::{CellSprings, CellVolumeConstraints, CellVolumeParams, SpringParams};
/// use balloon_constraint::impulse::{CellBody, ImpulseParams, ImpulseRun};
/// use balloon_mesh::lattice::{LatticeParams, build_lattice};
/// let soup = balloon_mesh::generate::icosphere(0.5, 2).unwrap();
/// let lattice = build_lattice(&soup, &LatticeParams { resolution: 8, ..LatticeParams::default() }).unwrap();
/// let x = lattice.tet_mesh.vertices.clone();
/// let tets = lattice.cell_tets.iter().map(|ids| ids.map(|t| lattice.tet_mesh.tets[t])).collect();
/// let constraints = CellVolumeConstraints::new(lattice.cells.clone(), tets, &x, CellVolumeParams::default())?;
/// let springs = CellSprings::new(&lattice.cells, &x, &SpringParams::default());
/// let masses = vec![0.01; x.len()];
/// let body = CellBody { masses: &masses, constraints: &constraints, springs: &springs };
/// let mut run = ImpulseRun::at_rest(x);
/// run.set_fixed_particles(&[0])?;
/// let stats = run.step(body, &ImpulseParams::default(), 1e-3)?;
/// assert_eq!((stats.step, run.steps()), (0, 1));
/// assert!(stats.max_cell_volume_error <= 1e-10);
/// assert!(run.state().velocities[1].z < 0.0 && run.state().velocities[0].z == 0.0);
/// # Ok::<(), balloon_constraint::ConstraintError>(())
/// ```
#[derive(Clone, Debug)]
pub struct ImpulseRun {
    state: ImpulseState,
    planes: Vec<Plane>,
    /// External forces per particle (N) added in step 1 of every step; empty = none.
    external: Vec<Vector3<f64>>,
    /// Fixed (hard-anchored) particles, one flag each; empty = none.
    fixed: Vec<bool>,
    steps: usize,
    total_halvings: u64,
    stepper: ImpulseStepper,
}

impl ImpulseRun {
    /// Particles at `positions` (m) with zero velocities, no sphere, no planes, no loads.
    pub fn at_rest(positions: Vec<Point3<f64>>) -> Self {
        Self {
            state: ImpulseState::at_rest(positions),
            planes: Vec::new(),
            steps: 0,
            total_halvings: 0,
            external: Vec::new(),
            fixed: Vec::new(),
            stepper: ImpulseStepper::new(),
        }
    }

    /// Adds (or replaces) the rigid sphere.
    ///
    /// # Errors
    /// [`ConstraintError::InvalidSphere`] unless its mass and radius are positive and finite.
    pub fn set_sphere(&mut self, sphere: RigidSphere) -> Result<(), ConstraintError> {
        for (what, value) in [("mass", sphere.mass), ("radius", sphere.radius)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConstraintError::InvalidSphere { what, value });
            }
        }
        self.state.sphere = Some(sphere);
        Ok(())
    }

    /// Adds a static plane.
    pub fn add_plane(&mut self, plane: Plane) {
        self.planes.push(plane);
    }

    /// Sets all particle velocities (m/s).
    ///
    /// # Errors
    /// [`ConstraintError::LengthMismatch`] unless there is one per particle.
    pub fn set_velocities(&mut self, velocities: &[Vector3<f64>]) -> Result<(), ConstraintError> {
        check_len("velocities", velocities.len(), self.state.velocities.len())?;
        self.state.velocities.copy_from_slice(velocities);
        Ok(())
    }

    /// Sets external forces (N), one per particle, added to the cell-spring forces in step 1 of
    /// every following step (Eq. 1: `v += h F / m`) until changed; `None` removes them.
    ///
    /// # Errors
    /// [`ConstraintError::LengthMismatch`] unless there is one per particle,
    /// [`ConstraintError::InvalidParameter`] naming the particle of a non-finite force.
    pub fn set_external_forces(
        &mut self,
        forces: Option<&[Vector3<f64>]>,
    ) -> Result<(), ConstraintError> {
        match forces {
            None => self.external.clear(),
            Some(f) => {
                check_len("external forces", f.len(), self.state.positions.len())?;
                if let Some(i) = f.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
                    let value = f[i].iter().copied().find(|c| !c.is_finite());
                    return Err(ConstraintError::invalid(
                        format!("external force on particle {i}"),
                        value.unwrap_or(f64::NAN),
                        "every component must be finite",
                    ));
                }
                self.external.clear();
                self.external.extend_from_slice(f);
            }
        }
        Ok(())
    }

    /// Pins `particles` hard from now on (in addition to those pinned before): each keeps its
    /// current position and zero velocity, as if of infinite mass (see the module docs). An
    /// empty list changes nothing.
    ///
    /// # Errors
    /// [`ConstraintError::ParticleOutOfRange`] for an index that is not a particle.
    pub fn set_fixed_particles(&mut self, particles: &[usize]) -> Result<(), ConstraintError> {
        let n = self.state.positions.len();
        if let Some(&particle) = particles.iter().find(|&&i| i >= n) {
            return Err(ConstraintError::ParticleOutOfRange {
                what: "fixed particle",
                particle,
                particles: n,
            });
        }
        if particles.is_empty() {
            return Ok(());
        }
        self.fixed.resize(n, false);
        for &i in particles {
            self.fixed[i] = true;
            self.state.velocities[i] = Vector3::zeros();
        }
        Ok(())
    }

    /// The state: positions, velocities, the sphere and the simulated time.
    pub fn state(&self) -> &ImpulseState {
        &self.state
    }

    /// The static planes.
    pub fn planes(&self) -> &[Plane] {
        &self.planes
    }

    /// The external forces (empty when none).
    pub fn external_forces(&self) -> &[Vector3<f64>] {
        &self.external
    }

    /// One flag per particle, `true` for a fixed one, or empty when none is.
    pub fn fixed_particles(&self) -> &[bool] {
        &self.fixed
    }

    /// Steps completed.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Step halvings so far.
    pub fn total_halvings(&self) -> u64 {
        self.total_halvings
    }

    /// Total momentum of particles (masses `masses`, kg) and sphere (kg m/s).
    pub fn momentum(&self, masses: &[f64]) -> Vector3<f64> {
        let mut p: Vector3<f64> = self
            .state
            .velocities
            .iter()
            .zip(masses)
            .map(|(v, m)| v * *m)
            .sum();
        if let Some(s) = &self.state.sphere {
            p += s.momentum();
        }
        p
    }

    /// Total angular momentum `sum m x × v` of particles (masses `masses`, kg) and sphere about
    /// the origin (kg m^2/s).
    pub fn angular_momentum(&self, masses: &[f64]) -> Vector3<f64> {
        let mut l: Vector3<f64> = self
            .state
            .positions
            .iter()
            .zip(&self.state.velocities)
            .zip(masses)
            .map(|((x, v), m)| x.coords.cross(v) * *m)
            .sum();
        if let Some(s) = &self.state.sphere {
            l += s.position.coords.cross(&s.velocity) * s.mass;
        }
        l
    }

    /// Kinetic energy of particles (masses `masses`, kg) and sphere (J).
    pub fn kinetic_energy(&self, masses: &[f64]) -> f64 {
        let mut e: f64 = self
            .state
            .velocities
            .iter()
            .zip(masses)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum();
        if let Some(s) = &self.state.sphere {
            e += s.kinetic_energy();
        }
        e
    }

    /// Advances `body` by one step of `dt` (s) with the scheme of [`ImpulseStepper`] (halving on
    /// inversion, Sec. 4) and reports.
    ///
    /// # Errors
    /// What [`ImpulseStepper::step`] reports (the state is then as before the step), or
    /// [`ConstraintError::NonFiniteState`] naming the first particle whose position or velocity
    /// is no longer finite (the step counter then stays).
    pub fn step(
        &mut self,
        body: CellBody<'_>,
        params: &ImpulseParams,
        dt: f64,
    ) -> Result<StepStats, ConstraintError> {
        let model = ImpulseModel {
            masses: body.masses,
            constraints: body.constraints,
            springs: body.springs,
            planes: &self.planes,
            external: &self.external,
            fixed: &self.fixed,
        };
        let info = self.stepper.step(&model, params, &mut self.state, dt)?;
        let x = &self.state.positions;
        for (i, (p, v)) in x.iter().zip(&self.state.velocities).enumerate() {
            if !(p.coords.iter().all(|c| c.is_finite()) && v.iter().all(|c| c.is_finite())) {
                return Err(ConstraintError::NonFiniteState { particle: i });
            }
        }
        self.total_halvings += info.halvings as u64;
        let stats = StepStats {
            step: self.steps,
            time: self.state.time,
            halvings: info.halvings,
            min_dt: info.min_dt,
            sweeps: info.sweeps,
            max_cell_volume_error: body.constraints.max_relative_error(x).0,
            total_volume_ratio: body.constraints.total_volume(x) / body.constraints.rest_volume(),
            momentum: self.momentum(body.masses).into(),
            angular_momentum: self.angular_momentum(body.masses).into(),
            external_impulse: info.external_impulse,
            kinetic_energy: self.kinetic_energy(body.masses),
            contacts: info.contacts,
            max_strain: body.springs.max_strain(x),
            sphere: self.state.sphere.map(|s| SphereStep {
                centre: s.position.into(),
                velocity: s.velocity.into(),
                contact: info.sphere_contacts > 0,
                contacts: info.sphere_contacts,
                contact_impulse: info.sphere_contact_impulse,
            }),
        };
        self.steps += 1;
        Ok(stats)
    }
}

fn check_len(name: &'static str, len: usize, expected: usize) -> Result<(), ConstraintError> {
    if len == expected {
        Ok(())
    } else {
        Err(ConstraintError::LengthMismatch {
            name,
            len,
            expected,
        })
    }
}
