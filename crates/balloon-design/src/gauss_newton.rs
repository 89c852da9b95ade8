//! The pieces of the shape optimisation's Gauss-Newton step (`docs/design.md`, D15): the
//! weighted projection that removes the rigid motions of a displacement field (the distance is
//! minimised over the rigid alignment, so a predicted displacement counts only modulo them) and
//! the conjugate-gradient solve of the damped normal equations, matrix-free.

use nalgebra::{Matrix3, Vector3};

use crate::problem::point;

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The L-BFGS direction `d = -H g` by the two-loop recursion on the curvature pairs
/// `(s, y, 1 / s.y)` of `memory` (oldest first), the initial matrix scaled by `s.y / y.y` of
/// the newest pair (Nocedal and Wright 2006, Algorithm 7.4).
pub(crate) fn lbfgs_direction(
    memory: &std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)>,
    g: &[f64],
) -> Vec<f64> {
    let mut d: Vec<f64> = g.iter().map(|v| -v).collect();
    let mut alphas = Vec::with_capacity(memory.len());
    for (s, y, rho) in memory.iter().rev() {
        let a = rho * dot(s, &d);
        for (di, yi) in d.iter_mut().zip(y) {
            *di -= a * yi;
        }
        alphas.push(a);
    }
    if let Some((s, y, _)) = memory.back() {
        let gamma = dot(s, y) / dot(y, y);
        for di in d.iter_mut() {
            *di *= gamma;
        }
    }
    for ((s, y, rho), a) in memory.iter().zip(alphas.iter().rev()) {
        let b = rho * dot(y, &d);
        for (di, si) in d.iter_mut().zip(s) {
            *di += (a - b) * si;
        }
    }
    d
}

/// `out += w g (g . u)` over the corner vectors `g` of the vertices `vertices` (flat `u` and
/// `out`, one 3-vector per vertex): the Gauss-Newton product of one scalar residual whose
/// gradient has the corner vectors `g`, weighted by `w`.
pub(crate) fn add_rank_one_product(
    vertices: &[usize],
    g: &[Vector3<f64>],
    w: f64,
    u: &[f64],
    out: &mut [f64],
) {
    let gu: f64 = vertices
        .iter()
        .zip(g)
        .map(|(&v, d)| d.dot(&point(u, v)))
        .sum();
    for (&v, d) in vertices.iter().zip(g) {
        for k in 0..3 {
            out[3 * v + k] += w * gu * d[k];
        }
    }
}

/// Removes from the displacement field `u` (flat, one 3-vector per vertex) its weighted
/// least-squares fit by an infinitesimal rigid motion `a + w × (y_v - c)` of the points `y`
/// (`c` their weighted centroid): `u - a - w × (y - c)` is orthogonal to every rigid motion of
/// `y` in the inner product `sum_v w_v u_v · z_v`, and the map is that inner product's
/// orthogonal projection (self-adjoint in it, idempotent).
pub(crate) fn remove_rigid_motion(y: &[f64], weights: &[f64], u: &mut [f64]) {
    let total: f64 = weights.iter().sum();
    if total <= 0.0 {
        return;
    }
    let mut c = Vector3::zeros();
    let mut a = Vector3::zeros();
    for (v, w) in weights.iter().enumerate() {
        c += point(y, v) * *w;
        a += point(u, v) * *w;
    }
    c /= total;
    a /= total;
    // Rotation: (sum_v w_v (|q|^2 I - q q^T)) w = sum_v w_v q × (u_v - a), q = y_v - c.
    let mut inertia = Matrix3::zeros();
    let mut moment = Vector3::zeros();
    for (v, w) in weights.iter().enumerate() {
        let q = point(y, v) - c;
        inertia += (Matrix3::identity() * q.norm_squared() - q * q.transpose()) * *w;
        moment += q.cross(&(point(u, v) - a)) * *w;
    }
    let omega = inertia
        .try_inverse()
        .map_or_else(Vector3::zeros, |m| m * moment);
    for v in 0..weights.len() {
        let q = point(y, v) - c;
        let d = a + omega.cross(&q);
        for k in 0..3 {
            u[3 * v + k] -= d[k];
        }
    }
}

/// Conjugate gradients for `A d = b`, `A` symmetric positive definite given by its product
/// `apply` (`None` when a product fails): from `d = 0`, until `|A d - b| <= tolerance |b|` or
/// `max_iterations`. Returns the iterate and the iterations taken, or `None` when a product
/// failed, was not finite, or showed `A` not positive definite before any progress.
pub(crate) fn conjugate_gradient(
    mut apply: impl FnMut(&[f64]) -> Option<Vec<f64>>,
    b: &[f64],
    tolerance: f64,
    max_iterations: usize,
) -> Option<(Vec<f64>, usize)> {
    let n = b.len();
    let mut d = vec![0.0; n];
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut rr = dot(&r, &r);
    let stop = tolerance * tolerance * rr;
    let mut iterations = 0;
    while iterations < max_iterations && rr > stop {
        let ap = apply(&p)?;
        let pap = dot(&p, &ap);
        if !(pap.is_finite() && pap > 0.0) {
            // Not positive definite along p (round-off): keep what was reached.
            return (iterations > 0).then_some((d, iterations));
        }
        let alpha = rr / pap;
        for i in 0..n {
            d[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        let next = dot(&r, &r);
        iterations += 1;
        if !next.is_finite() {
            return None;
        }
        let beta = next / rr;
        rr = next;
        for i in 0..n {
            p[i] = r[i] + beta * p[i];
        }
    }
    d.iter().all(|v| v.is_finite()).then_some((d, iterations))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The projection removes rigid motions exactly, keeps fields already orthogonal to them,
    /// and is self-adjoint in the weighted inner product.
    #[test]
    fn rigid_projection_is_the_weighted_orthogonal_projection() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        let y: Vec<f64> = mesh
            .vertices
            .iter()
            .flat_map(|v| [v.x * 1.3 + 0.2, v.y, v.z * 0.7])
            .collect();
        let nv = y.len() / 3;
        let w: Vec<f64> = (0..nv).map(|v| 0.5 + (v as f64).sin().abs()).collect();
        // A rigid motion: translation plus rotation about an arbitrary point.
        let (t, om) = (Vector3::new(0.3, -0.1, 0.2), Vector3::new(0.05, 0.4, -0.2));
        let mut rigid: Vec<f64> = (0..nv)
            .flat_map(|v| {
                let d = t + om.cross(&(point(&y, v) - Vector3::new(1.0, 2.0, 3.0)));
                [d.x, d.y, d.z]
            })
            .collect();
        remove_rigid_motion(&y, &w, &mut rigid);
        assert!(rigid.iter().all(|v| v.abs() < 1e-12), "{rigid:?}");
        let field = |s: f64| -> Vec<f64> { (0..3 * nv).map(|i| (s * i as f64).cos()).collect() };
        let (mut u, mut z) = (field(0.7), field(1.9));
        remove_rigid_motion(&y, &w, &mut u);
        remove_rigid_motion(&y, &w, &mut z);
        let mut again = u.clone();
        remove_rigid_motion(&y, &w, &mut again);
        let diff = again
            .iter()
            .zip(&u)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-12, "idempotent: {diff:e}");
        let wdot =
            |a: &[f64], b: &[f64]| -> f64 { (0..3 * nv).map(|i| w[i / 3] * a[i] * b[i]).sum() };
        let (raw_u, raw_z) = (field(0.7), field(1.9));
        let lhs = wdot(&u, &raw_z);
        let rhs = wdot(&raw_u, &z);
        assert!(
            (lhs - rhs).abs() < 1e-10 * lhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
    }

    /// Conjugate gradients solve a small SPD system.
    #[test]
    fn conjugate_gradient_solves_an_spd_system() {
        let n = 12;
        let a = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| {
            if i == j {
                4.0 + i as f64
            } else {
                1.0 / (1.0 + (i as f64 - j as f64).abs())
            }
        });
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let (d, it) = conjugate_gradient(
            |p| {
                Some(
                    (&a * nalgebra::DVector::from_column_slice(p))
                        .as_slice()
                        .to_vec(),
                )
            },
            &b,
            1e-12,
            100,
        )
        .unwrap();
        assert!(it <= n + 2);
        let r = &a * nalgebra::DVector::from_column_slice(&d) - nalgebra::DVector::from_vec(b);
        assert!(r.norm() < 1e-10, "{r}");
    }
}
