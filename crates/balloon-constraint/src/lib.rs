//! Projectors and constraints for the `balloon` toolkit.
//!
//! **For:** correcting positions (and velocities, for impulse methods) after an integration step:
//! the global shell-volume projection of Wang et al. 2015 (Eq. 24-28, Algorithm 2), the cell-volume
//! impulses of Diziol, Bender and Bayer 2011 (Sec. 4) with rigid-body contact, and the box
//! collisions and inner-layer containment of Song 2009.
//!
//! | module | holds |
//! |---|---|
//! | [`shell_volume`], [`projector`] | the shell-volume projection and the projector seam |
//! | [`cell_volume`], [`cell_global`] | cell constraints, their springs, Gauss-Seidel and global projections |
//! | [`rigid`] | rigid sphere and static planes, impulse contacts |
//! | [`impulse`] | the time stepping that goes with the cell impulses (Diziol, Bender and Bayer 2011, Sec. 4): spring and gravity impulses, contacts, volume impulses on the preview, step halving on inversion ([`impulse::ImpulseStepper`]), and a running body with its scene, loads and statistics ([`impulse::ImpulseRun`], which the facade's `VolumetricSimulation` composes) |
//! | [`two_layer`] | box collisions, the inner layer kept inside the outer one ([`two_layer::LayerContainment`]), winding numbers |
//!
//! **Not for:** integrating elastic shells or spring networks over time (see
//! `balloon-integrate`), computing element forces (see `balloon-element`), or the two-layer
//! force system and its explicit stepping (see `balloon-two-layer`, which uses [`two_layer`]).
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
