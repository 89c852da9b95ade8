//! Membrane triangle: a thin triangle with a fixed thickness.

use balloon_material::Material;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector3};

use crate::{ElementError, ThreePrism};

/// A constant-strain membrane triangle whose thickness is a fixed parameter, not a state.
///
/// Kinematics: with an orthonormal rest frame `(T1, T2)` in the rest plane
/// (`T1 = E12/|E12|`, `T2 = D x T1`), the in-plane deformation gradient is the 3x2 matrix
/// `Fm = [e12 e13] [T.E12 T.E13]^-1` ([`MembraneTriangle::in_plane_deformation_gradient`]). To use
/// the 3x3 materials of `balloon-material` it is completed by the current unit normal times a
/// fixed thickness stretch `lambda3` (default 1): `F = [Fm | lambda3 d]` in the rest frame
/// `(T1, T2, D)`, so `F T1 = Fm_1`, `F T2 = Fm_2`, `F D = lambda3 d`. This is exactly the
/// [`ThreePrism`] gradient with the current thickness frozen at `h = lambda3 H`, and the energy is
/// `A H psi(F)` (J). The choice keeps the thickness from adapting to in-plane stretch (no
/// plane-stress thinning): for the same material the membrane is stiffer in-plane than a
/// plane-stress model by the usual `lambda` versus `2 mu lambda / (lambda + 2 mu)` difference.
/// Forces and stiffness include the normal-variation terms, as for [`ThreePrism`].
///
/// Conventions: positions in m, forces in N, stiffness 9x9 in N/m vertex-major. Hot-path methods
/// assume a non-degenerate current triangle; see [`MembraneTriangle::check_state`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneTriangle {
    prism: ThreePrism,
    thickness_stretch: f64,
    in_plane_inv: Matrix2<f64>,
}

impl MembraneTriangle {
    /// A membrane with rest vertices `rest` (m) and fixed thickness `thickness` (m), thickness
    /// stretch 1.
    ///
    /// # Errors
    /// As [`ThreePrism::try_new`] (element named `three-prism` in the message).
    pub fn try_new(rest: [Vector3<f64>; 3], thickness: f64) -> Result<Self, ElementError> {
        let prism = ThreePrism::try_new(rest, thickness)?;
        let e12 = rest[1] - rest[0];
        let e13 = rest[2] - rest[0];
        let t1 = e12.normalize();
        let t2 = e12.cross(&e13).normalize().cross(&t1);
        let dm2 = Matrix2::new(t1.dot(&e12), t1.dot(&e13), t2.dot(&e12), t2.dot(&e13));
        let in_plane_inv = dm2.try_inverse().ok_or(ElementError::DegenerateRest {
            element: "membrane triangle",
            quantity: "area",
            value: prism.rest_area(),
        })?;
        Ok(Self {
            prism,
            thickness_stretch: 1.0,
            in_plane_inv,
        })
    }

    /// The same membrane with the through-thickness stretch `lambda3 = stretch` used to complete
    /// `F` (e.g. a pre-thinned sheet).
    ///
    /// # Errors
    /// [`ElementError::InvalidParameter`] naming `thickness_stretch` unless finite and `> 0`.
    pub fn with_thickness_stretch(mut self, stretch: f64) -> Result<Self, ElementError> {
        if !(stretch.is_finite() && stretch > 0.0) {
            return Err(ElementError::InvalidParameter {
                element: "membrane triangle",
                name: "thickness_stretch",
                value: stretch,
                allowed: "finite and > 0",
            });
        }
        self.thickness_stretch = stretch;
        Ok(self)
    }

    /// Rest area `A` (m^2).
    pub fn rest_area(&self) -> f64 {
        self.prism.rest_area()
    }

    /// Fixed thickness `H` (m).
    pub fn thickness(&self) -> f64 {
        self.prism.rest_thickness()
    }

    /// Rest volume `A H` (m^3).
    pub fn rest_volume(&self) -> f64 {
        self.prism.rest_volume()
    }

    #[inline]
    fn h(&self) -> f64 {
        self.thickness_stretch * self.prism.rest_thickness()
    }

    /// Checks that the current triangle is finite and not degenerate.
    ///
    /// # Errors
    /// As [`ThreePrism::check_state`].
    pub fn check_state(&self, x: &[Vector3<f64>; 3]) -> Result<(), ElementError> {
        self.prism.check_state(x, self.h())
    }

    /// In-plane deformation gradient `Fm` (3x2, dimensionless) mapping rest-frame coordinates
    /// `(T1, T2)` to the current configuration.
    pub fn in_plane_deformation_gradient(&self, x: &[Vector3<f64>; 3]) -> SMatrix<f64, 3, 2> {
        SMatrix::<f64, 3, 2>::from_columns(&[x[1] - x[0], x[2] - x[0]]) * self.in_plane_inv
    }

    /// The completed 3x3 deformation gradient `F` (world frame, see the type documentation).
    pub fn deformation_gradient(&self, x: &[Vector3<f64>; 3]) -> Matrix3<f64> {
        self.prism.deformation_gradient(x, self.h())
    }

    /// Elastic energy `A H psi(F)` (J).
    pub fn energy<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> f64 {
        self.prism.energy(mat, x, self.h())
    }

    /// Elastic forces `-dE/dx_i` (N).
    pub fn forces<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> [Vector3<f64>; 3] {
        self.prism.forces(mat, x, self.h())
    }

    /// Force differential `df = -K dx` (N).
    pub fn force_differential<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        dx: &[Vector3<f64>; 3],
    ) -> [Vector3<f64>; 3] {
        self.prism.force_differential(mat, x, self.h(), dx)
    }

    /// Stiffness `K = -df/dx` (N/m), 9x9 vertex-major, symmetric.
    pub fn stiffness<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> SMatrix<f64, 9, 9> {
        self.prism.stiffness(mat, x, self.h())
    }

    /// Forces and stiffness together (shared work).
    pub fn forces_and_stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        self.prism.forces_and_stiffness(mat, x, self.h())
    }

    /// Lumped vertex masses `rho A H / 3` each (kg) for density `density` (kg/m^3).
    pub fn lumped_masses(&self, density: f64) -> [f64; 3] {
        self.prism.lumped_masses(density)
    }
}
