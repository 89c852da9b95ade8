//! Derivatives of the three-prism forces with respect to its rest shape and its current
//! thickness, for inverse design (find the rest shape whose equilibrium is a given shape).
//!
//! The forces `f(x, h; X)` of [`ThreePrism`] (Wang et al. 2015, Eq. 8) depend on the rest
//! corners `X` through `Dm = [E12 E13 D H]` (Eq. 4, `D = N / |N|`, `N = E12 x E13`) and the
//! rest volume `V0 = A0 H` (`A0 = |N| / 2`). Along a variation `dX` at fixed `x` and `h`
//! (`docs/design.md`, D1-D5):
//!
//! * `dDm = [dE12 dE13 H dD]`, `dD = (I - D D^T) dN / |N|`, `dN = dE12 x E13 + E12 x dE13`;
//! * `B = dDm Dm^-1`, `dF = -F B`, `dV0 / V0 = D . dN / |N|`;
//! * `G = V0 P Dm^-T` (its columns are the edge gradients at fixed `d`), with
//!   `d(Dm^-T) = -Dm^-T dDm^T Dm^-T`:
//!   `dG = (dV0 / V0) G + V0 dP(F; dF) Dm^-T - G (Dm^-1 dDm)^T`;
//! * the normal lever `q = h / |n| (I - d d^T) G3` of the current shape varies only through
//!   `G3`: `dq = h / |n| (I - d d^T) dG3`;
//! * the edge gradients `g12 = G1 + e13 x q`, `g13 = G2 + q x e12` vary as
//!   `dg12 = dG1 + e13 x dq`, `dg13 = dG2 + dq x e12`, and the forces `[g12 + g13, -g12, -g13]`
//!   with them.
//!
//! The six edge columns are expanded to the nine vertex columns by translation invariance.

use balloon_material::Material;
use nalgebra::{Matrix3, SMatrix, Vector3};

use super::{Kinematics, Stress, ThreePrism};
use crate::expand::edge_to_vertex_hessian;

/// Unit edge variations: column `c` moves component `c % 3` of `E12` (`c < 3`) or of `E13`.
fn unit_edge_variations() -> [(Vector3<f64>, Vector3<f64>); 6] {
    std::array::from_fn(|c| {
        let mut u = Vector3::zeros();
        u[c % 3] = 1.0;
        if c < 3 {
            (u, Vector3::zeros())
        } else {
            (Vector3::zeros(), u)
        }
    })
}

impl ThreePrism {
    /// The elastic forces (N, bit for bit those of [`ThreePrism::forces`]) and their exact
    /// derivative with respect to the element's **rest** corners, `df/dX` (N/m), 9x9
    /// vertex-major (`[x1 y1 z1 x2 .. z3]` for both the forces and the rest corners), at fixed
    /// current corners `x` and current thickness `h`. The rest thickness `H` is the element's
    /// own and held fixed. Allocation-free.
    ///
    /// `rest` must be the rest corners this element was made from ([`ThreePrism::try_new`]),
    /// in the same frame (the derivative depends on the rest triangle's orientation in space;
    /// the element keeps only `Dm^-1`).
    ///
    /// This is the derivative of the forces, not of the energy gradient (`-df/dX`) and, unlike
    /// the stiffness, it is not symmetric. Invariances (tested): the forces do not change when
    /// the rest triangle is translated, so every row of the matrix sums to zero over the three
    /// rest corners; for an isotropic material (St. Venant-Kirchhoff, neo-Hookean) they do not
    /// change either when the rest triangle is rotated, about its normal or any other axis
    /// (`F -> F R^T` leaves `psi` unchanged), so the matrix has the six rigid motions of the
    /// rest triangle in its null space and rank at most 3: the forces depend on the rest
    /// triangle only through its three edge lengths. For an anisotropic material only the
    /// translations are in the null space.
    ///
    /// The formulas are in the module docs and `docs/design.md`.
    pub fn forces_and_rest_jacobian<M: Material>(
        &self,
        mat: &M,
        rest: &[Vector3<f64>; 3],
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let k = self.kinematics(x, h);
        let s = self.stress(&k, &mat.first_piola(&k.f));
        let (g12, g13) = Self::edge_gradient(&k, &s);
        let ge = self.rest_edge_jacobian(mat, rest, &k, &s);
        (
            [g12 + g13, -g12, -g13],
            -edge_to_vertex_hessian::<6, 9>(&ge),
        )
    }

    /// The rest Jacobian `df/dX` alone (see [`ThreePrism::forces_and_rest_jacobian`]).
    pub fn rest_jacobian<M: Material>(
        &self,
        mat: &M,
        rest: &[Vector3<f64>; 3],
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_rest_jacobian(mat, rest, x, h).1
    }

    /// The derivative of the elastic forces with respect to the current thickness `h` at fixed
    /// corners, `df/dh` (N/m, one vector per corner; the derivative of
    /// [`ThreePrism::forces`]). `h` enters `F` through its third column `d h` (Eq. 4), so
    /// `dF = d r3^T` (`r3` the third row of `Dm^-1`), and the normal lever `q` is proportional
    /// to `h`. For a design whose current thickness follows the rest shape (for example the
    /// per-element volume rule `h = A0 H / A`).
    pub fn thickness_jacobian<M: Material>(
        &self,
        mat: &M,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> [Vector3<f64>; 3] {
        let k = self.kinematics(x, h);
        let s = self.stress(&k, &mat.first_piola(&k.f));
        let r3 = self.dm_inv.row(2).into_owned();
        let df = k.d * r3;
        let dp = mat.first_piola_differential(&k.f, &df);
        let dg = dp * self.dm_inv.transpose() * self.rest_volume();
        let dg3 = dg.column(2);
        let dq = s.q / h + (dg3 - k.d * k.d.dot(&dg3)) * (k.h * k.inv_n);
        let a = dg.column(0) + k.e13.cross(&dq);
        let b = dg.column(1) + dq.cross(&k.e12);
        [a + b, -a, -b]
    }

    /// The 6x6 derivative of the edge gradients `(g12, g13)` with respect to the rest edges
    /// `(E12, E13)` (module docs).
    fn rest_edge_jacobian<M: Material>(
        &self,
        mat: &M,
        rest: &[Vector3<f64>; 3],
        k: &Kinematics,
        s: &Stress,
    ) -> SMatrix<f64, 6, 6> {
        let e12 = rest[1] - rest[0];
        let e13 = rest[2] - rest[0];
        let n = e12.cross(&e13);
        let inv_nn = 1.0 / n.norm();
        let d = n * inv_nn;
        let big_h = self.rest_thickness;
        let units = unit_edge_variations();
        // Per column: dDm and dV0 / V0.
        let var: [(Matrix3<f64>, f64); 6] = std::array::from_fn(|c| {
            let (de12, de13) = units[c];
            let dn = de12.cross(&e13) + e12.cross(&de13);
            let d_dn = d.dot(&dn);
            let dd = (dn - d * d_dn) * inv_nn;
            let ddm = Matrix3::from_columns(&[de12, de13, dd * big_h]);
            (ddm, d_dn * inv_nn)
        });
        let dfs: [Matrix3<f64>; 6] = std::array::from_fn(|c| -(k.f * var[c].0 * self.dm_inv));
        let dps = mat.first_piola_differentials(&k.f, &dfs);
        let dmt = self.dm_inv.transpose() * self.rest_volume();
        let mut ge = SMatrix::<f64, 6, 6>::zeros();
        for c in 0..6 {
            let (ddm, dv) = var[c];
            let left = self.dm_inv * ddm;
            let dg = s.g * dv + dps[c] * dmt - s.g * left.transpose();
            let dg3 = dg.column(2);
            let dq = (dg3 - k.d * k.d.dot(&dg3)) * (k.h * k.inv_n);
            let a = dg.column(0) + k.e13.cross(&dq);
            let bb = dg.column(1) + dq.cross(&k.e12);
            ge.fixed_view_mut::<3, 1>(0, c).copy_from(&a);
            ge.fixed_view_mut::<3, 1>(3, c).copy_from(&bb);
        }
        ge
    }
}

#[cfg(test)]
mod tests {
    use balloon_material::{Lame, Material, NeoHookean, StVenantKirchhoff};
    use balloon_test_support::{Rng, check_jacobian};
    use nalgebra::{Matrix3, Rotation3, Vector3};

    use crate::ThreePrism;
    use crate::tests::FibreMaterial;

    fn flat(x: &[Vector3<f64>; 3]) -> Vec<f64> {
        x.iter().flat_map(|v| v.iter().copied()).collect()
    }

    fn arr(x: &[f64]) -> [Vector3<f64>; 3] {
        std::array::from_fn(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
    }

    fn rvec(rng: &mut Rng) -> Vector3<f64> {
        Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
    }

    fn lame() -> Lame {
        Lame::try_from_young_poisson(1.0e6, 0.4).unwrap()
    }

    /// Rest triangle of size `l`, a deformed state (rotated, stretched by `s`, perturbed) and
    /// a current thickness.
    fn case(rng: &mut Rng, l: f64, s: f64) -> ([Vector3<f64>; 3], [Vector3<f64>; 3]) {
        let p0 = rvec(rng) * l;
        let rest = [
            p0,
            p0 + Vector3::new(1.0, 0.2 * rng.next_f64(), 0.3 * rng.next_f64()) * l,
            p0 + Vector3::new(0.3 * rng.next_f64(), 1.0, 0.2 * rng.next_f64()) * l,
        ];
        let r = Rotation3::new(rvec(rng) * 3.0).into_inner();
        let g = Matrix3::from_iterator((0..9).map(|_| rng.next_f64()));
        let a = r * (Matrix3::identity() + g * 0.15) * s;
        let x = rest.map(|p| a * p + rvec(rng) * (0.05 * l));
        (rest, x)
    }

    /// `df/dX` against central differences of the forces of elements rebuilt from perturbed
    /// rest corners, for several sizes and stretches.
    fn rest_jacobian_suite<M: Material>(mat: &M, seed: u64) {
        let mut rng = Rng::new(seed);
        for (l, big_h) in [(1.0, 0.1), (0.01, 1.0e-3)] {
            for s in [0.8, 1.0, 1.4] {
                let (rest, x) = case(&mut rng, l, s);
                let h = big_h * (0.7 + 0.3 * rng.next_f64());
                let p = ThreePrism::try_new(rest, big_h).unwrap();
                let forces = |r: &[f64]| {
                    let q = ThreePrism::try_new(arr(r), big_h).unwrap();
                    flat(&q.forces(mat, &x, h))
                };
                let (f, j) = p.forces_and_rest_jacobian(mat, &rest, &x, h);
                assert_eq!(f, p.forces(mat, &x, h));
                let jv = |_: &[f64], d: &[f64]| {
                    (j * nalgebra::SVector::<f64, 9>::from_column_slice(d))
                        .as_slice()
                        .to_vec()
                };
                check_jacobian(forces, jv, &flat(&rest), 1e-6 * l, 1e-6, seed);
                // Translations of the rest triangle are in the null space.
                for c in 0..3 {
                    let mut t = nalgebra::SVector::<f64, 9>::zeros();
                    for v in 0..3 {
                        t[3 * v + c] = 1.0;
                    }
                    assert!((j * t).norm() <= 1e-9 * j.norm());
                }
                // Thickness derivative against central differences.
                let dh = 1e-6 * h;
                let fp = p.forces(mat, &x, h + dh);
                let fm = p.forces(mat, &x, h - dh);
                let tj = p.thickness_jacobian(mat, &x, h);
                for v in 0..3 {
                    let fd = (fp[v] - fm[v]) / (2.0 * dh);
                    assert!(
                        (fd - tj[v]).norm() <= 1e-6 * tj.iter().map(|t| t.norm()).sum::<f64>(),
                        "{fd} vs {}",
                        tj[v]
                    );
                }
            }
        }
    }

    #[test]
    fn rest_jacobian_matches_finite_differences_stvk() {
        rest_jacobian_suite(&StVenantKirchhoff::new(lame()), 3);
    }

    #[test]
    fn rest_jacobian_matches_finite_differences_neo_hookean() {
        rest_jacobian_suite(&NeoHookean::new(lame()), 4);
    }

    #[test]
    fn rest_jacobian_matches_finite_differences_anisotropic() {
        rest_jacobian_suite(&FibreMaterial::new(), 5);
    }

    #[test]
    fn isotropic_rest_jacobian_ignores_rest_rotations() {
        let mut rng = Rng::new(9);
        let mat = NeoHookean::new(lame());
        let (rest, x) = case(&mut rng, 0.05, 1.3);
        let p = ThreePrism::try_new(rest, 1e-3).unwrap();
        let j = p.rest_jacobian(&mat, &rest, &x, 8e-4);
        let c = (rest[0] + rest[1] + rest[2]) / 3.0;
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            let mut w = nalgebra::SVector::<f64, 9>::zeros();
            for v in 0..3 {
                w.fixed_rows_mut::<3>(3 * v)
                    .copy_from(&axis.cross(&(rest[v] - c)));
            }
            assert!(
                (j * w).norm() <= 1e-8 * j.norm() * w.norm(),
                "{}",
                (j * w).norm()
            );
        }
    }
}
