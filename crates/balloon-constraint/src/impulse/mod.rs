//! The impulse-based time stepping of Diziol, Bender and Bayer 2011, Sec. 4 for particles
//! held by cell-volume constraints ([`crate::cell_volume`]), with a rigid sphere and static planes
//! ([`crate::rigid`]).
//!
//! One step of length `h` ([`ImpulseStepper::step`]):
//!
//! 1. `v += h (F / m + g)` with the damped cell springs and the external forces `F` (Eq. 1); the
//!    sphere falls with `g`;
//! 2. impulse contacts with the planes and the sphere, then the cell-volume impulses on the
//!    preview `x = p + h v` (Eq. 2-4), repeated up to `contact_iterations` times while contacts
//!    remain violated; intermediate rounds project to a loose tolerance (`max(tol, 1e-6)`), the
//!    last one always to the tight tolerance, so every step ends with every cell at its rest
//!    volume;
//! 3. `p = x`; the sphere moves with its velocity.
//!
//! Fixed particles ([`ImpulseModel::fixed`], hard anchors) have infinite mass: step 1 leaves
//! their velocity at zero, the plane contacts do not move them, and the sphere contacts and the
//! volume impulses see a zero inverse mass, so their cells are corrected by the other corners
//! only (a cell with a fixed corner takes the gradient correction, which weights every corner by
//! its inverse mass, whatever [`crate::cell_volume::CellCorrection`] says).
//!
//! If a preview tetrahedron inverts, the state is restored and the step redone as two half
//! steps, recursively, up to `max_halvings` times (Sec. 4); beyond that the step fails with
//! [`crate::ConstraintError::Inversion`]. Any failure leaves the state as it was before the failed
//! (sub-)step.
//!
//! ```
//! use balloon_constraint::cell_volume::{CellSprings, CellVolumeConstraints, CellVolumeParams, SpringParams};
//! use balloon_constraint::impulse::{ImpulseModel, ImpulseParams, ImpulseState, ImpulseStepper};
//! use balloon_mesh::lattice::{LatticeParams, build_lattice};
//! let soup = balloon_mesh::generate::icosphere(0.5, 2).unwrap();
//! let lattice = build_lattice(&soup, &LatticeParams { resolution: 8, ..LatticeParams::default() }).unwrap();
//! let x = lattice.tet_mesh.vertices.clone();
//! let tets = lattice.cell_tets.iter().map(|ids| ids.map(|t| lattice.tet_mesh.tets[t])).collect();
//! let constraints = CellVolumeConstraints::new(lattice.cells.clone(), tets, &x, CellVolumeParams::default()).unwrap();
//! let springs = CellSprings::new(&lattice.cells, &x, &SpringParams::default());
//! let masses = vec![0.01; x.len()];
//! let model = ImpulseModel { masses: &masses, constraints: &constraints, springs: &springs, planes: &[], external: &[], fixed: &[] };
//! let params = ImpulseParams { gravity: [0.0, 0.0, -9.81], ..ImpulseParams::default() };
//! let mut state = ImpulseState::at_rest(x);
//! let info = ImpulseStepper::new().step(&model, &params, &mut state, 1e-3).unwrap();
//! assert_eq!(info.halvings, 0);
//! assert!(constraints.max_relative_error(&state.positions).0 <= 1e-10);
//! assert!(state.velocities.iter().all(|v| v.z < 0.0)); // everything falls
//! ```
//!
//! Two levels: [`ImpulseStepper`] advances an [`ImpulseState`] on a borrowed [`ImpulseModel`]
//! (the scheme alone); [`ImpulseRun`] owns the state with the scene (sphere, planes), the loads
//! (external forces, fixed particles) and the step counters, checks its inputs, and reports
//! [`StepStats`] after every step of a [`CellBody`] (masses, cell constraints, springs).

mod run;
mod stepper;

pub use run::{CellBody, ImpulseRun, SphereStep, StepStats};
pub use stepper::{ImpulseModel, ImpulseParams, ImpulseState, ImpulseStepInfo, ImpulseStepper};
