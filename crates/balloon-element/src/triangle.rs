//! The checks every triangle element shares: a valid rest triangle with its thickness
//! ([`rest_triangle`]) and a current triangle that can be evaluated ([`check_positions`],
//! [`check_area`]). One place for the degeneracy test, so the three-prism and the hyperelastic
//! membrane reject exactly the same triangles.

use nalgebra::Vector3;

use crate::ElementError;

/// Relative tolerance below which a triangle counts as degenerate:
/// `|e12 x e13| <= DEGENERACY_TOL * (|e12|^2 + |e13|^2)`.
pub(crate) const DEGENERACY_TOL: f64 = 1e-12;

/// The rest edges, normal and area of a checked rest triangle.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RestTriangle {
    /// `E12 = X2 - X1` (m).
    pub(crate) e12: Vector3<f64>,
    /// `E13 = X3 - X1` (m).
    pub(crate) e13: Vector3<f64>,
    /// `N = E12 x E13` (m^2, twice the area along the unit normal).
    pub(crate) normal: Vector3<f64>,
    /// `|N|` (m^2).
    pub(crate) normal_norm: f64,
    /// `A = |N| / 2` (m^2).
    pub(crate) area: f64,
}

impl RestTriangle {
    /// The error of element `element` for this rest triangle (e.g. when a rest matrix built
    /// from it cannot be inverted).
    pub(crate) fn degenerate(&self, element: &'static str) -> ElementError {
        ElementError::DegenerateRest {
            element,
            quantity: "area",
            value: self.area,
        }
    }
}

/// Checks the rest positions `rest` (m) and rest thickness `thickness` (m) of a triangle element
/// named `element` and returns its edges, normal and area.
///
/// # Errors
/// * [`ElementError::NonFinite`] for a non-finite position or thickness;
/// * [`ElementError::InvalidParameter`] naming `thickness` if `H <= 0`;
/// * [`ElementError::DegenerateRest`] (quantity `area`) for a (near) zero-area triangle,
///   `|E12 x E13| <= 1e-12 (|E12|^2 + |E13|^2)`.
pub(crate) fn rest_triangle(
    element: &'static str,
    rest: &[Vector3<f64>; 3],
    thickness: f64,
) -> Result<RestTriangle, ElementError> {
    if rest.iter().any(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(ElementError::NonFinite {
            element,
            quantity: "rest position",
        });
    }
    if !thickness.is_finite() {
        return Err(ElementError::NonFinite {
            element,
            quantity: "rest thickness",
        });
    }
    if thickness <= 0.0 {
        return Err(ElementError::InvalidParameter {
            element,
            name: "thickness",
            value: thickness,
            allowed: "> 0 m",
        });
    }
    let e12 = rest[1] - rest[0];
    let e13 = rest[2] - rest[0];
    let normal = e12.cross(&e13);
    let normal_norm = normal.norm();
    let triangle = RestTriangle {
        e12,
        e13,
        normal,
        normal_norm,
        area: 0.5 * normal_norm,
    };
    if normal_norm <= DEGENERACY_TOL * (e12.norm_squared() + e13.norm_squared()) {
        return Err(triangle.degenerate(element));
    }
    Ok(triangle)
}

/// Checks that the current positions `x` (m) of element `element` are finite.
///
/// # Errors
/// [`ElementError::NonFinite`] (quantity `position`).
pub(crate) fn check_positions(
    element: &'static str,
    x: &[Vector3<f64>; 3],
) -> Result<(), ElementError> {
    if x.iter().any(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(ElementError::NonFinite {
            element,
            quantity: "position",
        });
    }
    Ok(())
}

/// Checks that the current triangle `x` of element `element` is not degenerate
/// (`|e12 x e13| > 1e-12 (|e12|^2 + |e13|^2)`), so its unit normal exists.
///
/// # Errors
/// [`ElementError::Degenerate`] (quantity `area`).
pub(crate) fn check_area(element: &'static str, x: &[Vector3<f64>; 3]) -> Result<(), ElementError> {
    let e12 = x[1] - x[0];
    let e13 = x[2] - x[0];
    let nn = e12.cross(&e13).norm();
    if nn <= DEGENERACY_TOL * (e12.norm_squared() + e13.norm_squared()) {
        return Err(ElementError::Degenerate {
            element,
            quantity: "area",
            value: 0.5 * nn,
        });
    }
    Ok(())
}
