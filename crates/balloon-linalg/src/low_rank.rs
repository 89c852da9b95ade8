//! Dense low-rank terms `c u u^T` that are never assembled ([`LowRankTerm`]; the uniform-gas
//! coupling of Wang et al. 2015, Eq. 16-17) and exact solves with them by Sherman-Morrison / Woodbury
//! ([`solve_with_low_rank`]).

use nalgebra::{DMatrix, DVector};

use crate::error::SolveError;
use crate::vector::dot;

/// A dense symmetric rank-1 term `coefficient * u u^T` of a stiffness matrix that must never be
/// assembled (the uniform-gas coupling of Wang et al. 2015, Eq. 16-17).
#[derive(Clone, Debug, Default)]
pub struct LowRankTerm {
    /// Scalar factor (units of stiffness per unit of `u u^T`).
    pub coefficient: f64,
    /// The vector `u`, one entry per degree of freedom.
    pub vector: Vec<f64>,
}

/// `out += scale * sum_i c_i u_i (u_i . p)`: the product of the low-rank terms, scaled.
#[inline]
pub fn add_low_rank_product(terms: &[LowRankTerm], scale: f64, p: &[f64], out: &mut [f64]) {
    let n = out.len();
    for t in terms {
        let s = scale * t.coefficient * dot(&t.vector, p);
        for i in 0..n {
            out[i] += s * t.vector[i];
        }
    }
}

/// Solves `(A + sum_i c_i u_i u_i^T) x = b` given a solver for `A` (`solve_a` overwrites its
/// argument with `A^-1` of it), by Sherman-Morrison (one term) / Woodbury (several):
/// `x = y - Z (I + C U^T Z)^-1 C U^T y` with `y = A^-1 b`, `Z = A^-1 U`, `C = diag(c_i)`.
/// For one term this is `x = y - c z (u^T y) / (1 + c u^T z)`.
///
/// `terms` are `(c_i, u_i)` pairs; terms with `c_i = 0` are skipped. `z_scratch` is reused.
pub fn solve_with_low_rank(
    mut solve_a: impl FnMut(&mut [f64]) -> Result<(), SolveError>,
    terms: &[(f64, &[f64])],
    b: &[f64],
    x: &mut [f64],
    z_scratch: &mut Vec<Vec<f64>>,
) -> Result<(), SolveError> {
    let n = b.len();
    x.copy_from_slice(b);
    solve_a(x)?;
    let active: Vec<(f64, &[f64])> = terms
        .iter()
        .copied()
        .filter(|(c, u)| *c != 0.0 && !u.is_empty())
        .collect();
    if active.is_empty() {
        return Ok(());
    }
    for (_, u) in &active {
        if u.len() != n {
            return Err(SolveError::Dimension {
                what: "low-rank vector",
                len: u.len(),
                expected: n,
            });
        }
    }
    let r = active.len();
    z_scratch.resize_with(r, Vec::new);
    for (z, (_, u)) in z_scratch.iter_mut().zip(&active) {
        z.clear();
        z.extend_from_slice(u);
        solve_a(z)?;
    }
    // Capacitance S = I + C U^T Z, rhs w = C U^T y.
    let mut s = DMatrix::<f64>::identity(r, r);
    let mut w = DVector::<f64>::zeros(r);
    for (i, (ci, ui)) in active.iter().enumerate() {
        for j in 0..r {
            s[(i, j)] += ci * dot(ui, &z_scratch[j]);
        }
        w[i] = ci * dot(ui, x);
    }
    let coef = s
        .lu()
        .solve(&w)
        .filter(|c| c.iter().all(|v| v.is_finite()))
        .ok_or(SolveError::SingularCapacitance { rank: r })?;
    for (j, z) in z_scratch.iter().take(r).enumerate() {
        for i in 0..n {
            x[i] -= coef[j] * z[i];
        }
    }
    Ok(())
}
