//! Errors of the element crate.

use thiserror::Error;

/// What can go wrong when building an element or checking its current state.
///
/// Every variant names the element kind (`"three-prism"`, `"membrane triangle"`,
/// `"tetrahedron"`, `"spring"`) and the offending quantity with its value, so a caller that knows
/// the element index can report it precisely.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ElementError {
    /// A position, thickness or parameter is NaN or infinite.
    ///
    /// Fix: check the mesh file and the solver state for non-finite numbers.
    #[error("{element}: {quantity} is not finite")]
    NonFinite {
        /// Element kind.
        element: &'static str,
        /// Which input (e.g. `"rest position of vertex 2"`, `"thickness"`).
        quantity: &'static str,
    },
    /// A scalar parameter is out of its admissible range.
    ///
    /// Happens for a non-positive thickness or thickness stretch, a negative spring stiffness,
    /// damping or rest length. Fix: pass a value in `allowed`.
    #[error("{element}: parameter `{name}` = {value} is invalid, allowed: {allowed}")]
    InvalidParameter {
        /// Element kind.
        element: &'static str,
        /// Parameter name (`thickness`, `stiffness`, ...).
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// Admissible range.
        allowed: &'static str,
    },
    /// The rest shape has (near) zero area, volume or length, so its reference matrix cannot be
    /// inverted.
    ///
    /// Happens for collinear triangle vertices, coplanar tetrahedron vertices or coincident spring
    /// ends. Fix: remove degenerate faces from the mesh (`balloon-mesh` validation reports them).
    #[error("{element}: degenerate rest shape, {quantity} = {value:e}")]
    DegenerateRest {
        /// Element kind.
        element: &'static str,
        /// `"area"`, `"volume"` or `"length"`.
        quantity: &'static str,
        /// The measured value (m^2, m^3 or m).
        value: f64,
    },
    /// The rest tetrahedron has negative signed volume (its vertices are ordered clockwise).
    ///
    /// Fix: swap two vertices of the tetrahedron so that `(x2-x1) x (x3-x1) . (x4-x1) > 0`.
    #[error("{element}: inverted rest shape, signed volume = {volume:e} m^3")]
    InvertedRest {
        /// Element kind.
        element: &'static str,
        /// Signed rest volume (m^3).
        volume: f64,
    },
    /// The current state is degenerate: zero triangle area (the unit normal of Wang et al. 2015, Eq. 1 is
    /// undefined) or zero spring length (the direction is undefined).
    ///
    /// Happens when a simulation collapses an element; reduce the time step or stiffen the model.
    #[error("{element}: degenerate current state, {quantity} = {value:e}")]
    Degenerate {
        /// Element kind.
        element: &'static str,
        /// `"area"` or `"length"`.
        quantity: &'static str,
        /// The measured value (m^2 or m).
        value: f64,
    },
    /// The current tetrahedron is inverted or flat (`det F <= 0`).
    ///
    /// Happens when a simulation turns an element inside out; reduce the time step or use a
    /// material that resists inversion (neo-Hookean).
    #[error("{element}: inverted current state, det F = {det_f:e}")]
    Inverted {
        /// Element kind.
        element: &'static str,
        /// Determinant of the deformation gradient.
        det_f: f64,
    },
}
