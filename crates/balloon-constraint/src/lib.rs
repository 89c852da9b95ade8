//! Projectors and constraints for the `balloon` toolkit.
//!
//! **For:** correcting positions (and velocities, for impulse methods) after an integration step:
//! the global shell-volume projection of seed 000 (Eq. 24-28, Algorithm 2), the cell-volume
//! impulses of seed 003 (Sec. 4) with rigid-body contact, and the box collisions and inner-layer
//! containment of seed 004.
//!
//! **Not for:** integrating forces over time; see `balloon-integrate`.

pub mod cell_global;
pub mod cell_volume;
pub mod projector;
pub mod rigid;
pub mod shell_volume;
pub mod two_layer;
