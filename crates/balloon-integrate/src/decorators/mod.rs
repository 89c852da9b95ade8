//! [`ForceSystem`](crate::ForceSystem) decorators: a system wrapped so that the integrators see
//! it with something added or held, without the system knowing.
//!
//! * [`Anchored`]: zero-length springs from vertices to fixed points ([`AnchorSpring`], checked
//!   once into [`Anchors`]), their forces, energy and stiffness added to the inner system's, so
//!   stiff springs are integrated implicitly with it.
//! * [`Pinned`]: vertices held in place ([`Pins`]): every pinned degree of freedom is
//!   decoupled from the others (zero rows and columns of the stiffness, a force that cancels
//!   the integrator's gravity), so backward Euler and the static solve leave it exactly where
//!   it is.
//!
//! A vertex here is three consecutive degrees of freedom `3 v, 3 v + 1, 3 v + 2` (the layout of
//! [`ForceSystem`](crate::ForceSystem)); the decorators know nothing else about the system.
//! They borrow the system and their data for one call of an integrator, and nest:
//! `Pinned::new(&mut Anchored::new(&mut system, &anchors)?, &mut pins)?`.
//!
//! ```
//! use balloon_integrate::decorators::{AnchorSpring, Anchored, Anchors, Pinned, Pins};
//! use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
//! use balloon_integrate::{ForceSystem, SystemError};
//!
//! /// Two free particles of 1 kg (no forces of their own).
//! struct Free([f64; 6]);
//! impl ForceSystem for Free {
//!     fn num_dofs(&self) -> usize { 6 }
//!     fn masses(&self) -> &[f64] { &self.0 }
//!     fn forces(&mut self, _t: f64, _x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
//!         f.fill(0.0);
//!         Ok(())
//!     }
//!     fn add_force_differential(&self, _dx: &[f64], _df: &mut [f64]) {}
//!     fn add_stiffness_triplets(&self, _t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
//!         Ok(())
//!     }
//!     fn potential_energy(&mut self, _t: f64, _x: &[f64]) -> Result<Option<f64>, SystemError> {
//!         Ok(Some(0.0))
//!     }
//! }
//!
//! let mut system = Free([1.0; 6]);
//! // Particle 0 on a stiff spring to (1, 0, 0); particle 1 held where it is.
//! let spring = AnchorSpring { vertex: 0, anchor: [1.0, 0.0, 0.0], stiffness: 1e4 };
//! let anchors = Anchors::new(2, vec![spring])?;
//! let mut pins = Pins::new(2, vec![1])?;
//! let mut params = BackwardEulerParams::default();
//! params.gravity = [0.0, 0.0, -9.81];
//! params.mass_damping = 50.0;
//! let mut integrator = BackwardEuler::new(params)?;
//! let (mut x, mut v) = (vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5], vec![0.0; 6]);
//! let mut masked = Vec::new();
//! for n in 0..200 {
//!     pins.prepare_step(&mut v, &[], params.gravity, &mut masked);
//!     let mut anchored = Anchored::new(&mut system, &anchors)?;
//!     let mut held = Pinned::new(&mut anchored, &mut pins)?;
//!     integrator.step(&mut held, n as f64 * 0.01, 0.01, &mut x, &mut v, None)?;
//! }
//! // The stiff spring (k dt^2 / m = 1) is stable and holds particle 0 near its anchor, gravity
//! // pulling it down by m g / k; the pinned particle has not moved at all.
//! assert!((x[0] - 1.0).abs() < 1e-6 && (x[2] + 9.81e-4).abs() < 1e-6);
//! assert_eq!(x[3..], [0.5, 0.5, 0.5]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod anchors;
mod pins;

pub use anchors::{AnchorSpring, Anchored, Anchors};
pub use pins::{Pinned, Pins};

use thiserror::Error;

/// Bad input to a decorator: a vertex that does not exist, a spring that is not finite, or
/// decorator data made for a system of another size.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum DecoratorError {
    /// A vertex index is not below the number of vertices. Fix: index the vertices of the
    /// system the decorator is for (`0..num_vertices`).
    #[error("`{what}` = {vertex} is out of range: the system has {num_vertices} vertices")]
    VertexOutOfRange {
        /// What the index is (`pinned vertex`, `anchor spring vertex`).
        what: &'static str,
        /// The index.
        vertex: usize,
        /// The number of vertices.
        num_vertices: usize,
    },
    /// An anchor spring's anchor is not finite, or its stiffness is not finite and `>= 0`.
    #[error(
        "invalid `anchor spring` = {spring:?}: the anchor must be finite and the stiffness finite and >= 0"
    )]
    InvalidSpring {
        /// The spring.
        spring: AnchorSpring,
    },
    /// The decorator's data were made for a system with another number of vertices than the
    /// system it wraps. Fix: make them with `num_dofs() / 3` of that system.
    #[error(
        "{what} were made for {expected} vertices, but the wrapped system has {found} vertices"
    )]
    SizeMismatch {
        /// `pins` or `anchor springs`.
        what: &'static str,
        /// The number of vertices the data were made for.
        expected: usize,
        /// The wrapped system's number of vertices.
        found: usize,
    },
}

#[cfg(test)]
mod tests;
