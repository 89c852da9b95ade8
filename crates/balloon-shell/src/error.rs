//! The error of building a [`ShellSystem`](crate::ShellSystem) from its parts.

use thiserror::Error;

/// Parts of a shell system that do not fit together (before any evaluation; errors while
/// evaluating are [`balloon_integrate::SystemError`]s).
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ShellSystemError {
    /// A list does not have one entry per triangle (or per vertex). Fix: give one element and
    /// one thickness per triangle, one mass per vertex, three coordinates per vertex.
    #[error("`{what}` has {len} entries, expected {expected}")]
    LengthMismatch {
        /// Which list (`elements`, `thickness`, `vertex_masses`, `rest`).
        what: &'static str,
        /// Its length.
        len: usize,
        /// The length it must have.
        expected: usize,
    },
    /// A triangle names a vertex that does not exist. Fix: index the vertices `0..num_vertices`.
    #[error(
        "triangle {triangle}: vertex {vertex} is out of range, the shell has {num_vertices} vertices"
    )]
    VertexOutOfRange {
        /// The triangle's index.
        triangle: usize,
        /// The vertex index it names.
        vertex: usize,
        /// The number of vertices.
        num_vertices: usize,
    },
    /// The material refused a rest element (degenerate triangle, thickness not positive, a
    /// non-finite coordinate).
    #[error("element {element}: {source}")]
    Element {
        /// The triangle's index.
        element: usize,
        /// The element's own error, with its numbers.
        #[source]
        source: balloon_element::ElementError,
    },
    /// A parameter of the system is out of its range. Fix: the value named in `allowed`.
    #[error("`{name}` = {value}: must be {allowed}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
}
