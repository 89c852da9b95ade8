//! [`DesignError`]: what can go wrong in a design, in the library's words.

use balloon_element::ElementError;

/// A design that cannot be made or checked.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// A parameter out of its range.
    #[error("`{name}` = {value} is not allowed: {allowed}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// Its value (a length for a list of the wrong size).
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// The target surface cannot be designed for.
    #[error("target: {0}")]
    Target(String),
    /// A rest triangle of a trial rest shape is degenerate or not finite.
    #[error("rest element {element}: {source}")]
    RestElement {
        /// The element (face) index.
        element: usize,
        /// The element's own error.
        source: ElementError,
    },
    /// A non-finite value appeared.
    #[error("{0} is not finite")]
    NonFinite(&'static str),
    /// The linear solve of a Gauss-Newton step failed.
    #[error("linear solve: {0}")]
    Linear(String),
    /// The forward static solve could not be set up or failed outright.
    #[error("forward static solve: {0}")]
    Forward(String),
}
