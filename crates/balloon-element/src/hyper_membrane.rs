//! Constant-strain membrane triangle for the incompressible hyperelastic membranes of
//! `balloon_material::membrane`.

use balloon_material::membrane::MembraneMaterial;
use nalgebra::{Matrix2, SMatrix, Vector3};

use crate::ElementError;
use crate::expand::edge_to_vertex_hessian;
use crate::prism::project_psd;
use crate::triangle::{check_area, check_positions, rest_triangle};

mod rest_derivative;

const NAME: &str = "hyper membrane";

/// A constant-strain triangle of an incompressible rubber membrane (plane stress), for the
/// models of `balloon_material::membrane` (`docs/membranes.md`, Eq. M22-M26).
///
/// Kinematics: with an orthonormal frame `(T1, T2)` of the rest plane (`T1 = E12/|E12|`,
/// `T2 = N x T1`), the in-plane deformation gradient is the 3x2 matrix
/// `Fm = [e12 e13] Dm^-1`, `Dm = [T.E12 T.E13]` (2x2), and the in-plane right Cauchy-Green
/// tensor is `C = Fm^T Fm` (2x2). Unlike [`crate::ThreePrism`] there is no thickness state and no
/// normal in `F`: the thickness follows incompressibility, `h = H / sqrt(det C)`
/// ([`HyperMembrane::thickness`]), and the energy is that of the membrane model,
///
/// `E = A0 H W(C)` (J), with `A0` the rest area and `H` the rest thickness.
///
/// Forces: `dE = A0 H (S/2) : dC = A0 H (Fm S) : dFm`, so `dE/d[e12 e13] = A0 H Fm S Dm^-T`
/// and `f1 = g12 + g13`, `f2 = -g12`, `f3 = -g13` (`g = dE/de`). Stiffness: the 6x6 Hessian with
/// respect to the edges, `dG = A0 H (dFm S + Fm dS) Dm^-T` with `dS` the model's stress
/// differential at `dC = dFm^T Fm + Fm^T dFm`, expanded to the 9 vertex coordinates by
/// translation invariance. The energy depends on the positions only through `C`, so it is
/// invariant under rigid motions: the forces have zero sum and zero torque.
///
/// Conventions as for the other elements: positions in metres (world frame), forces in newtons,
/// `forces = -dE/dx`, stiffness `K = d^2E/dx^2` (N/m, 9x9, vertex-major `[x1 y1 z1 x2 ..]`),
/// `force_differential(dx) = -K dx`. The hot-path methods assume a valid state (finite,
/// non-degenerate triangle, admissible for the model); see [`HyperMembrane::check_state`] and
/// [`HyperMembrane::is_admissible`]. Outside it the energy is `+infinity` and forces are NaN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HyperMembrane {
    dm_inv: Matrix2<f64>,
    rest_area: f64,
    rest_thickness: f64,
}

impl HyperMembrane {
    /// Rest data from the rest vertex positions `rest` (m) and the rest thickness `thickness`
    /// = H (m).
    ///
    /// # Errors
    /// * [`ElementError::NonFinite`] for a non-finite position or thickness;
    /// * [`ElementError::InvalidParameter`] naming `thickness` if `H <= 0`;
    /// * [`ElementError::DegenerateRest`] (quantity `area`) for a (near) zero-area triangle,
    ///   `|E12 x E13| <= 1e-12 (|E12|^2 + |E13|^2)`.
    pub fn try_new(rest: [Vector3<f64>; 3], thickness: f64) -> Result<Self, ElementError> {
        let tri = rest_triangle(NAME, &rest, thickness)?;
        let (e12, e13) = (tri.e12, tri.e13);
        let t1 = e12 / e12.norm();
        let t2 = (tri.normal / tri.normal_norm).cross(&t1);
        let dm = Matrix2::new(t1.dot(&e12), t1.dot(&e13), t2.dot(&e12), t2.dot(&e13));
        let dm_inv = dm.try_inverse().ok_or(tri.degenerate(NAME))?;
        Ok(Self {
            dm_inv,
            rest_area: tri.area,
            rest_thickness: thickness,
        })
    }

    /// Rest area `A0` (m^2).
    pub fn rest_area(&self) -> f64 {
        self.rest_area
    }

    /// Rest thickness `H` (m).
    pub fn rest_thickness(&self) -> f64 {
        self.rest_thickness
    }

    /// Rest volume `A0 H` (m^3).
    pub fn rest_volume(&self) -> f64 {
        self.rest_area * self.rest_thickness
    }

    /// Checks that the current triangle is finite and not degenerate
    /// (`|e12 x e13| > 1e-12 (|e12|^2 + |e13|^2)`). Whether the model accepts the stretch is a
    /// separate question, see [`HyperMembrane::is_admissible`].
    ///
    /// # Errors
    /// [`ElementError::NonFinite`] or [`ElementError::Degenerate`] (quantity `area`).
    pub fn check_state(&self, x: &[Vector3<f64>; 3]) -> Result<(), ElementError> {
        check_positions(NAME, x)?;
        check_area(NAME, x)
    }

    /// Whether the model is defined at the current state (for example below Gent's
    /// extensibility limit), see `MembraneMaterial::is_admissible`.
    pub fn is_admissible<M: MembraneMaterial>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> bool {
        mat.is_admissible(&self.right_cauchy_green(x))
    }

    /// In-plane deformation gradient `Fm = [e12 e13] Dm^-1` (3x2, dimensionless), mapping the
    /// rest-plane frame `(T1, T2)` to the current configuration.
    #[inline]
    pub fn in_plane_deformation_gradient(&self, x: &[Vector3<f64>; 3]) -> SMatrix<f64, 3, 2> {
        SMatrix::<f64, 3, 2>::from_columns(&[x[1] - x[0], x[2] - x[0]]) * self.dm_inv
    }

    /// In-plane right Cauchy-Green tensor `C = Fm^T Fm` (2x2, dimensionless).
    #[inline]
    pub fn right_cauchy_green(&self, x: &[Vector3<f64>; 3]) -> Matrix2<f64> {
        let fm = self.in_plane_deformation_gradient(x);
        fm.transpose() * fm
    }

    /// Current thickness `h = H / sqrt(det C)` (m), from incompressibility: the current area is
    /// `A0 sqrt(det C)` and the volume `A0 H` is kept.
    pub fn thickness(&self, x: &[Vector3<f64>; 3]) -> f64 {
        balloon_material::membrane::incompressible_thickness(
            self.rest_thickness,
            &self.right_cauchy_green(x),
        )
    }

    /// Elastic energy `A0 H W(C)` (J).
    pub fn energy<M: MembraneMaterial>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> f64 {
        self.rest_volume() * mat.energy(&self.right_cauchy_green(x))
    }

    /// `dE/d[e12 e13] = A0 H Fm S Dm^-T` (3x2, N).
    #[inline]
    fn edge_gradient(&self, fm: &SMatrix<f64, 3, 2>, s: &Matrix2<f64>) -> SMatrix<f64, 3, 2> {
        fm * s * self.dm_inv.transpose() * self.rest_volume()
    }

    /// Elastic forces `-dE/dx_i` (N) on the three vertices.
    pub fn forces<M: MembraneMaterial>(&self, mat: &M, x: &[Vector3<f64>; 3]) -> [Vector3<f64>; 3] {
        let fm = self.in_plane_deformation_gradient(x);
        let s = mat.stress(&(fm.transpose() * fm));
        let g = self.edge_gradient(&fm, &s);
        let (g12, g13) = (g.column(0).into_owned(), g.column(1).into_owned());
        [g12 + g13, -g12, -g13]
    }

    /// Energy and forces together (one stress evaluation).
    pub fn energy_and_forces<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> (f64, [Vector3<f64>; 3]) {
        let fm = self.in_plane_deformation_gradient(x);
        let (w, s) = mat.energy_and_stress(&(fm.transpose() * fm));
        let g = self.edge_gradient(&fm, &s);
        let (g12, g13) = (g.column(0).into_owned(), g.column(1).into_owned());
        (self.rest_volume() * w, [g12 + g13, -g12, -g13])
    }

    /// Differential of `dE/d[e12 e13]` along an edge variation `dDs = [de12 de13]`.
    #[inline]
    fn edge_gradient_differential<M: MembraneMaterial>(
        &self,
        mat: &M,
        fm: &SMatrix<f64, 3, 2>,
        c: &Matrix2<f64>,
        s: &Matrix2<f64>,
        dds: &SMatrix<f64, 3, 2>,
    ) -> SMatrix<f64, 3, 2> {
        let dfm = dds * self.dm_inv;
        let ftdf = fm.transpose() * dfm;
        let dc = ftdf + ftdf.transpose();
        let ds = mat.stress_differential(c, &dc);
        (dfm * s + fm * ds) * self.dm_inv.transpose() * self.rest_volume()
    }

    /// Force differential `df = -K dx` (N) along vertex displacements `dx` (m).
    pub fn force_differential<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        dx: &[Vector3<f64>; 3],
    ) -> [Vector3<f64>; 3] {
        let fm = self.in_plane_deformation_gradient(x);
        let c = fm.transpose() * fm;
        let s = mat.stress(&c);
        let dds = SMatrix::<f64, 3, 2>::from_columns(&[dx[1] - dx[0], dx[2] - dx[0]]);
        let dg = self.edge_gradient_differential(mat, &fm, &c, &s, &dds);
        let (a, b) = (dg.column(0).into_owned(), dg.column(1).into_owned());
        [a + b, -a, -b]
    }

    /// Evaluates the kinematics and the stress once at `x` so that the forces and many force
    /// differentials (one per CG iteration of a matrix-free Newton solve, Wang et al. 2015, Eq. 11) reuse
    /// them. Assumes a valid state, like the other hot-path methods.
    pub fn linearize<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> HyperMembraneLinearization {
        let fm = self.in_plane_deformation_gradient(x);
        let c = fm.transpose() * fm;
        let s = mat.stress(&c);
        HyperMembraneLinearization {
            element: *self,
            fm,
            c,
            s,
        }
    }

    /// Forces and the 6x6 Hessian with respect to the edge vectors `(e12, e13)`.
    fn forces_and_edge_hessian<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 6, 6>) {
        let fm = self.in_plane_deformation_gradient(x);
        let c = fm.transpose() * fm;
        let s = mat.stress(&c);
        let g = self.edge_gradient(&fm, &s);
        let mut ke = SMatrix::<f64, 6, 6>::zeros();
        for col in 0..6 {
            let mut dds = SMatrix::<f64, 3, 2>::zeros();
            dds[(col % 3, col / 3)] = 1.0;
            let dg = self.edge_gradient_differential(mat, &fm, &c, &s, &dds);
            ke.fixed_view_mut::<3, 1>(0, col).copy_from(&dg.column(0));
            ke.fixed_view_mut::<3, 1>(3, col).copy_from(&dg.column(1));
        }
        let (g12, g13) = (g.column(0).into_owned(), g.column(1).into_owned());
        ([g12 + g13, -g12, -g13], ke)
    }

    /// Stiffness `K = d^2E/dx^2` (N/m), 9x9 vertex-major, symmetric; indefinite in compression
    /// (a membrane buckles) and for a material past its pressure-maximum softening.
    pub fn stiffness<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_stiffness(mat, x).1
    }

    /// Forces and exact stiffness together (shared kinematics and stress).
    pub fn forces_and_stiffness<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let (f, ke) = self.forces_and_edge_hessian(mat, x);
        (f, edge_to_vertex_hessian::<6, 9>(&ke))
    }

    /// Forces and the positive semi-definite projection of the stiffness, for projected Newton:
    /// `S^T Ke+ S` with `Ke+` the nearest PSD matrix to the 6x6 edge Hessian (eigenvalues clamped
    /// at zero; unchanged when `Ke` is already positive semi-definite), exactly as
    /// [`crate::ThreePrism::forces_and_projected_stiffness`]. The forces are exact.
    pub fn forces_and_projected_stiffness<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let (f, ke) = self.forces_and_edge_hessian(mat, x);
        (f, edge_to_vertex_hessian::<6, 9>(&project_psd(ke)))
    }

    /// Projected stiffness alone (see [`HyperMembrane::forces_and_projected_stiffness`]).
    pub fn projected_stiffness<M: MembraneMaterial>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_projected_stiffness(mat, x).1
    }

    /// Lumped vertex masses `rho A0 H / 3` each (kg) for a density `density` (kg/m^3).
    pub fn lumped_masses(&self, density: f64) -> [f64; 3] {
        [density * self.rest_volume() / 3.0; 3]
    }
}

/// A [`HyperMembrane`] linearised at one state by [`HyperMembrane::linearize`]: `Fm`, `C` and
/// the stress are evaluated once, and [`HyperMembraneLinearization::force_differential`] applies
/// `df = -K dx` without recomputing them. The material passed to `force_differential` must be
/// the one used to linearise.
#[derive(Clone, Copy, Debug)]
pub struct HyperMembraneLinearization {
    element: HyperMembrane,
    fm: SMatrix<f64, 3, 2>,
    c: Matrix2<f64>,
    s: Matrix2<f64>,
}

impl HyperMembraneLinearization {
    /// In-plane right Cauchy-Green tensor `C` at the linearisation state.
    pub fn right_cauchy_green(&self) -> &Matrix2<f64> {
        &self.c
    }

    /// Elastic forces `-dE/dx_i` (N) at the linearisation state (same as
    /// [`HyperMembrane::forces`]).
    pub fn forces(&self) -> [Vector3<f64>; 3] {
        let g = self.element.edge_gradient(&self.fm, &self.s);
        let (g12, g13) = (g.column(0).into_owned(), g.column(1).into_owned());
        [g12 + g13, -g12, -g13]
    }

    /// Force differential `df = -K dx` (N), same as [`HyperMembrane::force_differential`] at the
    /// linearisation state.
    pub fn force_differential<M: MembraneMaterial>(
        &self,
        mat: &M,
        dx: &[Vector3<f64>; 3],
    ) -> [Vector3<f64>; 3] {
        let dds = SMatrix::<f64, 3, 2>::from_columns(&[dx[1] - dx[0], dx[2] - dx[0]]);
        let dg = self
            .element
            .edge_gradient_differential(mat, &self.fm, &self.c, &self.s, &dds);
        let (a, b) = (dg.column(0).into_owned(), dg.column(1).into_owned());
        [a + b, -a, -b]
    }
}

#[cfg(test)]
mod tests;
