//! `balloon`: inflatable thin shells and volume-conserving soft bodies.
//!
//! This is the thin facade over the solver crates. It re-exports them and offers builders for the
//! three systems of the project:
//!
//! | system | builder | runs in | paper |
//! |---|---|---|---|
//! | shell balloons with thickness | `shell::ShellBalloon` | `balloon-shell` | Wang et al. 2015, "Cute Balloons with Thickness" |
//! | volume-conserving impulse-based bodies | `volumetric::VolumetricBody` | `balloon-constraint` | Diziol, Bender and Bayer 2011 |
//! | two-layer elastic objects | `two_layer::TwoLayerBody` | `balloon-two-layer` | Song 2009 |
//!
//! Every running system implements [`Simulation`] (step, time, dt, flat positions, the drawn
//! surface, shared statistics, a typed [`SimulationError`]), so run loops, viewers and benchmarks
//! are written once. Every part of the shell swaps in one line on its builder: material, gas
//! model (a user's own `GasModel` too), integrator parameters, linear solver and projector (see
//! [`shell`]).
//!
//! Not in this crate: the numerics themselves and the running systems' state machines (elements,
//! materials, gases, integrators, constraint projectors, the shell's step, sub-steps and static
//! rest shape live in the re-exported stage crates), file output and pictures (the CLI and
//! `balloon-render`).
//!
//! Features: `parallel` (default on) runs the shell's per-element force and stiffness loops and
//! the lattice generator on rayon and lets the sparse Cholesky factorisation use the rayon pool
//! when asked to; it forwards to the `parallel` features of `balloon-mesh`, `balloon-linalg` and
//! `balloon-integrate`. Without it everything runs on the calling thread with identical results.
//!
//! ```
//! use balloon::Simulation;
//! use balloon::gas::GasKind;
//! use balloon::shell::ShellBalloon;
//!
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let mut sim = ShellBalloon::new(mesh)
//!     .with_gas(GasKind::Constant)
//!     .with_gauge_pressure(1000.0)
//!     .build()
//!     .unwrap();
//! let stats = Simulation::step(&mut sim).unwrap();
//! assert_eq!((stats.steps, stats.dt), (1, sim.dt()));
//! assert!(stats.detail.gas_volume > sim.rest_gas_volume());
//! ```

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
pub use balloon_linalg as linalg;
pub use balloon_material as material;
pub use balloon_mesh as mesh;
