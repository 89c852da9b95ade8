//! Two-layer elastic objects (Song 2009, "Dynamic Deformation of Uniform Elastic Two-Layer
//! Objects"): mass-spring bodies in 1D, 2D and 3D whose inner and outer layers are joined by
//! radius and shear springs, filled with an ideal gas, pulled by gravity and a drag ("mouse")
//! spring, bouncing in a box, and advanced by explicit Euler, midpoint, RK4 or symplectic Euler.
//!
//! **For:** the numerics of this system, usable without the `balloon` facade:
//!
//! * [`TwoLayerModel`]: particles, springs per [`SpringKind`], the two closed layers and their
//!   gas (Ch. 3), built by [`TwoLayerModel::line`], [`TwoLayerModel::circle`] or
//!   [`TwoLayerModel::from_unit_sphere`];
//! * [`TwoLayerForces`]: gravity (Sec. 4.1), Hooke (Sec. 4.2) and damping (Sec. 4.3) forces per
//!   spring kind ([`balloon_element::Spring`]), the drag spring (Sec. 4.4,
//!   [`balloon_element::TargetSpring`]), gas pressure per closed layer (Sec. 4.5,
//!   [`balloon_gas::layer`]) and anchor / external loads, laid out on the model's particles, with
//!   their energies; a [`balloon_integrate::explicit::SecondOrderSystem`];
//! * [`TwoLayerSimulation`]: steps with any [`ExplicitMethod`], resolves the box collisions and
//!   keeps the inner layer inside the outer one (Sec. 4.6, [`balloon_constraint::two_layer`]),
//!   reports [`TwoLayerStats`] and stops with [`TwoLayerError::BlowUp`] on NaN or energy growth.
//!
//! **Not for:** choosing shapes and defaults from a scenario (the facade's `TwoLayerBody`
//! builder does that and converts into [`TwoLayerParams`]), writing frames, or implicit
//! integration (see `balloon-integrate`).
//!
//! **Why a crate of its own.** The force system needs elements (springs), the layer gas and
//! the explicit integrators' [`balloon_integrate::explicit::SecondOrderSystem`]; the stepping
//! adds the box collisions and the containment of `balloon-constraint`. Placed in
//! `balloon-constraint` it would make the projector crate depend on the integrators and the
//! elements, against the one-way order mesh <- element <- (gas, constraint) <- integrate. Here
//! it sits above `balloon-integrate` and `balloon-constraint`, beside the facade that builds it.
//!
//! ```
//! use balloon_two_layer::{ExplicitMethod, TwoLayerModel, TwoLayerParams, TwoLayerSimulation};
//! use nalgebra::Point3;
//! let sphere = balloon_mesh::generate::octahedron_sphere(1.0, 1)?;
//! let model = TwoLayerModel::from_unit_sphere(sphere, Point3::origin(), [0.8, 1.0], [0.01, 0.01])
//!     .with_pressures(200.0, 200.0);
//! let mut sim = TwoLayerSimulation::new(model, TwoLayerParams::default(), ExplicitMethod::Rk4, 1e-3)?;
//! let stats = sim.step()?;
//! assert!(stats.volume_outer > stats.volume_inner);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! **Particle layout.** In 2D and 3D particles `0..n` are the inner layer and `n..2n` the outer
//! layer, with inner particle `j` paired to outer particle `j + n` (same direction from the
//! centre). In 1D particle 0 is the fixed end and particle 1 the free end.
//!
//! **Gas.** Following Song 2009, Sec. 4.7 (Steps 6-9), each closed layer encloses its own gas
//! with constant `nRT`: `P_k = (nRT)_k / V_k` (Eq. 4.10) acts outward on layer `k` only. The
//! region between the layers is the elastic material itself, modelled by the radius and shear
//! springs, not a gas. The force is exactly `-dU/dx` of `U_gas = -(nRT)_k ln(V_k / V_k0)`, so
//! the undamped model conserves energy. Pressures are given as *initial* pressures at the rest
//! volume: `(nRT)_k = P_k0 V_k0` ([`TwoLayerModel::with_pressures`]).
//!
//! Section and equation numbers without an author in this crate ("Sec. 4.4", "Eq. 4.7") refer
//! to Song 2009.

pub mod analytic;
mod error;
mod forces;
mod model;
mod params;
mod sim;

pub use balloon_integrate::explicit::ExplicitMethod;
pub use error::{BlowUpReason, TwoLayerError};
pub use forces::{AnchorSpring, DragTarget, EnergyBreakdown, TwoLayerForces};
pub use model::{Dimension, Layers, Spring, SpringKind, SpringParams, TwoLayerModel};
pub use params::TwoLayerParams;
pub use sim::{TwoLayerSimulation, TwoLayerStats};

#[cfg(test)]
mod tests;
