//! [`CholeskySolver`]: sparse Cholesky plus Sherman-Morrison / Woodbury, with iterative
//! refinement.

use serde::{Deserialize, Serialize};

use super::problem::{LinearProblem, LinearSolver};
use crate::cholesky::SparseCholesky;
use crate::error::SolveError;
use crate::info::{Preconditioner, SolveInfo};
use crate::low_rank::solve_with_low_rank;
use crate::vector::dot;

/// Parameters of [`CholeskySolver`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CholeskyParams {
    /// Refine while `||b - A x|| > relative_tolerance ||b||` (floored at `1e-14`; default
    /// `1e-8`). The achieved residual is reported either way.
    pub relative_tolerance: f64,
    /// Most iterative-refinement steps with the same factorisation (default 2).
    pub max_refinements: usize,
    /// Run the numeric factorisation on the rayon pool (default `false`; needs the `parallel`
    /// feature).
    pub parallel: bool,
}

impl Default for CholeskyParams {
    fn default() -> Self {
        Self {
            relative_tolerance: 1e-8,
            max_refinements: 2,
            parallel: false,
        }
    }
}

/// Sparse Cholesky (faer, [`SparseCholesky`], symbolic analysis reused while the pattern
/// version is unchanged) of the assembled sparse part, refactorised at every solve, with the
/// low-rank terms handled exactly by Sherman-Morrison / Woodbury ([`solve_with_low_rank`]),
/// then iterative refinement with the same factorisation while the residual misses the
/// tolerance. The sparse part must be positive definite.
#[derive(Debug, Default)]
pub struct CholeskySolver {
    params: CholeskyParams,
    cholesky: SparseCholesky,
    z_scratch: Vec<Vec<f64>>,
    product: Vec<f64>,
    residual: Vec<f64>,
    correction: Vec<f64>,
    factorizations: u64,
}

impl CholeskySolver {
    /// A solver with these parameters.
    pub fn new(params: CholeskyParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// The parameters.
    pub fn params(&self) -> &CholeskyParams {
        &self.params
    }
}

impl LinearSolver for CholeskySolver {
    fn name(&self) -> &str {
        "cholesky"
    }

    fn needs_assembled_matrix(&self) -> bool {
        true
    }

    fn factorizations(&self) -> u64 {
        self.factorizations
    }

    fn factorization_seconds(&self) -> f64 {
        self.cholesky.factorization_seconds()
    }

    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError> {
        let (a, version) = problem
            .matrix()
            .ok_or(SolveError::NeedsAssembledMatrix { solver: "cholesky" })?;
        if problem.correction.is_some() {
            return Err(SolveError::CorrectionUnsupported { solver: "cholesky" });
        }
        problem.check_dimensions(b, x)?;
        let n = a.n;
        self.cholesky.set_parallel(self.params.parallel);
        self.cholesky.factorize(a, version)?;
        self.factorizations += 1;
        let terms: Vec<(f64, &[f64])> = problem
            .low_rank
            .iter()
            .map(|t| (problem.k_coef * t.coefficient, t.vector.as_slice()))
            .collect();
        let chol = &mut self.cholesky;
        solve_with_low_rank(
            |r| chol.solve_in_place(r),
            &terms,
            b,
            x,
            &mut self.z_scratch,
        )?;
        // Report the achieved residual honestly; refine with the same factorisation if it
        // misses the tolerance.
        let tol = self.params.relative_tolerance.max(1e-14);
        let bn = dot(b, b).sqrt();
        for v in [&mut self.product, &mut self.residual, &mut self.correction] {
            v.resize(n, 0.0);
        }
        let mut refinements = 0;
        loop {
            problem.apply(x, &mut self.product);
            for i in 0..n {
                self.residual[i] = b[i] - self.product[i];
            }
            let rel = if bn > 0.0 {
                dot(&self.residual, &self.residual).sqrt() / bn
            } else {
                0.0
            };
            if !rel.is_finite() {
                return Err(SolveError::NonFinite {
                    iteration: refinements,
                });
            }
            if rel <= tol || refinements == self.params.max_refinements {
                return Ok(SolveInfo {
                    iterations: 1 + refinements,
                    relative_residual: rel,
                    converged: rel <= tol,
                    preconditioner: Preconditioner::None,
                });
            }
            solve_with_low_rank(
                |r| chol.solve_in_place(r),
                &terms,
                &self.residual,
                &mut self.correction,
                &mut self.z_scratch,
            )?;
            for i in 0..n {
                x[i] += self.correction[i];
            }
            refinements += 1;
        }
    }
}
