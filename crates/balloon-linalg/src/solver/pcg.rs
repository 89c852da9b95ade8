//! [`AssembledPcg`]: preconditioned CG on the assembled matrix.

use super::params::{CgParams, PcgPreconditioner};
use super::problem::{LinearProblem, LinearSolver};
use crate::error::SolveError;
use crate::info::{Preconditioner, SolveInfo};
use crate::krylov::{CgWorkspace, cg};
use crate::precond::{IncompleteCholesky, jacobi};

/// Preconditioned CG on the assembled sparse part, the low-rank terms applied matrix-free
/// inside the mat-vec. Preconditioner: Jacobi on `diag(A)` (low-rank diagonal included) or
/// IC(0) of the sparse part ([`IncompleteCholesky`], its pattern reused while the problem's
/// pattern version is unchanged). A non-positive diagonal is reported as non-positive
/// curvature (the matrix cannot be positive definite).
#[derive(Clone, Debug, Default)]
pub struct AssembledPcg {
    params: CgParams,
    preconditioner: PcgPreconditioner,
    diag: Vec<f64>,
    ic0: IncompleteCholesky,
    workspace: CgWorkspace,
}

impl AssembledPcg {
    /// A solver with these parameters and preconditioner.
    pub fn new(params: CgParams, preconditioner: PcgPreconditioner) -> Self {
        Self {
            params,
            preconditioner,
            ..Self::default()
        }
    }

    /// The parameters.
    pub fn params(&self) -> &CgParams {
        &self.params
    }
}

impl LinearSolver for AssembledPcg {
    fn name(&self) -> &str {
        "pcg"
    }

    fn set_relative_tolerance(&mut self, tolerance: f64) {
        self.params.relative_tolerance = tolerance;
    }

    fn needs_assembled_matrix(&self) -> bool {
        true
    }

    /// CG applies the whole problem; the matrix only preconditions.
    fn accepts_correction(&self) -> bool {
        true
    }

    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError> {
        let (a, version) = problem
            .matrix()
            .ok_or(SolveError::NeedsAssembledMatrix { solver: "pcg" })?;
        problem.check_dimensions(b, x)?;
        let n = a.n;
        let k_coef = problem.k_coef;
        self.diag.resize(n, 0.0);
        a.diagonal_into(&mut self.diag);
        for t in problem.low_rank {
            for i in 0..n.min(t.vector.len()) {
                self.diag[i] += k_coef * t.coefficient * t.vector[i] * t.vector[i];
            }
        }
        if let Some(i) = self.diag.iter().position(|d| d.is_nan() || *d <= 0.0) {
            return Err(SolveError::NonPositiveCurvature {
                iteration: 0,
                curvature: self.diag[i],
                direction_norm_squared: 1.0,
            });
        }
        let use_ic = self.preconditioner == PcgPreconditioner::IncompleteCholesky;
        if use_ic {
            self.ic0.factorize(a, version)?;
        }
        let (diag, ic) = (&self.diag, &self.ic0);
        let mut info = cg(
            |p, out| problem.apply(p, out),
            |r, z| {
                if use_ic {
                    ic.apply(r, z);
                } else {
                    jacobi(diag, r, z);
                }
            },
            b,
            x,
            self.params.max_iterations,
            self.params.relative_tolerance,
            &mut self.workspace,
        )?;
        info.preconditioner = if use_ic {
            Preconditioner::IncompleteCholesky
        } else {
            Preconditioner::DiagonalJacobi
        };
        Ok(info)
    }
}
