//! The three-prism shell element of Wang et al. 2015 (Sec. 4, Eq. 1-4, 8, 11, 19).

use balloon_material::Material;
use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::ElementError;
use crate::expand::edge_to_vertex_hessian;
use crate::triangle::{check_area, check_positions, rest_triangle};

mod rest_derivative;

const NAME: &str = "three-prism";

/// Rest data of one three-prism element: a triangle extruded along its unit normal by a thickness
/// (Wang et al. 2015, Sec. 4, Fig. 1).
///
/// A point of the element with parameters `alpha = (a1, a2, a3)` is (Eq. 1)
/// `x(alpha) = (1 - a1 - a2) x1 + a1 x2 + a2 x3 + a3 h d`, `d = (e12 x e13) / |e12 x e13|`,
/// so the deformation gradient is constant in the element (Eq. 4):
///
/// `F = [e12 e13 d h] [E12 E13 D H]^-1 = Ds Dm^-1`,
///
/// where capital letters are rest quantities. The three vertex positions are degrees of freedom;
/// the current thickness `h` is a *parameter* (changed only by the shell-volume projection of
/// Wang et al. 2015, Sec. 7). Because `d` is the current unit normal, `F` depends non-linearly on the
/// positions and the forces and stiffness include the derivative of `d` (see `docs/elements.md`):
/// through `dF` always, and through a geometric "normal lever" term that vanishes identically for
/// isotropic materials (then `P D` is parallel to `d`) but is kept for general ones.
/// Note `det F = (|e12 x e13| h) / (|E12 x E13| H) > 0`: the element cannot invert.
///
/// Array conventions: positions `x: [Vector3; 3]` in metres (world frame, counter-clockwise seen
/// from outside so that `d` points outwards), thickness in metres, forces in newtons, stiffness in
/// N/m with vertex-major ordering `[x1 y1 z1 x2 y2 z2 x3 y3 z3]`.
///
/// The hot-path methods assume a valid state (finite positions, non-degenerate triangle,
/// `h > 0`); call [`ThreePrism::check_state`] to verify one. On a zero-area triangle they return
/// non-finite numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThreePrism {
    dm_inv: Matrix3<f64>,
    rest_area: f64,
    rest_thickness: f64,
}

/// Current kinematic quantities shared by energy, forces and differentials.
#[derive(Clone, Copy, Debug)]
struct Kinematics {
    e12: Vector3<f64>,
    e13: Vector3<f64>,
    /// Current unit normal.
    d: Vector3<f64>,
    /// `1 / |e12 x e13|`.
    inv_n: f64,
    h: f64,
    f: Matrix3<f64>,
}

/// Stress quantities at the current state.
#[derive(Clone, Copy, Debug)]
struct Stress {
    /// `V0 P Dm^-T`: its columns are `dE/d(e12)`, `dE/d(e13)`, `dE/d(h d)` at fixed `d`.
    g: Matrix3<f64>,
    /// `h / |n| (I - d d^T) g3`, the normal-variation lever (see `docs/elements.md`).
    q: Vector3<f64>,
}

impl ThreePrism {
    /// Rest data from the rest vertex positions (m) and rest thickness `thickness` = H (m).
    ///
    /// # Errors
    /// * [`ElementError::NonFinite`] for a non-finite position or thickness;
    /// * [`ElementError::InvalidParameter`] naming `thickness` if `H <= 0`;
    /// * [`ElementError::DegenerateRest`] (quantity `area`) for a (near) zero-area triangle,
    ///   `|E12 x E13| <= 1e-12 (|E12|^2 + |E13|^2)`.
    pub fn try_new(rest: [Vector3<f64>; 3], thickness: f64) -> Result<Self, ElementError> {
        let tri = rest_triangle(NAME, &rest, thickness)?;
        let (n, nn) = (tri.normal, tri.normal_norm);
        let dm = Matrix3::from_columns(&[tri.e12, tri.e13, n * (thickness / nn)]);
        let dm_inv = dm.try_inverse().ok_or(tri.degenerate(NAME))?;
        Ok(Self {
            dm_inv,
            rest_area: tri.area,
            rest_thickness: thickness,
        })
    }

    /// Rest triangle area `A` (m^2).
    pub fn rest_area(&self) -> f64 {
        self.rest_area
    }

    /// Rest thickness `H` (m).
    pub fn rest_thickness(&self) -> f64 {
        self.rest_thickness
    }

    /// Rest volume `V^e = A H` (m^3), the `V^e` of Wang et al. 2015, Eq. 8 and 19.
    pub fn rest_volume(&self) -> f64 {
        self.rest_area * self.rest_thickness
    }

    /// The inverse rest matrix `Dm^-1 = [E12 E13 D H]^-1` of Eq. 4 (1/m).
    pub fn rest_matrix_inverse(&self) -> &Matrix3<f64> {
        &self.dm_inv
    }

    /// Checks that the current state can be evaluated: finite positions, finite `h > 0` and a
    /// non-degenerate triangle (`|e12 x e13| > 1e-12 (|e12|^2 + |e13|^2)`), so the unit normal `d`
    /// exists.
    ///
    /// # Errors
    /// [`ElementError::NonFinite`], [`ElementError::InvalidParameter`] (thickness) or
    /// [`ElementError::Degenerate`] (quantity `area`).
    pub fn check_state(&self, x: &[Vector3<f64>; 3], h: f64) -> Result<(), ElementError> {
        check_positions(NAME, x)?;
        if !h.is_finite() {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "thickness",
            });
        }
        if h <= 0.0 {
            return Err(ElementError::InvalidParameter {
                element: NAME,
                name: "thickness",
                value: h,
                allowed: "> 0 m",
            });
        }
        check_area(NAME, x)
    }

    #[inline]
    fn kinematics(&self, x: &[Vector3<f64>; 3], h: f64) -> Kinematics {
        let e12 = x[1] - x[0];
        let e13 = x[2] - x[0];
        let n = e12.cross(&e13);
        let inv_n = 1.0 / n.norm();
        let d = n * inv_n;
        let ds = Matrix3::from_columns(&[e12, e13, d * h]);
        Kinematics {
            e12,
            e13,
            d,
            inv_n,
            h,
            f: ds * self.dm_inv,
        }
    }

    #[inline]
    fn stress(&self, k: &Kinematics, p: &Matrix3<f64>) -> Stress {
        let g = p * self.dm_inv.transpose() * self.rest_volume();
        let g3 = g.column(2).into_owned();
        let q = (g3 - k.d * k.d.dot(&g3)) * (k.h * k.inv_n);
        Stress { g, q }
    }

    /// `(dE/de12, dE/de13)`; `dE/dx1` is minus their sum.
    #[inline]
    fn edge_gradient(k: &Kinematics, s: &Stress) -> (Vector3<f64>, Vector3<f64>) {
        (
            s.g.column(0) + k.e13.cross(&s.q),
            s.g.column(1) + s.q.cross(&k.e12),
        )
    }

    /// First half of the differential along edge variations `(de12, de13)`: the normal variation
    /// `dd = (I - d d^T) dn / |n|`, `d . dn`, and `dF = [de12 de13 h dd] Dm^-1`.
    #[inline]
    fn gradient_variation(
        &self,
        k: &Kinematics,
        de12: &Vector3<f64>,
        de13: &Vector3<f64>,
    ) -> (Matrix3<f64>, Vector3<f64>, f64) {
        let dn = de12.cross(&k.e13) + k.e12.cross(de13);
        let d_dn = k.d.dot(&dn);
        let dd = (dn - k.d * d_dn) * k.inv_n;
        let dds = Matrix3::from_columns(&[*de12, *de13, dd * k.h]);
        (dds * self.dm_inv, dd, d_dn)
    }

    /// Second half: the differential of `(dE/de12, dE/de13)` given `dP`, `dd` and `d . dn`
    /// (`dmt = V0 Dm^-T`).
    #[inline]
    fn finish_differential(
        k: &Kinematics,
        s: &Stress,
        dmt: &Matrix3<f64>,
        (de12, de13): (&Vector3<f64>, &Vector3<f64>),
        dp: &Matrix3<f64>,
        dd: &Vector3<f64>,
        d_dn: f64,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let dg = dp * dmt;
        let g3 = s.g.column(2);
        let dg3 = dg.column(2);
        let dq = -s.q * (k.inv_n * d_dn)
            + (dg3 - k.d * (k.d.dot(&dg3) + dd.dot(&g3)) - dd * k.d.dot(&g3)) * (k.h * k.inv_n);
        (
            dg.column(0) + de13.cross(&s.q) + k.e13.cross(&dq),
            dg.column(1) + dq.cross(&k.e12) + s.q.cross(de12),
        )
    }

    /// Differential of `(dE/de12, dE/de13)` along edge variations `(de12, de13)`.
    #[inline]
    fn edge_gradient_differential<M: Material>(
        &self,
        mat: &M,
        k: &Kinematics,
        s: &Stress,
        de12: &Vector3<f64>,
        de13: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let (df, dd, d_dn) = self.gradient_variation(k, de12, de13);
        let dp = mat.first_piola_differential(&k.f, &df);
        let dmt = self.dm_inv.transpose() * self.rest_volume();
        Self::finish_differential(k, s, &dmt, (de12, de13), &dp, &dd, d_dn)
    }

    /// Deformation gradient `F = [e12 e13 d h] Dm^-1` (Wang et al. 2015, Eq. 4), dimensionless.
    pub fn deformation_gradient(&self, x: &[Vector3<f64>; 3], h: f64) -> Matrix3<f64> {
        self.kinematics(x, h).f
    }

    /// Elastic energy `E^e = V^e psi(F)` (J) with `V^e = A H` the rest volume (Wang et al. 2015, Eq. 5, 8).
    pub fn energy<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3], h: f64) -> f64 {
        self.rest_volume() * mat.energy_density(&self.kinematics(x, h).f)
    }

    /// Elastic forces `f_i = -dE^e/dx_i` (N) on the three vertices (Wang et al. 2015, Eq. 8), including
    /// the contribution of the rotating unit normal `d`.
    pub fn forces<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3], h: f64) -> [Vector3<f64>; 3] {
        let k = self.kinematics(x, h);
        let s = self.stress(&k, &mat.first_piola(&k.f));
        let (g12, g13) = Self::edge_gradient(&k, &s);
        [g12 + g13, -g12, -g13]
    }

    /// The elastic forces (Eq. 8) and energy (Eq. 5, 8) in one evaluation of the kinematics
    /// and the strain: the forces bit for bit those of [`ThreePrism::forces`], the energy that
    /// of [`ThreePrism::energy`] (through [`Material::energy_and_piola`]). For a line search
    /// whose trials need both.
    pub fn forces_and_energy<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], f64) {
        let k = self.kinematics(x, h);
        let (psi, p) = mat.energy_and_piola(&k.f);
        let s = self.stress(&k, &p);
        let (g12, g13) = Self::edge_gradient(&k, &s);
        ([g12 + g13, -g12, -g13], self.rest_volume() * psi)
    }

    /// Force differential `df = -K dx` (N) along vertex displacements `dx` (m), Wang et al. 2015, Eq. 11,
    /// including the variation of the unit normal `d` (both through `dF` and through the
    /// geometric term `P : d^2F`). The thickness `h` is held fixed.
    pub fn force_differential<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
        dx: &[Vector3<f64>; 3],
    ) -> [Vector3<f64>; 3] {
        let k = self.kinematics(x, h);
        let s = self.stress(&k, &mat.first_piola(&k.f));
        let (a, b) =
            self.edge_gradient_differential(mat, &k, &s, &(dx[1] - dx[0]), &(dx[2] - dx[0]));
        [a + b, -a, -b]
    }

    /// Evaluates the kinematics and the stress once at `(x, h)` so that the forces and many
    /// force differentials (one per CG iteration of a matrix-free Newton solve, Wang et al. 2015, Eq. 11
    /// and 23) can reuse them. Assumes a valid state, like the other hot-path methods.
    pub fn linearize<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ThreePrismLinearization {
        let kin = self.kinematics(x, h);
        let stress = self.stress(&kin, &mat.first_piola(&kin.f));
        ThreePrismLinearization {
            prism: *self,
            kin,
            stress,
        }
    }

    /// Stiffness `K = -df/dx = d^2E^e/dx^2` (N/m), 9x9, vertex-major `[x1 y1 z1 x2 .. z3]`.
    /// Symmetric (it is a Hessian); not necessarily positive definite (compression, and the
    /// normal-variation term).
    pub fn stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_stiffness(mat, x, h).1
    }

    /// Forces and stiffness together, sharing the kinematics and the stress (the hot path of an
    /// assembled Newton solve). Allocation-free. The stiffness is built from the Hessian with
    /// respect to the two edge vectors (6 material differentials) and expanded to the vertices
    /// using translation invariance.
    pub fn forces_and_stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let (f, ke) = self.forces_and_edge_hessian(mat, x, h);
        (f, edge_to_vertex_hessian::<6, 9>(&ke))
    }

    /// Forces and the *projected* (positive semi-definite) stiffness, for projected Newton.
    ///
    /// The exact stiffness `K = S^T Ke S` ([`ThreePrism::forces_and_stiffness`]) is built from
    /// the 6x6 Hessian `Ke` with respect to the two edge vectors, `S` the (onto) map from vertex
    /// to edge displacements; `K` is PSD exactly when `Ke` is. `Ke` is indefinite when the
    /// element is compressed (St. Venant-Kirchhoff is not convex in compression; the geometric
    /// term `S : dF^T dF` with a negative principal stress, and the normal-variation terms). This
    /// returns `S^T Ke+ S` with `Ke+ = Q max(Lambda, 0) Q^T` the nearest PSD matrix to `Ke` in
    /// the Frobenius norm (eigenvalues clamped at zero). When `Ke` is positive definite (a
    /// Cholesky factorisation of the 6x6 succeeds, the usual case for a stretched element) the
    /// exact stiffness is returned unchanged and no eigen-decomposition is done. The forces are
    /// the exact ones; only the Newton matrix changes, so Newton converges to the same backward
    /// Euler solution (Wang et al. 2015, Eq. 18), linearly rather than quadratically where elements are
    /// compressed.
    pub fn forces_and_projected_stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let (f, ke) = self.forces_and_edge_hessian(mat, x, h);
        (f, edge_to_vertex_hessian::<6, 9>(&project_psd(ke)))
    }

    /// Projected stiffness alone (see [`ThreePrism::forces_and_projected_stiffness`]).
    pub fn projected_stiffness<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_projected_stiffness(mat, x, h).1
    }

    /// Forces and the 6x6 Hessian with respect to the edge vectors `(e12, e13)`.
    #[inline]
    fn forces_and_edge_hessian<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 6, 6>) {
        let k = self.kinematics(x, h);
        let s = self.stress(&k, &mat.first_piola(&k.f));
        let (g12, g13) = Self::edge_gradient(&k, &s);
        let dmt = self.dm_inv.transpose() * self.rest_volume();
        // Unit edge variations: column c moves component c % 3 of e12 (c < 3) or e13 (c >= 3).
        let units: [(Vector3<f64>, Vector3<f64>); 6] = std::array::from_fn(|c| {
            let mut u = Vector3::zeros();
            u[c % 3] = 1.0;
            if c < 3 {
                (u, Vector3::zeros())
            } else {
                (Vector3::zeros(), u)
            }
        });
        let var: [(Matrix3<f64>, Vector3<f64>, f64); 6] =
            std::array::from_fn(|c| self.gradient_variation(&k, &units[c].0, &units[c].1));
        let dps = mat.first_piola_differentials(&k.f, &var.map(|v| v.0));
        let mut ke = SMatrix::<f64, 6, 6>::zeros();
        for c in 0..6 {
            let (a, b) = Self::finish_differential(
                &k,
                &s,
                &dmt,
                (&units[c].0, &units[c].1),
                &dps[c],
                &var[c].1,
                var[c].2,
            );
            ke.fixed_view_mut::<3, 1>(0, c).copy_from(&a);
            ke.fixed_view_mut::<3, 1>(3, c).copy_from(&b);
        }
        ([g12 + g13, -g12, -g13], ke)
    }

    /// Generalised force on the thickness, `-dE^e/dh` (N): positive when the material pushes the
    /// thickness to grow. Equals `-V^e d . (P Dm^-T)_3`, i.e. `-V^e P : (d r3^T)` with `r3` the
    /// third row of `Dm^-1`.
    pub fn thickness_force<M: Material>(&self, mat: &M, x: &[Vector3<f64>; 3], h: f64) -> f64 {
        let k = self.kinematics(x, h);
        let g = mat.first_piola(&k.f) * self.dm_inv.transpose() * self.rest_volume();
        -k.d.dot(&g.column(2))
    }

    /// Lumped vertex masses of Wang et al. 2015, Eq. 19 with `w_i = 1/3`: `rho A H / 3` each (kg), for a
    /// density `density` in kg/m^3. They sum to `rho V^e`.
    pub fn lumped_masses(&self, density: f64) -> [f64; 3] {
        [density * self.rest_volume() / 3.0; 3]
    }

    /// Masses for the shell-volume projection of Wang et al. 2015, Sec. 7 (Eq. 27): weight 1/6 for each of
    /// the three real vertices and 1/2 for the virtual vertex at the centre of the upper triangle,
    /// i.e. `([rho V/6; 3], rho V/2)` in kg. They sum to `rho V^e`.
    pub fn projection_masses(&self, density: f64) -> ([f64; 3], f64) {
        let m = density * self.rest_volume();
        ([m / 6.0; 3], m / 2.0)
    }
}

/// The nearest positive semi-definite matrix to the symmetric part of `a` (Frobenius norm):
/// eigenvalues clamped at zero. Returns `a` unchanged (up to symmetrisation) when it is positive
/// semi-definite up to `1e-10` of its mean diagonal, detected by a Cholesky factorisation, which
/// is much cheaper than the eigen-solve.
pub(crate) fn project_psd<const N: usize>(a: SMatrix<f64, N, N>) -> SMatrix<f64, N, N>
where
    nalgebra::Const<N>: nalgebra::DimMin<nalgebra::Const<N>, Output = nalgebra::Const<N>>
        + nalgebra::DimSub<nalgebra::U1>,
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<
            <nalgebra::Const<N> as nalgebra::DimSub<nalgebra::U1>>::Output,
        >,
{
    let sym = (a + a.transpose()) * 0.5;
    // Positive definite up to a negligible shift: keep it as it is. The shift (1e-10 of the
    // mean diagonal) lets near-rest elements, whose rigid-rotation modes are zero up to
    // rounding, skip the eigen-solve; their eigenvalues are >= -1e-10 trace / N.
    let mut shifted = sym;
    let eps = 1e-10 * sym.trace().abs() / N as f64;
    for i in 0..N {
        shifted[(i, i)] += eps;
    }
    if shifted.cholesky().is_some() {
        return sym;
    }
    let mut eig = sym.symmetric_eigen();
    eig.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
    eig.recompose()
}

/// A three-prism linearised at one state by [`ThreePrism::linearize`]: the kinematics and the
/// stress are evaluated once, and [`ThreePrismLinearization::force_differential`] applies
/// `df = -K dx` without recomputing them (cheaper than [`ThreePrism::force_differential`] when
/// the same state is used for many products, as in matrix-free CG). The material passed to
/// `force_differential` must be the one used to linearise.
#[derive(Clone, Copy, Debug)]
pub struct ThreePrismLinearization {
    prism: ThreePrism,
    kin: Kinematics,
    stress: Stress,
}

impl ThreePrismLinearization {
    /// Deformation gradient at the linearisation state.
    pub fn deformation_gradient(&self) -> &Matrix3<f64> {
        &self.kin.f
    }

    /// Elastic forces `-dE/dx_i` (N) at the linearisation state (same as
    /// [`ThreePrism::forces`]).
    pub fn forces(&self) -> [Vector3<f64>; 3] {
        let (g12, g13) = ThreePrism::edge_gradient(&self.kin, &self.stress);
        [g12 + g13, -g12, -g13]
    }

    /// Thickness force `-dE/dh` (N) at the linearisation state (same as
    /// [`ThreePrism::thickness_force`]).
    pub fn thickness_force(&self) -> f64 {
        -self.kin.d.dot(&self.stress.g.column(2))
    }

    /// Force differential `df = -K dx` (N), same as [`ThreePrism::force_differential`] at the
    /// linearisation state.
    pub fn force_differential<M: Material>(
        &self,
        mat: &M,
        dx: &[Vector3<f64>; 3],
    ) -> [Vector3<f64>; 3] {
        let (a, b) = self.prism.edge_gradient_differential(
            mat,
            &self.kin,
            &self.stress,
            &(dx[1] - dx[0]),
            &(dx[2] - dx[0]),
        );
        [a + b, -a, -b]
    }
}
