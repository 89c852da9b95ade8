//! Projectors and constraints for the `balloon` toolkit.
//!
//! **For:** correcting positions (and velocities, for impulse methods) after an integration step:
//! the global shell-volume projection of seed 000 (Eq. 24-28, Algorithm 2), the cell-volume
//! impulses of seed 003 (Sec. 4) with rigid-body contact, and the box collisions and inner-layer
//! containment of seed 004.
//!
//! [`impulse`] holds the time stepping that goes with the cell impulses (seed 003, Sec. 4):
//! explicit spring and gravity impulses, contacts, volume impulses on the preview and step
//! halving on inversion; the facade's `VolumetricSimulation` is built on it.
//!
//! **Not for:** integrating elastic shells or spring networks over time (see
//! `balloon-integrate`), or computing element forces (see `balloon-element`).
//!
//! ```
//! use balloon_constraint::rigid::Plane;
//! use nalgebra::{Point3, Vector3};
//! let floor = Plane::new(Point3::origin(), Vector3::new(0.0, 0.0, 2.0)).unwrap();
//! assert_eq!(floor.distance(&Point3::new(1.0, 2.0, 0.5)), 0.5); // the normal is normalised
//! ```

pub mod cell_global;
pub mod cell_volume;
pub mod error;
pub mod impulse;
pub mod projector;
pub mod rigid;
pub mod shell_volume;
pub mod two_layer;

pub use error::ConstraintError;
