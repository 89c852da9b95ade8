//! The shell balloon as a force system (Wang et al. 2015, "Cute Balloons with Thickness").
//!
//! **For:** the forces, energy and tangent stiffness of a closed shell of elements filled with
//! gas, over a triangle mesh, as a [`ForceSystem`](balloon_integrate::ForceSystem) that any
//! integrator of `balloon-integrate` steps or solves:
//!
//! * [`ShellSystem`]: one element per triangle (the three-prism of Eq. 1-11, or an
//!   incompressible membrane triangle), their forces and 9x9 stiffness blocks in parallel
//!   element loops gathered per vertex, plus the enclosed gas (pressure forces Eq. 15, the
//!   rank-1 tangent Eq. 16-17, optionally the follower term in the element blocks);
//! * [`ShellMaterial`]: the seam between a material and the element every triangle becomes
//!   (every `balloon_material::Material` on three-prisms, a [`Membrane`] on membrane triangles,
//!   [`ShellMaterialModel`] chosen at run time);
//! * [`statics::StaticShell`]: the static energy of the shell with a load factor and a gas
//!   term (the shell's own gas, or a volume control by an augmented Lagrangian), for
//!   `balloon_integrate::statics::StaticSolver`;
//! * [`ShellSimulation`]: the running balloon (Algorithms 1 and 2): each step backward Euler
//!   on the system (wrapped by the anchor and pin decorators of `balloon-integrate`) in
//!   adaptive sub-steps, the shell-volume projection of `balloon-constraint`, the velocity
//!   update, the state check; its live controls, statistics ([`ShellStepStats`]) and errors
//!   ([`ShellError`]); and its static rest shape ([`ShellSimulation::solve_static`]: the
//!   thickness fixed point and the volume control around the static solver, see
//!   [`statics`]);
//! * [`connected::ConnectedBalloons`]: balloons of ideal gas joined by tubes the gas flows
//!   through;
//! * [`analytic`]: the analytic inflated sphere of the three-prism model.
//!
//! **Not for:** the integrators, sub-step control, anchors and pins themselves
//! (`balloon-integrate` and its `decorators`), the shell-volume projection
//! (`balloon-constraint`), or building a balloon from a mesh with defaults and a gas set-up
//! (the `balloon` facade's `ShellBalloon`).
//!
//! **Why a crate of its own** and not part of `balloon-element`: an element knows its
//! material and its corners, nothing of the gas. The shell system joins the elements over a
//! mesh with the enclosed gas (`balloon-gas`): the pressure's rank-1 tangent and follower
//! blocks are added to the element blocks in the same pass, and the static energy replaces the
//! gas by a volume control. So it depends on `balloon-element`, `balloon-gas` and
//! `balloon-integrate` (whose `ForceSystem` it implements), which `balloon-element` must not;
//! the running balloon adds `balloon-constraint` (its projector).
//!
//! ```
//! use balloon_gas::{IdealGas, PressureLoad};
//! use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
//! use balloon_material::{Lame, NeoHookean};
//! use balloon_shell::ShellSystem;
//!
//! let mesh = balloon_mesh::generate::icosphere(0.1, 2)?;
//! let mut x = mesh.positions_flat();
//! let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
//! // Neo-Hookean rubber, 0.3 mm thick, with 2 kPa of ideal gas over no ambient pressure.
//! let material = NeoHookean::new(Lame::try_from_young_poisson(1e6, 0.45)?);
//! let gas = PressureLoad::new(IdealGas::try_new(2000.0, v0)?).with_ambient_pressure(0.0)?;
//! let thickness = vec![3e-4; mesh.num_triangles()];
//! let mut shell =
//!     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
//! let mut params = BackwardEulerParams::default();
//! params.mass_damping = 10.0;
//! let mut integrator = BackwardEuler::new(params)?;
//! let mut v = vec![0.0; x.len()];
//! for n in 0..5 {
//!     integrator.step(&mut shell, n as f64 * 0.01, 0.01, &mut x, &mut v, None)?;
//! }
//! let v1 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
//! assert!(v1 > v0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! | feature | default | what it does |
//! |---|---|---|
//! | `parallel` | on | runs the element loops on rayon from [`PARALLEL_THRESHOLD`] elements on (identical results) |

pub mod analytic;
mod bending;
pub mod connected;
mod error;
mod material;
mod membrane;
pub mod run;
pub mod statics;
mod system;

pub use error::ShellSystemError;
pub use material::{ShellElement, ShellMaterial, ShellMaterialModel};
pub use membrane::{Membrane, membrane_sphere_stretch};
pub use run::{RUNAWAY_VOLUME_FACTOR, ShellError, ShellSimulation, ShellSnapshot, ShellStepStats};
pub use system::{PARALLEL_THRESHOLD, SPLIT_STIFFNESS_RATIO, ShellSystem};

#[cfg(test)]
mod tests;
