//! The rest-mesh shape term of the shape optimisation's continuation (`docs/design.md`, D16):
//! a conformal (angle-preserving) energy of the rest triangles against the target's, with a
//! free scale per triangle, so that the inflation's stretch is not penalised but a sheared rest
//! triangle is.
//!
//! For a triangle `(i, j, k)` with target edges `E* = [x*_j - x*_i, x*_k - x*_i]` (3x2) and
//! metric `G* = E*^T E* = L^T L` (Cholesky), the map from the target triangle to the rest
//! triangle in the target's orthonormal frame is `F = E M`, `E` the rest edges and
//! `M = L^-1`; `C = F^T F` (2x2) has the squared principal stretches as eigenvalues. The
//! residual
//!
//! ```text
//! r_t = ( (C11 - C22) / tr C,  2 C12 / tr C ),     |r_t|^2 = 1 - 4 det C / (tr C)^2
//! ```
//!
//! is zero exactly when the rest triangle is the target triangle up to a rotation and a
//! uniform scale, and is invariant under both. The term is
//! `gamma/2 l^2 sum_t (a_t / mean a) |r_t|^2`, `a_t` the target triangle areas and `l` the
//! target's mean edge length (so `gamma` is dimensionless: a fully sheared triangle costs as
//! much as a vertex distance of `l sqrt(gamma)`). Its Gauss-Newton matrix
//! `gamma l^2 sum_t (a_t / mean a) J_t^T J_t` (`J_t = dr_t/dX`) is what the outer loop's
//! damped normal equations add.

use nalgebra::{Matrix2, Vector3};

use crate::problem::{DesignProblem, corners};

/// The shape term's per-triangle data: the corners, `M = L^-1` (upper triangular: `m11`,
/// `m12`, `m22`) and the weight `l^2 a_t / mean a`.
pub(crate) struct ShapeTerm {
    triangles: Vec<[usize; 3]>,
    frames: Vec<Matrix2<f64>>,
    weights: Vec<f64>,
}

/// A triangle's residual and its gradient rows with respect to its three corners.
struct Local {
    r: [f64; 2],
    rows: [[Vector3<f64>; 3]; 2],
}

impl ShapeTerm {
    /// The term of `problem`'s target (degenerate target triangles are left out).
    pub(crate) fn new(problem: &DesignProblem) -> Self {
        let x = problem.target();
        let edge = problem.mean_edge_length();
        let mut triangles = Vec::new();
        let mut frames = Vec::new();
        let mut areas = Vec::new();
        for t in problem.triangles() {
            let [p, q, r] = corners(x, t);
            let (e1, e2) = (q - p, r - p);
            let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
            let l11 = a.sqrt();
            let l12 = b / l11;
            let l22 = (c - l12 * l12).max(0.0).sqrt();
            let area = e1.cross(&e2).norm() / 2.0;
            if !(l11 > 0.0 && l22 > 0.0 && area > 0.0) {
                continue;
            }
            triangles.push(*t);
            frames.push(Matrix2::new(1.0 / l11, -l12 / (l11 * l22), 0.0, 1.0 / l22));
            areas.push(area);
        }
        let mean = areas.iter().sum::<f64>() / areas.len().max(1) as f64;
        let weights = areas.iter().map(|a| edge * edge * a / mean).collect();
        Self {
            triangles,
            frames,
            weights,
        }
    }

    /// Triangle `n`'s residual and gradient rows at the rest shape `rest`; `None` for a
    /// collapsed rest triangle (left out).
    fn local(&self, rest: &[f64], n: usize) -> Option<Local> {
        let [p, q, r] = corners(rest, &self.triangles[n]);
        let (e1, e2) = (q - p, r - p);
        let m = &self.frames[n];
        let f1 = e1 * m[(0, 0)];
        let f2 = e1 * m[(0, 1)] + e2 * m[(1, 1)];
        let (c11, c22, c12) = (f1.dot(&f1), f2.dot(&f2), f1.dot(&f2));
        let tr = c11 + c22;
        if !(tr > 0.0 && tr.is_finite()) {
            return None;
        }
        let res = [(c11 - c22) / tr, 2.0 * c12 / tr];
        let s = 2.0 / tr;
        // d r / d(f1, f2), then through df1 = m11 de1, df2 = m12 de1 + m22 de2.
        let g = [
            [f1 * ((1.0 - res[0]) * s), f2 * (-(1.0 + res[0]) * s)],
            [(f2 - f1 * res[1]) * s, (f1 - f2 * res[1]) * s],
        ];
        let rows = g.map(|[g1, g2]| {
            let h1 = g1 * m[(0, 0)] + g2 * m[(0, 1)];
            let h2 = g2 * m[(1, 1)];
            [-(h1 + h2), h1, h2]
        });
        Some(Local { r: res, rows })
    }

    /// `S(X) / gamma = 1/2 sum_t w_t |r_t|^2` and its gradient, at the rest shape `rest`.
    pub(crate) fn value_gradient(&self, rest: &[f64]) -> (f64, Vec<f64>) {
        let mut value = 0.0;
        let mut g = vec![0.0; rest.len()];
        for n in 0..self.triangles.len() {
            let Some(l) = self.local(rest, n) else {
                continue;
            };
            let w = self.weights[n];
            value += 0.5 * w * (l.r[0] * l.r[0] + l.r[1] * l.r[1]);
            for (row, r) in l.rows.iter().zip(l.r) {
                for (&v, d) in self.triangles[n].iter().zip(row) {
                    for k in 0..3 {
                        g[3 * v + k] += w * r * d[k];
                    }
                }
            }
        }
        (value, g)
    }

    /// The Gauss-Newton product `sum_t w_t J_t^T J_t u` at the rest shape `rest`.
    pub(crate) fn gauss_newton_product(&self, rest: &[f64], u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; u.len()];
        for n in 0..self.triangles.len() {
            let Some(l) = self.local(rest, n) else {
                continue;
            };
            let w = self.weights[n];
            let t = &self.triangles[n];
            for row in &l.rows {
                crate::gauss_newton::add_rank_one_product(t, row, w, u, &mut out);
            }
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

    /// A rest shape that is the target up to a rotation, a translation and a uniform scale
    /// costs nothing; a sheared one does.
    #[test]
    fn similar_rest_shapes_cost_nothing() {
        let problem = problem();
        let term = ShapeTerm::new(&problem);
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let similar: Vec<f64> = problem
            .target()
            .chunks(3)
            .flat_map(|p| {
                let y = rot * Vector3::new(p[0], p[1], p[2]) * 1.37 + Vector3::new(0.1, 0.2, 0.3);
                [y.x, y.y, y.z]
            })
            .collect();
        let (value, g) = term.value_gradient(&similar);
        assert!(value < 1e-28, "{value:e}");
        assert!(g.iter().all(|v| v.abs() < 1e-12), "{g:?}");
        let sheared: Vec<f64> = problem
            .target()
            .chunks(3)
            .flat_map(|p| [p[0] + 0.5 * p[1], p[1], p[2]])
            .collect();
        assert!(term.value_gradient(&sheared).0 > 1e-6);
    }

    /// The gradient against central differences of the value, and the Gauss-Newton product
    /// against `J^T J` built from central differences of the gradient at a zero-residual point
    /// (where the two agree), along random directions at a sheared rest shape.
    #[test]
    fn gradient_matches_central_differences() {
        let problem = problem();
        let term = ShapeTerm::new(&problem);
        let rest: Vec<f64> = problem
            .target()
            .chunks(3)
            .enumerate()
            .flat_map(|(v, p)| {
                let s = (v as f64 * 1.7).sin() * 4e-3;
                [p[0] + 0.3 * p[1] + s, p[1] - s, p[2] * 1.1 + 0.5 * s]
            })
            .collect();
        check_gradient(|x| term.value_gradient(x), &rest, 1e-6, 1e-7, 1e-12);
        // At a similar shape (zero residual) the Hessian is J^T J: compare with the
        // gradient's central differences.
        let at = problem.target().to_vec();
        check_gauss_newton_product(
            |x| term.value_gradient(x),
            |x, d| term.gauss_newton_product(x, d),
            &at,
            1e-6,
        );
    }
}
