//! The rest-mesh bending term of the shape optimisation's continuation (`docs/design.md`,
//! D17): a discrete hinge energy on the rest mesh's dihedral angles against the target's
//! (Grinspun et al., "Discrete Shells", SCA 2003, Eq. 3 with the target as the reference), so
//! that the bendings of the rest mesh (normal motions that keep its edge lengths, which the
//! equilibrium hardly sees and the conformal shape term of D16 does not resist) cost something.
//!
//! For an interior edge `e = (x0, x1)` with the triangles `A = (x0, x1, x2)` and
//! `B = (x1, x0, x3)` (outward normals `nA = (x1 - x0) × (x2 - x0)`,
//! `nB = (x0 - x1) × (x3 - x1)`), the dihedral angle is
//! `theta_e = atan2((nA × nB)·e/|e|, nA·nB)` (0 on a flat hinge), and the term is
//!
//! ```text
//! B(X) = gamma/2 l^2 sum_e (w_e / mean w) (theta_e(X) - theta_e(x*))^2,   w_e = 3 |e*|^2 / (a*_A + a*_B)
//! ```
//!
//! with the target's edge lengths and triangle areas in `w_e` (Grinspun et al.'s `|e|/h_e`)
//! and `l` the target's mean edge length, so `gamma` is dimensionless as in D16. Dihedral
//! angles do not change under rotations, translations and uniform scalings, so the term is zero
//! on a rest shape similar to the target and its gradient is orthogonal to the rigid motions;
//! the inflation's (near-uniform) stretch is nearly free. Its Gauss-Newton matrix is
//! `gamma l^2 sum_e (w_e / mean w) g_e g_e^T` with `g_e = d theta_e / dX` (Bridson et al. 2003's
//! bending modes: `g2 = |e| nA / |nA|^2`, `g3 = |e| nB / |nB|^2`, and `g0`, `g1` from the
//! translation and rotation invariance).

use nalgebra::Vector3;

use crate::problem::{DesignProblem, point};

/// The bending term's hinges: the four corners `[x0, x1, x2, x3]` of each interior edge, the
/// target's dihedral angle and the weight `l^2 w_e / mean w`.
pub(crate) struct BendingTerm {
    hinges: Vec<[usize; 4]>,
    rest_angles: Vec<f64>,
    weights: Vec<f64>,
}

/// The dihedral angle of the hinge `h` at `x` and its gradient with respect to the four
/// corners; `None` for a degenerate hinge.
fn angle_and_gradient(x: &[f64], h: &[usize; 4]) -> Option<(f64, [Vector3<f64>; 4])> {
    let [p0, p1, p2, p3] = h.map(|v| point(x, v));
    let e = p1 - p0;
    let na = e.cross(&(p2 - p0));
    let nb = (p0 - p1).cross(&(p3 - p1));
    let (la, lb, le) = (na.norm_squared(), nb.norm_squared(), e.norm());
    if !(la > 0.0 && lb > 0.0 && le > 0.0) {
        return None;
    }
    let theta = (na.cross(&nb).dot(&e) / le).atan2(na.dot(&nb));
    let g2 = na * (-le / la);
    let g3 = nb * (-le / lb);
    let sa = (p2 - p0).dot(&e) / (le * le);
    let sb = (p3 - p0).dot(&e) / (le * le);
    let g0 = -(g2 * (1.0 - sa) + g3 * (1.0 - sb));
    let g1 = -(g2 * sa + g3 * sb);
    Some((theta, [g0, g1, g2, g3]))
}

impl BendingTerm {
    /// The term of `problem`'s target (hinges with a degenerate target triangle, and edges
    /// not shared by exactly two triangles, are left out).
    pub(crate) fn new(problem: &DesignProblem) -> Self {
        let x = problem.target();
        let mut hinges = Vec::new();
        let mut rest_angles = Vec::new();
        let mut raw = Vec::new();
        for found in balloon_mesh::topology::hinges(problem.triangles()) {
            let h = found.corners;
            let Some((theta, _)) = angle_and_gradient(x, &h) else {
                continue;
            };
            let [p0, p1, p2, p3] = h.map(|v| point(x, v));
            let e = p1 - p0;
            let areas = (e.cross(&(p2 - p0)).norm() + (p0 - p1).cross(&(p3 - p1)).norm()) / 2.0;
            hinges.push(h);
            rest_angles.push(theta);
            raw.push(3.0 * e.norm_squared() / areas);
        }
        let edge = problem.mean_edge_length();
        let mean = raw.iter().sum::<f64>() / raw.len().max(1) as f64;
        let weights = raw.iter().map(|w| edge * edge * w / mean).collect();
        Self {
            hinges,
            rest_angles,
            weights,
        }
    }

    /// Number of hinges.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.hinges.len()
    }

    /// `B(X) / gamma = 1/2 sum_e w_e (theta_e - theta*_e)^2` and its gradient at the rest
    /// shape `rest`.
    pub(crate) fn value_gradient(&self, rest: &[f64]) -> (f64, Vec<f64>) {
        let mut value = 0.0;
        let mut g = vec![0.0; rest.len()];
        for ((h, theta0), w) in self.hinges.iter().zip(&self.rest_angles).zip(&self.weights) {
            let Some((theta, grad)) = angle_and_gradient(rest, h) else {
                continue;
            };
            let r = theta - theta0;
            value += 0.5 * w * r * r;
            for (&v, d) in h.iter().zip(&grad) {
                for k in 0..3 {
                    g[3 * v + k] += w * r * d[k];
                }
            }
        }
        (value, g)
    }

    /// Adds `scale` times the Gauss-Newton matrix `sum_e w_e g_e g_e^T` at the rest shape
    /// `rest` into the vertex blocks `a` of `J^T J` laid out by `pattern` (a hinge's four
    /// corners lie within two rings of each other).
    pub(crate) fn add_gauss_newton_blocks(
        &self,
        rest: &[f64],
        scale: f64,
        pattern: &crate::normal::NormalPattern,
        a: &mut [nalgebra::Matrix3<f64>],
    ) {
        for (h, w) in self.hinges.iter().zip(&self.weights) {
            let Some((_, grad)) = angle_and_gradient(rest, h) else {
                continue;
            };
            for (p, gp) in h.iter().zip(&grad) {
                for (q, gq) in h.iter().zip(&grad) {
                    a[pattern.a_slot(*p, *q)] += gp * gq.transpose() * (scale * w);
                }
            }
        }
    }

    /// The Gauss-Newton product `sum_e w_e g_e (g_e · u)` at the rest shape `rest`.
    pub(crate) fn gauss_newton_product(&self, rest: &[f64], u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; u.len()];
        for (h, w) in self.hinges.iter().zip(&self.weights) {
            let Some((_, grad)) = angle_and_gradient(rest, h) else {
                continue;
            };
            crate::gauss_newton::add_rank_one_product(h, &grad, *w, u, &mut out);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_fixtures::{
        check_gauss_newton_product, check_gradient, ellipsoid_problem as problem,
    };

    fn similar(problem: &DesignProblem, scale: f64) -> Vec<f64> {
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        problem
            .target()
            .chunks(3)
            .flat_map(|p| {
                let y = rot * Vector3::new(p[0], p[1], p[2]) * scale + Vector3::new(0.1, 0.2, 0.3);
                [y.x, y.y, y.z]
            })
            .collect()
    }

    /// Every edge of a closed mesh is a hinge; a rest shape similar to the target costs
    /// nothing (zero value and gradient); rigid motions and a uniform scaling are in the null
    /// space of the Gauss-Newton matrix at any rest shape; a bent rest shape costs something.
    #[test]
    fn similar_rest_shapes_and_rigid_motions_cost_nothing() {
        let problem = problem();
        let term = BendingTerm::new(&problem);
        assert_eq!(term.len(), 3 * problem.triangles().len() / 2);
        let (value, g) = term.value_gradient(&similar(&problem, 1.37));
        assert!(value < 1e-28, "{value:e}");
        assert!(g.iter().all(|v| v.abs() < 1e-12), "{g:?}");
        // A bent rest shape: a vertex pushed inwards along its radius.
        let mut bent = problem.target().to_vec();
        for k in 0..3 {
            bent[k] *= 0.9;
        }
        let (value, g) = term.value_gradient(&bent);
        assert!(value > 1e-8, "{value:e}");
        let gn = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        // Rigid motions and the scaling at the bent shape: the gradient is orthogonal to them
        // and the Gauss-Newton matrix maps them to zero.
        let x = &bent;
        let nv = x.len() / 3;
        let mut fields: Vec<Vec<f64>> = Vec::new();
        for k in 0..3 {
            fields.push(
                (0..3 * nv)
                    .map(|i| f64::from(u8::from(i % 3 == k)))
                    .collect(),
            );
            let axis = Vector3::ith(k, 1.0);
            fields.push(
                (0..nv)
                    .flat_map(|v| {
                        let d = axis.cross(&point(x, v));
                        [d.x, d.y, d.z]
                    })
                    .collect(),
            );
        }
        fields.push(x.clone());
        let generic: Vec<f64> = (0..3 * nv).map(|i| (i as f64 * 0.77).sin()).collect();
        let norm = |u: &[f64]| u.iter().map(|v| v * v).sum::<f64>().sqrt();
        // The Gauss-Newton matrix's size along a generic direction, per unit length.
        let generic_gain = norm(&term.gauss_newton_product(x, &generic)) / norm(&generic);
        assert!(generic_gain > 0.0);
        for u in &fields {
            let gu: f64 = g.iter().zip(u).map(|(a, b)| a * b).sum();
            assert!(gu.abs() < 1e-10 * gn * norm(u), "{gu:e}");
            let gain = norm(&term.gauss_newton_product(x, u)) / norm(u);
            assert!(gain < 1e-10 * generic_gain, "{gain:e} vs {generic_gain:e}");
        }
    }

    /// The gradient against central differences of the value along random directions at a
    /// bent rest shape, and the Gauss-Newton product against central differences of the
    /// gradient at a shape similar to the target (zero residual, where the two agree).
    #[test]
    fn gradient_matches_central_differences() {
        let problem = problem();
        let term = BendingTerm::new(&problem);
        let rest: Vec<f64> = problem
            .target()
            .chunks(3)
            .enumerate()
            .flat_map(|(v, p)| {
                let s = 1.0 + 0.05 * (v as f64 * 1.7).sin();
                [p[0] * s, p[1] * s + 0.1 * p[0], p[2] * s]
            })
            .collect();
        assert!(term.value_gradient(&rest).0 > 1e-8);
        check_gradient(|x| term.value_gradient(x), &rest, 1e-7, 1e-6, 0.0);
        let at = similar(&problem, 0.9);
        check_gauss_newton_product(
            |x| term.value_gradient(x),
            |x, d| term.gauss_newton_product(x, d),
            &at,
            1e-7,
        );
    }
}
