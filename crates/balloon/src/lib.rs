//! `balloon`: inflatable thin shells and volume-conserving soft bodies.
//!
//! This is the thin facade over the solver crates. It re-exports them and offers builders for the
//! three systems of the project:
//!
//! | system | builder | seed |
//! |---|---|---|
//! | shell balloons with thickness | `shell::ShellBalloon` | 000 (Wang et al., "Cute Balloons with Thickness") |
//! | volume-conserving impulse-based bodies | `volumetric::VolumetricBody` | 003 (Diziol, Bender, Bayer) |
//! | two-layer elastic objects | `two_layer::TwoLayerBody` | 004 (Song) |

pub mod fields;
pub mod shell;
pub mod simulation;
pub mod two_layer;
pub mod volumetric;

pub use simulation::{DrawnSurface, Simulation, SimulationError, SimulationStats};

pub use balloon_constraint as constraint;
pub use balloon_element as element;
pub use balloon_gas as gas;
pub use balloon_integrate as integrate;
pub use balloon_material as material;
pub use balloon_mesh as mesh;
