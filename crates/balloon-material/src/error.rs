//! Errors of the material crate.

use thiserror::Error;

/// What can go wrong when building a material from user parameters.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum MaterialError {
    /// A material parameter is outside its admissible range (or not finite).
    ///
    /// Happens for example for a non-positive Young's modulus, a Poisson ratio outside
    /// `(-1, 0.5)`, or Lame parameters whose bulk modulus `lambda + 2 mu / 3` is not positive.
    /// Fix: pass a value inside `allowed`.
    #[error("invalid material parameter `{name}` = {value}: allowed range is {allowed}")]
    InvalidParameter {
        /// Name of the parameter (`young`, `poisson`, `mu`, `lambda`).
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// Human-readable admissible range.
        allowed: &'static str,
    },
    /// A material name that is not one of the known models.
    ///
    /// Happens when parsing a [`crate::MaterialKind`] from a string. Fix: use one of `stvk`,
    /// `st-venant-kirchhoff`, `neo-hookean`, `neohookean`.
    #[error(
        "unknown material model `{0}`: expected one of stvk, st-venant-kirchhoff, neo-hookean, neohookean"
    )]
    UnknownModel(String),
}
