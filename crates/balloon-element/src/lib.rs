//! Finite elements of the `balloon` workspace, generic over a [`balloon_material::Material`]:
//! per-element kinematics, energy, forces, force differential and stiffness block.
//!
//! **What it is for.** One element at a time, allocation-free, monomorphised over the material
//! (no trait objects in hot loops). Assembly over a mesh, time integration and gas pressure live
//! in other crates; this crate knows nothing of time or gas. Every element here is used by a
//! system: the three-prism by the shell balloon (Wang et al. 2015), the springs by the two-layer body
//! (Song 2009).
//!
//! **What it is not for.** Volumetric (tetrahedral) elasticity: the
//! volumetric body of Diziol, Bender and Bayer 2011 is held together by cell-volume impulses and cell springs
//! (`balloon-constraint`), not by tetrahedral elements.
//!
//! | element | DOFs | kinematics | paper |
//! |---|---|---|---|
//! | [`ThreePrism`] | 3 vertices (+ thickness parameter `h`) | `F = [e12 e13 d h][E12 E13 D H]^-1` | Wang et al. 2015, Eq. 1-4, 8, 11, 19 |
//! | [`HyperMembrane`] | 3 vertices, incompressible (`h = H / sqrt(det C)`) | `C = Fm^T Fm` (2x2) into a `MembraneMaterial` | `docs/membranes.md` (not yet wired into the shell system) |
//! | [`Spring`] | 2 particles | Hooke + axial dashpot | Song 2009, Eq. 4.2-4.6 (two-layer bodies) |
//! | [`TargetSpring`] | 1 particle + a driven target | Hooke + axial dashpot | Song 2009, Eq. 4.7 (drag) |
//! | [`Hinge`] | 4 vertices (an interior edge and its two opposite vertices) | dihedral angle `theta`, `E = D/2 w (theta - theta_bar)^2` | Grinspun et al. 2003, Eq. 3; angle gradient of Bridson et al. 2003 |
//!
//! Sign conventions, shared by all elements: `forces = -dE/dx`; `force_differential(dx) = df =
//! -K dx`; `stiffness = K = d^2E/dx^2` (symmetric), vertex-major `[x1 y1 z1 x2 ...]`.
//! The derivation of the three-prism forces and differential, including the derivative of the
//! unit normal, is in `docs/elements.md`.
//!
//! ```
//! use balloon_element::ThreePrism;
//! use balloon_material::{Lame, StVenantKirchhoff};
//! use nalgebra::Vector3;
//!
//! let rest = [Vector3::zeros(), Vector3::new(0.01, 0.0, 0.0), Vector3::new(0.0, 0.01, 0.0)];
//! let prism = ThreePrism::try_new(rest, 1.0e-3)?;
//! let rubber = StVenantKirchhoff::new(Lame::try_from_young_poisson(1.0e6, 0.45).unwrap());
//! // At rest (x = rest positions, h = H) there is no energy and no force.
//! assert_eq!(prism.energy(&rubber, &rest, 1.0e-3), 0.0);
//! let stretched = rest.map(|p| p * 1.1);
//! let (f, k) = prism.forces_and_stiffness(&rubber, &stretched, 1.0e-3);
//! assert!(f[1].x < 0.0); // the stretched sheet pulls vertex 2 back
//! assert!((k - k.transpose()).norm() <= 1e-9 * k.norm());
//! # Ok::<(), balloon_element::ElementError>(())
//! ```
//!
//! Features: none.

mod error;
mod expand;
mod hinge;
mod hyper_membrane;
mod prism;
mod spring;
mod triangle;

pub use error::ElementError;
pub use hinge::Hinge;
pub use hyper_membrane::{HyperMembrane, HyperMembraneLinearization};
pub use prism::{ThreePrism, ThreePrismLinearization};
pub use spring::{Spring, TargetSpring};

#[cfg(test)]
mod tests;
