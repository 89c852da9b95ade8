//! Errors of the material crate.

use thiserror::Error;

/// `value` as a message shows it: plain (`-1`, `0.45`) unless very small or large, then in
/// exponent form (`1e-300`, not three hundred zeros).
pub(crate) fn number(value: f64) -> String {
    let a = value.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// What can go wrong when building a material from user parameters.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum MaterialError {
    /// A material parameter is outside its admissible range (or not finite).
    ///
    /// Happens for example for a non-positive Young's modulus, a Poisson ratio outside
    /// `(-1, 0.5)`, or Lame parameters whose bulk modulus `lambda + 2 mu / 3` is not positive.
    /// Fix: pass a value inside `allowed`.
    #[error(
        "invalid material parameter `{name}` = {}: allowed range is {allowed}",
        number(*value)
    )]
    InvalidParameter {
        /// Name of the parameter (`young`, `poisson`, `mu`, `lambda`, and for the membranes
        /// `c1`, `c2`, `c3`, `jm`, `ogden_mu`, `ogden_alpha`, `radius`, `thickness`, ...).
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
    /// A membrane model name that is not one of the known models.
    ///
    /// Happens when parsing a [`crate::membrane::MembraneKind`] from a string. Fix: use one of
    /// `membrane-neo-hookean`, `membrane-mooney-rivlin`, `membrane-gent`, `membrane-ogden`,
    /// `membrane-yeoh` (the `membrane-` prefix is optional).
    #[error(
        "unknown membrane model `{0}`: expected one of membrane-neo-hookean, membrane-mooney-rivlin, membrane-gent, membrane-ogden, membrane-yeoh"
    )]
    UnknownMembraneModel(String),
    /// A membrane preset name that is not one of the known presets.
    ///
    /// Happens when parsing a [`crate::membrane::MembranePreset`] from a string. Fix: use one of
    /// `natural-rubber`, `elastosil-m4601`.
    #[error("unknown membrane preset `{0}`: expected one of natural-rubber, elastosil-m4601")]
    UnknownPreset(String),
    /// The Ogden lists `mu_p` and `alpha_p` have different lengths (or are empty).
    ///
    /// Happens for `--ogden-mu a,b,c --ogden-alpha x,y`. Fix: give one `alpha_p` per `mu_p`, at
    /// least one term.
    #[error(
        "Ogden model needs one alpha per mu and at least one term: got {mu_terms} mu and {alpha_terms} alpha values"
    )]
    OgdenTermMismatch {
        /// Number of `mu_p` values given.
        mu_terms: usize,
        /// Number of `alpha_p` values given.
        alpha_terms: usize,
    },
}
