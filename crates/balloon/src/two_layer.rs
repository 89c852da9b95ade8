//! Two-layer elastic objects (seed 004, Song, "Dynamic Deformation of Uniform Elastic Two-Layer
//! Objects"): mass-spring bodies in 1D, 2D and 3D whose inner and outer layers are joined by
//! radius and shear springs, filled with an ideal gas, pulled by gravity and a drag ("mouse")
//! spring, bouncing in a box, and advanced by explicit Euler, midpoint, RK4 or symplectic Euler.
//!
//! * [`TwoLayerBody`]: the builder (shape, radii, masses, spring constants per [`SpringKind`],
//!   pressures, gravity, collision box, restitution) -> [`TwoLayerModel`] (particles, springs,
//!   layers; seed Ch. 3).
//! * [`TwoLayerForces`]: gravity (seed Sec. 4.1), Hooke (Sec. 4.2) and damping (Sec. 4.3)
//!   forces per spring type ([`balloon_element::Spring`]), the drag spring (Sec. 4.4,
//!   [`balloon_element::TargetSpring`]), gas pressure per closed layer (Sec. 4.5,
//!   [`balloon_gas::layer`]), laid out on the model's particles; a
//!   [`balloon_integrate::explicit::SecondOrderSystem`].
//! * [`TwoLayerSimulation`]: steps with any [`ExplicitMethod`], resolves collisions (Sec. 4.6),
//!   reports [`TwoLayerStats`] and stops with [`TwoLayerError::BlowUp`] on NaN or energy growth.
//!
//! ```
//! use balloon::two_layer::{TwoLayerBody, ExplicitMethod};
//! let body = TwoLayerBody::octahedron_sphere(1)
//!     .with_radii(0.8, 1.0)
//!     .with_pressure(200.0, 200.0);
//! let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
//! let stats = sim.step().unwrap();
//! assert!(stats.volume_outer > stats.volume_inner);
//! ```
//!
//! **Particle layout.** In 2D and 3D particles `0..n` are the inner layer and `n..2n` the outer
//! layer, with inner particle `j` paired to outer particle `j + n` (same direction from the
//! centre). In 1D particle 0 is the fixed end and particle 1 the free end.
//!
//! **Gas.** Following seed Sec. 4.7 (Steps 6-9), each closed layer encloses its own gas with
//! constant `nRT`: `P_k = (nRT)_k / V_k` (seed Eq. 4.10) acts outward on layer `k` only. The
//! region between the layers is the elastic material itself, modelled by the radius and shear
//! springs, not a gas. The force is exactly `-dU/dx` of `U_gas = -(nRT)_k ln(V_k / V_k0)`, so the
//! undamped model conserves energy. Pressures are given as *initial* pressures at the rest
//! volume: `(nRT)_k = P_k0 V_k0`.

pub mod analytic;
mod containment;
mod forces;
mod model;
mod sim;

pub use balloon_constraint::two_layer::AxisBox;
pub use balloon_integrate::explicit::ExplicitMethod;
pub use forces::{AnchorSpring, DragTarget, EnergyBreakdown, TwoLayerForces};
pub use model::{Dimension, Shape, Spring, SpringKind, SpringParams, TwoLayerBody, TwoLayerModel};
pub use sim::{TwoLayerSimulation, TwoLayerStats};

use thiserror::Error;

/// Errors of the two-layer system.
#[derive(Debug, Error)]
pub enum TwoLayerError {
    /// A parameter is out of range (non-positive mass, radius, time step, spring constant, ...).
    /// The message names the parameter and the allowed range.
    #[error("invalid two-layer parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is invalid and what is allowed.
        reason: String,
    },
    /// A sphere generator rejected its parameters (e.g. too few slices).
    #[error("cannot build the two-layer sphere: {0}")]
    Mesh(#[from] balloon_mesh::MeshError),
    /// The collision box or restitution is invalid.
    #[error(transparent)]
    Collision(#[from] balloon_constraint::ConstraintError),
    /// The integrator rejected the step (bad time step or state size).
    #[error(transparent)]
    Integrator(#[from] balloon_integrate::explicit::ExplicitError),
    /// The simulation blew up: a position or velocity became NaN or infinite, or the total energy
    /// grew beyond the initial energy plus the work done by the drag by more than the allowed
    /// bound. Explicit integrators are only conditionally stable: use a smaller `dt`, softer
    /// springs, heavier particles, more damping, or RK4 / symplectic Euler.
    #[error(
        "simulation blew up at step {step} (t = {time:.6} s) with the {method} integrator and dt = {dt:e} s: {reason}; try a smaller dt (e.g. {suggested_dt:e} s), softer springs or more damping"
    )]
    BlowUp {
        /// The step that failed (1-based count of steps taken).
        step: usize,
        /// Simulated time at the failure (s).
        time: f64,
        /// The integrator.
        method: ExplicitMethod,
        /// The time step (s).
        dt: f64,
        /// A smaller time step to try (s).
        suggested_dt: f64,
        /// What was detected.
        reason: BlowUpReason,
    },
}

/// What the blow-up check of [`TwoLayerSimulation::step`] detected, with its numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlowUpReason {
    /// A particle's position (`velocity == false`) or velocity became NaN or infinite.
    NonFinite {
        /// The particle.
        particle: usize,
        /// Whether the velocity (rather than the position) is not finite.
        velocity: bool,
    },
    /// A gas-filled layer enclosed a non-positive volume.
    InvertedLayer {
        /// `"outer"` or `"inner"`.
        layer: &'static str,
        /// Its signed enclosed volume (m^3, or m^2 in 2D).
        volume: f64,
    },
    /// The total energy exceeded `initial + work + tolerance * scale` (or is not finite).
    EnergyGrowth {
        /// Total energy after the step (J).
        total: f64,
        /// The bound it exceeded (J).
        bound: f64,
        /// Initial total energy (J).
        initial: f64,
        /// Work done by the drag so far (J).
        work: f64,
        /// Allowed growth in units of the energy scale.
        tolerance: f64,
        /// The energy scale (J).
        scale: f64,
    },
}

impl std::fmt::Display for BlowUpReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::NonFinite { particle, velocity } => {
                let what = if velocity { "velocity" } else { "position" };
                write!(f, "{what} of particle {particle} is not finite")
            }
            Self::InvertedLayer { layer, volume } => {
                write!(
                    f,
                    "the gas-filled {layer} layer turned inside out (volume {volume:e})"
                )
            }
            Self::EnergyGrowth {
                total,
                bound,
                initial,
                work,
                tolerance,
                scale,
            } => write!(
                f,
                "total energy {total:.6e} J exceeds the bound {bound:.6e} J (initial {initial:.6e} J + work {work:.6e} J + {tolerance} x energy scale {scale:.6e} J)"
            ),
        }
    }
}

pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, TwoLayerError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(TwoLayerError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: "must be a positive finite number".into(),
        })
    }
}

pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, TwoLayerError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(TwoLayerError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: "must be a finite number >= 0".into(),
        })
    }
}
