//! The error type of `balloon-gas`.

use thiserror::Error;

/// Everything that can go wrong while building a gas model or evaluating a pressure load.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GasError {
    /// The enclosed volume is zero, negative or not finite. Happens when the surface is inverted
    /// (inward-oriented triangles), collapsed, or has blown up; fix the orientation of the mesh or
    /// reduce the time step.
    #[error(
        "enclosed gas volume is {volume:e} m^3; it must be positive and finite (is the surface outward oriented and closed?)"
    )]
    InvalidVolume {
        /// The offending volume, m^3.
        volume: f64,
    },
    /// A derived quantity (pressure, its derivative) became NaN or infinite.
    #[error("non-finite {quantity} ({value:e}) at gas volume {volume:e} m^3, time {time} s")]
    NonFinite {
        /// Which quantity (e.g. "absolute pressure").
        quantity: &'static str,
        /// Its value.
        value: f64,
        /// The volume at which it was evaluated, m^3.
        volume: f64,
        /// The time at which it was evaluated, s.
        time: f64,
    },
    /// A model parameter is out of range (e.g. a non-positive initial volume). The message names
    /// the parameter and the accepted range.
    #[error("invalid gas parameter `{name}` = {value:e}: {requirement}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {vertex}, but the position array holds only {num_vertices} vertices"
    )]
    VertexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// The offending vertex index.
        vertex: usize,
        /// Number of vertices (`x.len() / 3`).
        num_vertices: usize,
    },
    /// A flat array has the wrong length.
    #[error("array `{name}` has length {len}, expected {expected}")]
    LengthMismatch {
        /// Array name (`x`, `f`, `dx`, ...).
        name: &'static str,
        /// Its length.
        len: usize,
        /// The expected length.
        expected: usize,
    },
    /// A gas kind name could not be parsed.
    #[error(
        "unknown gas kind `{0}`; expected one of \"ideal\", \"constant\", \"pump\", \"polytropic\", \"leak\", \"supply-pump\""
    )]
    UnknownKind(String),
}
