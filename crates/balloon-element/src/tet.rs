//! Linear (constant-strain) tetrahedron.

use balloon_material::Material;
use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::ElementError;
use crate::expand::edge_to_vertex_hessian;

const NAME: &str = "tetrahedron";

/// Rest data of a linear tetrahedron: `F = Ds Dm^-1` with `Ds = [x2-x1 x3-x1 x4-x1]` and `Dm` its
/// rest counterpart; energy `V0 psi(F)` with `V0 = det(Dm)/6` the rest volume.
///
/// Conventions: positions `[Vector3; 4]` in m, positively oriented
/// (`(x2-x1) x (x3-x1) . (x4-x1) > 0`); forces in N; stiffness 12x12 in N/m vertex-major
/// `[x1 y1 z1 x2 .. z4]`. The hot-path methods assume finite positions; for materials that are
/// undefined for `det F <= 0` (neo-Hookean) call [`LinearTetrahedron::check_state`] first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearTetrahedron {
    dm_inv: Matrix3<f64>,
    rest_volume: f64,
}

impl LinearTetrahedron {
    /// Rest data from the four rest vertex positions (m).
    ///
    /// # Errors
    /// * [`ElementError::NonFinite`] for a non-finite position;
    /// * [`ElementError::DegenerateRest`] (quantity `volume`) if the vertices are (nearly)
    ///   coplanar: `|det Dm| <= 1e-12 l^3` with `l` the longest edge from vertex 1;
    /// * [`ElementError::InvertedRest`] if the signed rest volume is negative.
    pub fn try_new(rest: [Vector3<f64>; 4]) -> Result<Self, ElementError> {
        if rest.iter().any(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "rest position",
            });
        }
        let dm = Matrix3::from_columns(&[rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]]);
        let det = dm.determinant();
        let l = dm.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
        if det.abs() <= 1e-12 * l * l * l {
            return Err(ElementError::DegenerateRest {
                element: NAME,
                quantity: "volume",
                value: det / 6.0,
            });
        }
        if det < 0.0 {
            return Err(ElementError::InvertedRest {
                element: NAME,
                volume: det / 6.0,
            });
        }
        let dm_inv = dm.try_inverse().ok_or(ElementError::DegenerateRest {
            element: NAME,
            quantity: "volume",
            value: det / 6.0,
        })?;
        Ok(Self {
            dm_inv,
            rest_volume: det / 6.0,
        })
    }

    /// Rest volume `V0` (m^3).
    pub fn rest_volume(&self) -> f64 {
        self.rest_volume
    }

    /// Inverse rest matrix `Dm^-1` (1/m).
    pub fn rest_matrix_inverse(&self) -> &Matrix3<f64> {
        &self.dm_inv
    }

    /// Checks that the current positions are finite and the tetrahedron is not inverted or flat
    /// (`det F > 0`).
    ///
    /// # Errors
    /// [`ElementError::NonFinite`] or [`ElementError::Inverted`].
    pub fn check_state(&self, x: &[Vector3<f64>; 4]) -> Result<(), ElementError> {
        if x.iter().any(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "position",
            });
        }
        let det_f = self.deformation_gradient(x).determinant();
        if det_f <= 0.0 {
            return Err(ElementError::Inverted {
                element: NAME,
                det_f,
            });
        }
        Ok(())
    }

    /// Deformation gradient `F = Ds Dm^-1` (dimensionless).
    pub fn deformation_gradient(&self, x: &[Vector3<f64>; 4]) -> Matrix3<f64> {
        Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]) * self.dm_inv
    }

    /// Elastic energy `V0 psi(F)` (J).
    pub fn energy<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 4]) -> f64 {
        self.rest_volume * mat.energy_density(&self.deformation_gradient(x))
    }

    #[inline]
    fn forces_from_gradient(g: &Matrix3<f64>) -> [Vector3<f64>; 4] {
        let (a, b, c) = (g.column(0), g.column(1), g.column(2));
        [a + b + c, -a, -b, -c]
    }

    /// Elastic forces `f_i = -V0 P(F) dF/dx_i` (N): with `G = V0 P Dm^-T`,
    /// `f_{2,3,4} = -G_{1,2,3}` and `f_1 = G_1 + G_2 + G_3`.
    pub fn forces<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 4]) -> [Vector3<f64>; 4] {
        let p = mat.first_piola(&self.deformation_gradient(x));
        Self::forces_from_gradient(&(p * self.dm_inv.transpose() * self.rest_volume))
    }

    /// Force differential `df = -K dx = -V0 dP(F; dDs Dm^-1) Dm^-T` distributed like the forces
    /// (N).
    pub fn force_differential<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 4],
        dx: &[Vector3<f64>; 4],
    ) -> [Vector3<f64>; 4] {
        let f = self.deformation_gradient(x);
        let df = self.deformation_gradient(dx);
        let dp = mat.first_piola_differential(&f, &df);
        Self::forces_from_gradient(&(dp * self.dm_inv.transpose() * self.rest_volume))
    }

    /// Stiffness `K = -df/dx` (N/m), 12x12 vertex-major, symmetric.
    pub fn stiffness<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 4]) -> SMatrix<f64, 12, 12> {
        self.forces_and_stiffness(mat, x).1
    }

    /// Forces and stiffness together; the stiffness is built from 9 (batched) material differentials with
    /// respect to the three edge vectors and expanded by translation invariance.
    pub fn forces_and_stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 4],
    ) -> ([Vector3<f64>; 4], SMatrix<f64, 12, 12>) {
        let f = self.deformation_gradient(x);
        let dmt = self.dm_inv.transpose() * self.rest_volume;
        let p = mat.first_piola(&f);
        // Unit variation of component c % 3 of edge c / 3: dDs = unit(c % 3, c / 3), so
        // dF = unit(c % 3) (row c / 3 of Dm^-1).
        let dfs: [Matrix3<f64>; 9] = std::array::from_fn(|c| {
            let mut dds = Matrix3::zeros();
            dds[(c % 3, c / 3)] = 1.0;
            dds * self.dm_inv
        });
        let dps = mat.first_piola_differentials(&f, &dfs);
        let mut ke = SMatrix::<f64, 9, 9>::zeros();
        for c in 0..9 {
            let dg = dps[c] * dmt;
            ke.column_mut(c).copy_from_slice(dg.as_slice());
        }
        (
            Self::forces_from_gradient(&(p * dmt)),
            edge_to_vertex_hessian::<9, 12>(&ke),
        )
    }

    /// Lumped vertex masses `rho V0 / 4` each (kg) for density `density` (kg/m^3).
    pub fn lumped_masses(&self, density: f64) -> [f64; 4] {
        [density * self.rest_volume / 4.0; 4]
    }
}
