//! One step of the scheme ([`ImpulseStepper::step`]) on a borrowed [`ImpulseModel`] and an owned
//! [`ImpulseState`]: springs and gravity, contacts, volume impulses on the preview, step halving
//! on inversion (see the module documentation of [`crate::impulse`]).

use nalgebra::{Point3, Vector3};

use crate::ConstraintError;
use crate::cell_volume::{CellProjectionWorkspace, CellSprings, CellVolumeConstraints};
use crate::rigid::{
    Plane, RigidSphere, plane_particle_contacts, plane_sphere_contact, sphere_particle_contacts,
};

/// Parameters of the stepping scheme (validated by the caller's builder).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpulseParams {
    /// Gravity (m/s^2). Default `[0, 0, -9.81]`.
    pub gravity: [f64; 3],
    /// Restitution of contacts in `[0, 1]`. Default 0.2.
    pub restitution: f64,
    /// Rounds of (contacts, volume projection) per step, `>= 1`. Default 4.
    pub contact_iterations: usize,
    /// Relative cell-volume tolerance of the final projection of each step. Default 1e-10.
    pub tolerance: f64,
    /// Largest number of nested step halvings on inversion. Default 8.
    pub max_halvings: u32,
}

impl Default for ImpulseParams {
    fn default() -> Self {
        Self {
            gravity: [0.0, 0.0, -9.81],
            restitution: 0.2,
            contact_iterations: 4,
            tolerance: 1e-10,
            max_halvings: 8,
        }
    }
}

/// What a step reads but does not change: particle masses, the cell constraints and springs,
/// the static planes and the external forces (one per particle, or empty for none).
#[derive(Clone, Copy, Debug)]
pub struct ImpulseModel<'a> {
    /// Particle masses (kg).
    pub masses: &'a [f64],
    /// Cell-volume constraints.
    pub constraints: &'a CellVolumeConstraints,
    /// Cell springs.
    pub springs: &'a CellSprings,
    /// Static planes.
    pub planes: &'a [Plane],
    /// External forces per particle (N), added to the spring forces; empty for none.
    pub external: &'a [Vector3<f64>],
    /// Fixed particles (hard anchors), one flag per particle, or empty for none: a fixed
    /// particle keeps zero velocity and never moves (infinite mass; see the module docs).
    pub fixed: &'a [bool],
}

/// What a step changes: particle positions and velocities, the optional rigid sphere and the
/// simulated time.
#[derive(Clone, Debug, PartialEq)]
pub struct ImpulseState {
    /// Particle positions (m).
    pub positions: Vec<Point3<f64>>,
    /// Particle velocities (m/s).
    pub velocities: Vec<Vector3<f64>>,
    /// The rigid sphere, if any.
    pub sphere: Option<RigidSphere>,
    /// Simulated time (s).
    pub time: f64,
}

impl ImpulseState {
    /// Particles at `positions` with zero velocities, no sphere, time 0.
    pub fn at_rest(positions: Vec<Point3<f64>>) -> Self {
        let n = positions.len();
        Self {
            positions,
            velocities: vec![Vector3::zeros(); n],
            sphere: None,
            time: 0.0,
        }
    }
}

/// What a step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpulseStepInfo {
    /// Step halvings needed.
    pub halvings: u32,
    /// Smallest sub-step used (s).
    pub min_dt: f64,
    /// Gauss-Seidel sweeps or Newton iterations of the projections (summed over sub-steps and
    /// contact rounds).
    pub sweeps: usize,
    /// Active contacts (summed over sub-steps and rounds).
    pub contacts: usize,
    /// Impulse (N s) that acted from outside the particles and the sphere during the step:
    /// gravity `h g (sum m + M)`, the external forces `h sum F` and the contact impulses of the
    /// static planes (measured as the momentum change of their contact passes). Everything
    /// else (springs, volume impulses with momentum-conserving centres, sphere-particle
    /// contacts) is internal, so the momentum changes by exactly this much up to round-off.
    pub external_impulse: [f64; 3],
    /// Active sphere-particle contacts of the completed sub-steps (summed over sub-steps and
    /// contact rounds; part of `contacts`).
    pub sphere_contacts: usize,
    /// Impulse (N s) the particles gave the sphere through their contacts over the completed
    /// sub-steps, `M (V_after - V_before)` of each contact pass (the particles received the
    /// opposite; zero without a sphere).
    pub sphere_contact_impulse: [f64; 3],
}

/// The stepper: scratch buffers and the caches of the global cell-volume solve, kept from step
/// to step. Cloning gives fresh caches.
#[derive(Clone, Debug, Default)]
pub struct ImpulseStepper {
    forces: Vec<Vector3<f64>>,
    /// The masses with infinity for the fixed particles (only when some are fixed).
    pinned_masses: Vec<f64>,
    projection: CellProjectionWorkspace,
}

impl ImpulseStepper {
    /// A stepper with empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Advances `state` by `dt` (s), halving on inversion (see the module docs).
    ///
    /// # Errors
    /// [`ConstraintError`]; the state is then as before the failed (sub-)step.
    pub fn step(
        &mut self,
        model: &ImpulseModel<'_>,
        params: &ImpulseParams,
        state: &mut ImpulseState,
        dt: f64,
    ) -> Result<ImpulseStepInfo, ConstraintError> {
        let mut info = ImpulseStepInfo {
            min_dt: dt,
            ..ImpulseStepInfo::default()
        };
        self.advance(model, params, state, dt, 0, &mut info)?;
        Ok(info)
    }

    /// Advances by `h`; on inversion restores the state and does two steps of `h / 2`; on any
    /// other failure restores the state of the failed (sub-)step and reports it.
    fn advance(
        &mut self,
        model: &ImpulseModel<'_>,
        params: &ImpulseParams,
        state: &mut ImpulseState,
        h: f64,
        depth: u32,
        info: &mut ImpulseStepInfo,
    ) -> Result<(), ConstraintError> {
        let saved = (
            state.positions.clone(),
            state.velocities.clone(),
            state.sphere,
        );
        match self.sub_step(model, params, state, h, info) {
            Ok(()) => {
                state.time += h;
                Ok(())
            }
            Err(ConstraintError::Inverted { cell, tet, .. }) => {
                (state.positions, state.velocities, state.sphere) = saved;
                if depth >= params.max_halvings {
                    return Err(ConstraintError::Inversion {
                        cell,
                        tet,
                        halvings: depth,
                        dt: h,
                    });
                }
                info.halvings += 1;
                info.min_dt = info.min_dt.min(h / 2.0);
                self.advance(model, params, state, h / 2.0, depth + 1, info)?;
                self.advance(model, params, state, h / 2.0, depth + 1, info)
            }
            Err(source) => {
                (state.positions, state.velocities, state.sphere) = saved;
                Err(source)
            }
        }
    }

    /// One step of Eq. 1 followed by contacts and volume impulses on the preview.
    fn sub_step(
        &mut self,
        model: &ImpulseModel<'_>,
        params: &ImpulseParams,
        state: &mut ImpulseState,
        h: f64,
        info: &mut ImpulseStepInfo,
    ) -> Result<(), ConstraintError> {
        let g = Vector3::from(params.gravity);
        let fixed = |i: usize| model.fixed.get(i).copied().unwrap_or(false);
        let any_fixed = model.fixed.iter().any(|&f| f);
        let total_mass = if any_fixed {
            model
                .masses
                .iter()
                .enumerate()
                .filter(|&(i, _)| !fixed(i))
                .map(|(_, m)| m)
                .sum::<f64>()
        } else {
            model.masses.iter().sum::<f64>()
        } + state.sphere.map_or(0.0, |s| s.mass);
        let applied = if any_fixed {
            model
                .external
                .iter()
                .enumerate()
                .filter(|&(i, _)| !fixed(i))
                .fold(Vector3::zeros(), |a, (_, f)| a + f)
        } else {
            model.external.iter().fold(Vector3::zeros(), |a, f| a + f)
        };
        let mut external = g * (h * total_mass) + applied * h;
        // Masses seen by the contacts and the volume impulses: infinite for a fixed particle.
        if any_fixed {
            self.pinned_masses.clear();
            self.pinned_masses.extend(
                model.masses.iter().enumerate().map(
                    |(i, &m)| {
                        if fixed(i) { f64::INFINITY } else { m }
                    },
                ),
            );
        }
        let masses: &[f64] = if any_fixed {
            &self.pinned_masses
        } else {
            model.masses
        };
        let (mut sphere_contacts, mut sphere_impulse) = (0, Vector3::zeros());
        // 1. External forces: gravity and cell springs (Eq. 1).
        self.forces.clear();
        self.forces.resize(state.positions.len(), Vector3::zeros());
        model
            .springs
            .add_forces(&state.positions, &state.velocities, &mut self.forces);
        for (f, e) in self.forces.iter_mut().zip(model.external) {
            *f += e;
        }
        for (i, ((v, f), m)) in state
            .velocities
            .iter_mut()
            .zip(&self.forces)
            .zip(model.masses)
            .enumerate()
        {
            if any_fixed && fixed(i) {
                *v = Vector3::zeros();
                continue;
            }
            *v += (f / *m + g) * h;
        }
        if let Some(s) = &mut state.sphere {
            s.velocity += g * h;
        }
        // 2. Contacts and volume impulses on the preview (Eq. 2-4).
        let e = params.restitution;
        let mut preview = state.positions.clone();
        let tight = params.tolerance;
        for round in 0..params.contact_iterations {
            let mut contacts = 0;
            let before = (!model.planes.is_empty()).then(|| momentum(model.masses, state));
            for plane in model.planes {
                contacts +=
                    plane_particle_contacts(plane, &state.positions, &mut state.velocities, h, e);
                if let Some(s) = &mut state.sphere {
                    contacts += usize::from(plane_sphere_contact(plane, s, h, e));
                }
            }
            if any_fixed {
                // A plane does not push an anchored particle.
                for (i, v) in state.velocities.iter_mut().enumerate() {
                    if fixed(i) {
                        *v = Vector3::zeros();
                    }
                }
            }
            if let Some(before) = before {
                external += momentum(model.masses, state) - before;
            }
            if let Some(s) = &mut state.sphere {
                let before = s.momentum();
                let touching = sphere_particle_contacts(
                    s,
                    &state.positions,
                    &mut state.velocities,
                    masses,
                    h,
                    e,
                );
                contacts += touching;
                sphere_contacts += touching;
                sphere_impulse += s.momentum() - before;
            }
            info.contacts += contacts;
            for ((x, p), v) in preview
                .iter_mut()
                .zip(&state.positions)
                .zip(&state.velocities)
            {
                *x = p + v * h;
            }
            // Intermediate rounds (contacts will be re-checked) stop at a loose tolerance; the
            // last projection of the step is always converged to the tight one.
            let final_round = contacts == 0 || round + 1 == params.contact_iterations;
            let tolerance = if final_round { tight } else { tight.max(1e-6) };
            let proj = model.constraints.project_with(
                &mut self.projection,
                &mut preview,
                &mut state.velocities,
                masses,
                h,
                tolerance,
            )?;
            info.sweeps += proj.sweeps;
            if final_round {
                break;
            }
        }
        // 3. Positions from the corrected preview.
        state.positions.copy_from_slice(&preview);
        if let Some(s) = &mut state.sphere {
            s.position += s.velocity * h;
        }
        for (acc, x) in info.external_impulse.iter_mut().zip(external.iter()) {
            *acc += x;
        }
        for (acc, x) in info
            .sphere_contact_impulse
            .iter_mut()
            .zip(sphere_impulse.iter())
        {
            *acc += x;
        }
        info.sphere_contacts += sphere_contacts;
        Ok(())
    }
}

/// Momentum of the particles and the sphere (kg m/s).
fn momentum(masses: &[f64], state: &ImpulseState) -> Vector3<f64> {
    let p = state
        .velocities
        .iter()
        .zip(masses)
        .fold(Vector3::zeros(), |a, (v, m)| a + v * *m);
    p + state.sphere.map_or(Vector3::zeros(), |s| s.momentum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell_volume::{CellVolumeParams, SpringParams};
    use balloon_mesh::lattice::{LatticeParams, build_lattice};
    use balloon_test_support::Rng;

    struct Body {
        x: Vec<Point3<f64>>,
        constraints: CellVolumeConstraints,
        springs: CellSprings,
        masses: Vec<f64>,
    }

    fn body() -> Body {
        let soup = balloon_mesh::generate::icosphere(0.5, 2).unwrap();
        let params = LatticeParams {
            resolution: 8,
            ..LatticeParams::default()
        };
        let lattice = build_lattice(&soup, &params).unwrap();
        let x = lattice.tet_mesh.vertices.clone();
        let tets = lattice
            .cell_tets
            .iter()
            .map(|ids| ids.map(|t| lattice.tet_mesh.tets[t]))
            .collect();
        let constraints = CellVolumeConstraints::new(
            lattice.cells.clone(),
            tets,
            &x,
            CellVolumeParams::default(),
        )
        .unwrap();
        let springs = CellSprings::new(&lattice.cells, &x, &SpringParams::default());
        let masses = vec![0.02; x.len()];
        Body {
            x,
            constraints,
            springs,
            masses,
        }
    }

    fn model(b: &Body) -> ImpulseModel<'_> {
        ImpulseModel {
            masses: &b.masses,
            constraints: &b.constraints,
            springs: &b.springs,
            planes: &[],
            external: &[],
            fixed: &[],
        }
    }

    /// Without gravity or contacts the internal springs and volume impulses keep the momentum
    /// (equal masses), every cell ends at its rest volume, and time advances by `dt`.
    #[test]
    fn free_step_keeps_momentum_and_cell_volumes() {
        let b = body();
        let params = ImpulseParams {
            gravity: [0.0; 3],
            ..ImpulseParams::default()
        };
        let mut rng = Rng::new(3);
        let mut state = ImpulseState::at_rest(b.x.clone());
        for v in &mut state.velocities {
            *v = Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.05;
        }
        let momentum = |s: &ImpulseState| -> Vector3<f64> {
            s.velocities
                .iter()
                .zip(&b.masses)
                .map(|(v, m)| v * *m)
                .sum()
        };
        let p0 = momentum(&state);
        let mut stepper = ImpulseStepper::new();
        for _ in 0..5 {
            let info = stepper.step(&model(&b), &params, &mut state, 1e-3).unwrap();
            assert_eq!((info.halvings, info.contacts), (0, 0));
            assert!(info.sweeps > 0);
        }
        assert!((state.time - 5e-3).abs() < 1e-15);
        assert!(
            (momentum(&state) - p0).norm() < 1e-12,
            "{}",
            momentum(&state) - p0
        );
        assert!(b.constraints.max_relative_error(&state.positions).0 <= 1e-10);
    }

    /// A floor plane stops the falling body, and an inversion that no halving is allowed to fix
    /// is an error that leaves the state untouched.
    #[test]
    fn contacts_act_and_unfixable_inversion_rolls_back() {
        let b = body();
        let lowest = b.x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        let floor = [Plane::new(Point3::new(0.0, 0.0, lowest), Vector3::z()).unwrap()];
        let m = ImpulseModel {
            planes: &floor,
            ..model(&b)
        };
        let mut state = ImpulseState::at_rest(b.x.clone());
        state.velocities.fill(Vector3::new(0.0, 0.0, -1.0));
        let info = ImpulseStepper::new()
            .step(&m, &ImpulseParams::default(), &mut state, 1e-3)
            .unwrap();
        assert!(info.contacts > 0);
        let z_min = state
            .positions
            .iter()
            .map(|p| p.z)
            .fold(f64::INFINITY, f64::min);
        assert!(z_min > lowest - 1e-9, "{z_min} below the floor {lowest}");
        // Crush one particle through the body within a single step.
        let mut state = ImpulseState::at_rest(b.x.clone());
        let centre = b.x.iter().map(|p| p.coords).sum::<Vector3<f64>>() / b.x.len() as f64;
        state.velocities[0] = (centre - b.x[0].coords) * 3e3;
        let before = state.clone();
        let params = ImpulseParams {
            max_halvings: 0,
            gravity: [0.0; 3],
            ..ImpulseParams::default()
        };
        let err = ImpulseStepper::new()
            .step(&model(&b), &params, &mut state, 1e-3)
            .unwrap_err();
        assert!(
            matches!(err, ConstraintError::Inversion { halvings: 0, .. }),
            "{err}"
        );
        assert_eq!(state, before);
    }
}
