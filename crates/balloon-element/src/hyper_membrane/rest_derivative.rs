//! Derivative of the membrane triangle's forces with respect to its rest shape, for inverse
//! design.
//!
//! The forces of [`HyperMembrane`] depend on the rest corners `X` through the 2x2 rest matrix
//! `Dm = T^T [E12 E13]` in the rest frame `T = [T1 T2]` (`T1 = E12 / |E12|`, `T2 = N x T1`,
//! `N` the rest unit normal) and the rest volume `V0 = A0 H`. Along a variation `dX` at fixed
//! current corners (`docs/design.md`, D6-D9):
//!
//! * the frame turns with the triangle: `T^T dT = W = [[0, -w], [w, 0]]`,
//!   `w = T2 . dE12 / |E12|`, so `dDm = T^T [dE12 dE13] - W Dm` (a rigid rotation of the rest
//!   triangle leaves `Dm` unchanged);
//! * `B = dDm Dm^-1`, `dFm = -Fm B`, `dC = -(B^T C + C B)`, `dV0 / V0 = tr B`;
//! * the edge gradients `G = V0 Fm S Dm^-T` vary as
//!   `dG = tr(B) G + V0 (dFm S + Fm dS(C; dC)) Dm^-T - G (Dm^-1 dDm)^T`
//!   (from `d(Dm^-T) = -Dm^-T dDm^T Dm^-T`),
//!   and the forces `[g12 + g13, -g12, -g13]` with them.

use balloon_material::membrane::MembraneMaterial;
use nalgebra::{Matrix2, SMatrix, Vector3};

use super::HyperMembrane;
use crate::expand::edge_to_vertex_hessian;

impl HyperMembrane {
    /// The elastic forces (N, bit for bit those of [`HyperMembrane::forces`]) and their exact
    /// derivative with respect to the element's **rest** corners, `df/dX` (N/m), 9x9
    /// vertex-major (`[x1 y1 z1 x2 .. z3]` for both the forces and the rest corners), at fixed
    /// current corners `x`. The rest thickness `H` is the element's own and held fixed; the
    /// current thickness follows incompressibility and needs no argument. Allocation-free.
    ///
    /// `rest` must be the rest corners this element was made from ([`HyperMembrane::try_new`]):
    /// the element keeps only the intrinsic `Dm^-1`, and the derivative depends on the rest
    /// triangle's orientation in space.
    ///
    /// Not symmetric (the derivative of the forces, not a Hessian). Invariances (tested): the
    /// forces do not change when the rest triangle is translated or rotated (about its normal
    /// or any other axis), for every membrane model: the frame `(T1, T2)` turns with the
    /// triangle, so `Dm` does not change. The matrix has the six rigid motions of the rest
    /// triangle in its null space and rank at most 3.
    pub fn forces_and_rest_jacobian<M: MembraneMaterial>(
        &self,
        mat: &M,
        rest: &[Vector3<f64>; 3],
        x: &[Vector3<f64>; 3],
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        let fm = self.in_plane_deformation_gradient(x);
        let c = fm.transpose() * fm;
        let s = mat.stress(&c);
        let g = self.edge_gradient(&fm, &s);
        let e12 = rest[1] - rest[0];
        let e13 = rest[2] - rest[0];
        let len12 = e12.norm();
        let t1 = e12 / len12;
        let n = e12.cross(&e13);
        let t2 = (n / n.norm()).cross(&t1);
        let tt = SMatrix::<f64, 2, 3>::from_rows(&[t1.transpose(), t2.transpose()]);
        let dm = Matrix2::new(t1.dot(&e12), t1.dot(&e13), t2.dot(&e12), t2.dot(&e13));
        let dmit = self.dm_inv.transpose() * self.rest_volume();
        let mut ge = SMatrix::<f64, 6, 6>::zeros();
        for col in 0..6 {
            let mut des = SMatrix::<f64, 3, 2>::zeros();
            des[(col % 3, col / 3)] = 1.0;
            let w = t2.dot(&des.column(0)) / len12;
            let turn = Matrix2::new(0.0, -w, w, 0.0);
            let ddm = tt * des - turn * dm;
            let b = ddm * self.dm_inv;
            let left = self.dm_inv * ddm;
            let dfm = -(fm * b);
            let dc = -(b.transpose() * c + c * b);
            let ds = mat.stress_differential(&c, &dc);
            let dg = g * b.trace() + (dfm * s + fm * ds) * dmit - g * left.transpose();
            ge.fixed_view_mut::<3, 1>(0, col).copy_from(&dg.column(0));
            ge.fixed_view_mut::<3, 1>(3, col).copy_from(&dg.column(1));
        }
        let (g12, g13) = (g.column(0).into_owned(), g.column(1).into_owned());
        (
            [g12 + g13, -g12, -g13],
            -edge_to_vertex_hessian::<6, 9>(&ge),
        )
    }

    /// The rest Jacobian `df/dX` alone (see [`HyperMembrane::forces_and_rest_jacobian`]).
    pub fn rest_jacobian<M: MembraneMaterial>(
        &self,
        mat: &M,
        rest: &[Vector3<f64>; 3],
        x: &[Vector3<f64>; 3],
    ) -> SMatrix<f64, 9, 9> {
        self.forces_and_rest_jacobian(mat, rest, x).1
    }
}

#[cfg(test)]
mod tests {
    use balloon_material::membrane::{
        MembraneGent, MembraneModel, MembraneMooneyRivlin, MembraneNeoHookean, MembranePreset,
        MembraneYeoh,
    };
    use balloon_test_support::{Rng, check_jacobian};
    use nalgebra::{Rotation3, SVector, Vector3};

    use crate::HyperMembrane;

    fn flat(x: &[Vector3<f64>; 3]) -> Vec<f64> {
        x.iter().flat_map(|v| v.iter().copied()).collect()
    }

    fn arr(x: &[f64]) -> [Vector3<f64>; 3] {
        std::array::from_fn(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
    }

    fn rvec(rng: &mut Rng) -> Vector3<f64> {
        Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
    }

    fn models() -> Vec<MembraneModel> {
        vec![
            MembraneNeoHookean::try_new(4.0e5).unwrap().into(),
            MembraneMooneyRivlin::try_new(1.6e5, 0.4e5).unwrap().into(),
            MembraneGent::try_new(4.0e5, 30.0).unwrap().into(),
            MembranePreset::NaturalRubber.model(),
            MembraneYeoh::try_new(1.1e5, 2.0e4, 5.0e2).unwrap().into(),
        ]
    }

    #[test]
    fn membrane_rest_jacobian_matches_finite_differences() {
        let mut rng = Rng::new(17);
        for m in models() {
            for l in [1.0, 0.02] {
                let p0 = rvec(&mut rng) * l;
                let rest = [
                    p0,
                    p0 + Vector3::new(1.0, 0.2 * rng.next_f64(), 0.3 * rng.next_f64()) * l,
                    p0 + Vector3::new(0.3 * rng.next_f64(), 1.0, 0.2 * rng.next_f64()) * l,
                ];
                let rot = Rotation3::new(rvec(&mut rng) * 2.0);
                let scale = 1.4 + 0.3 * rng.next_f64();
                let x = rest.map(|p| rot * (p * scale + rvec(&mut rng) * (0.03 * l)));
                let el = HyperMembrane::try_new(rest, 1e-3).unwrap();
                assert!(el.is_admissible(&m, &x));
                let (f, j) = el.forces_and_rest_jacobian(&m, &rest, &x);
                assert_eq!(f, el.forces(&m, &x));
                let forces = |r: &[f64]| {
                    let q = HyperMembrane::try_new(arr(r), 1e-3).unwrap();
                    flat(&q.forces(&m, &x))
                };
                let jv = |_: &[f64], d: &[f64]| {
                    (j * SVector::<f64, 9>::from_column_slice(d))
                        .as_slice()
                        .to_vec()
                };
                check_jacobian(forces, jv, &flat(&rest), 1e-6 * l, 1e-6, 7);
                // Rigid motions of the rest triangle are in the null space.
                let c = (rest[0] + rest[1] + rest[2]) / 3.0;
                for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
                    let mut w = SVector::<f64, 9>::zeros();
                    let mut t = SVector::<f64, 9>::zeros();
                    for v in 0..3 {
                        w.fixed_rows_mut::<3>(3 * v)
                            .copy_from(&axis.cross(&(rest[v] - c)));
                        t.fixed_rows_mut::<3>(3 * v).copy_from(&axis);
                    }
                    assert!((j * w).norm() <= 1e-8 * j.norm() * w.norm());
                    assert!((j * t).norm() <= 1e-8 * j.norm() * t.norm());
                }
            }
        }
    }
}
