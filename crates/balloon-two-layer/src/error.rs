//! The error type of the two-layer system ([`TwoLayerError`]) and what a blow-up detected
//! ([`BlowUpReason`]).

use balloon_integrate::explicit::ExplicitMethod;
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

/// What the blow-up check of [`crate::TwoLayerSimulation::step`] detected, with its numbers.
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

impl TwoLayerError {
    /// `Ok(value)` if `value` is positive and finite, else [`TwoLayerError::InvalidParameter`]
    /// naming the parameter `name`.
    pub fn check_positive(name: &'static str, value: f64) -> Result<f64, Self> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(Self::InvalidParameter {
                name,
                value: value.to_string(),
                reason: "must be a positive finite number".into(),
            })
        }
    }

    /// `Ok(value)` if `value` is finite and `>= 0`, else [`TwoLayerError::InvalidParameter`]
    /// naming the parameter `name`.
    pub fn check_non_negative(name: &'static str, value: f64) -> Result<f64, Self> {
        if value.is_finite() && value >= 0.0 {
            Ok(value)
        } else {
            Err(Self::InvalidParameter {
                name,
                value: value.to_string(),
                reason: "must be a finite number >= 0".into(),
            })
        }
    }
}
