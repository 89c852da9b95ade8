//! [`FactorizedPcg`]: CG preconditioned by a kept (lagged) sparse Cholesky factorisation.

use serde::{Deserialize, Serialize};

use super::{CgParams, LinearProblem, LinearSolver, Preconditioner, SolveError, SolveInfo};
use crate::cholesky::SparseCholesky;
use crate::csr::CsrMatrix;
use crate::krylov::{CgWorkspace, cg};

/// Parameters of [`FactorizedPcg`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FactorizedPcgParams {
    /// CG iteration budget and tolerance (the budget of a solve with a fresh factor).
    pub cg: CgParams,
    /// When a solve with the lagged factor takes more than this many CG iterations (default
    /// 8), the next [`FactorizedPcgParams::fresh_solves_after_slow`] solves refactorise first,
    /// then the lagged factor is tried again. A solve with a lagged factor that does not
    /// converge within `2 x refactor_iterations` iterations (or breaks down) is continued with
    /// a fresh factorisation of the current matrix.
    pub refactor_iterations: usize,
    /// Solves that refactorise first after a slow one (default 6: two steps of three Newton
    /// iterations).
    pub fresh_solves_after_slow: usize,
    /// Run the numeric factorisation on the rayon pool (default `false`; needs the `parallel`
    /// feature).
    pub parallel: bool,
}

impl Default for FactorizedPcgParams {
    fn default() -> Self {
        Self {
            cg: CgParams::default(),
            refactor_iterations: 8,
            fresh_solves_after_slow: 6,
            parallel: false,
        }
    }
}

/// CG on the assembled matrix (low-rank terms applied matrix-free) preconditioned by a sparse
/// Cholesky factorisation of an *earlier* matrix, kept across solves while it pays:
///
/// 1. If there is no factor for the current pattern, or a refresh is pending, factorise the
///    current matrix (a *fresh* solve); otherwise keep the lagged factor (a *stale* solve).
/// 2. Run CG; a stale solve gets at most `2 x refactor_iterations` iterations.
/// 3. A stale solve that does not converge in that budget, or breaks down, refactorises the
///    current matrix and continues CG from where it was (from zero after a breakdown).
/// 4. A solve that started stale and needed more than `refactor_iterations` iterations (or a
///    refactorisation) means the matrix changes fast: the next `fresh_solves_after_slow` solves
///    refactorise first.
///
/// The sparse part must be positive definite for the factorisation; use it with a projected
/// (SPD) tangent.
#[derive(Debug, Default)]
pub struct FactorizedPcg {
    params: FactorizedPcgParams,
    cholesky: SparseCholesky,
    /// Pattern version of the kept factor.
    factor_version: Option<u64>,
    /// Solves left that refactorise first (set after a slow stale solve).
    fresh_solves_left: usize,
    workspace: CgWorkspace,
    factorizations: u64,
}

impl FactorizedPcg {
    /// A solver with these parameters.
    pub fn new(params: FactorizedPcgParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// The parameters.
    pub fn params(&self) -> &FactorizedPcgParams {
        &self.params
    }

    /// Factorises `a` and records it as the kept factor.
    fn refactorize(&mut self, a: &CsrMatrix, version: u64) -> Result<(), SolveError> {
        self.factor_version = None;
        self.cholesky.factorize(a, version)?;
        self.factor_version = Some(version);
        self.factorizations += 1;
        Ok(())
    }
}

impl LinearSolver for FactorizedPcg {
    fn name(&self) -> &str {
        "factorized-pcg"
    }

    fn needs_assembled_matrix(&self) -> bool {
        true
    }

    fn factorizations(&self) -> u64 {
        self.factorizations
    }

    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError> {
        let (a, version) = problem.matrix().ok_or(SolveError::NeedsAssembledMatrix {
            solver: "factorized-pcg",
        })?;
        problem.check_dimensions(b, x)?;
        self.cholesky.set_parallel(self.params.parallel);
        let mut fresh = false;
        if self.fresh_solves_left > 0
            || !self.cholesky.is_factorized()
            || self.factor_version != Some(version)
        {
            self.refactorize(a, version)?;
            self.fresh_solves_left = self.fresh_solves_left.saturating_sub(1);
            fresh = true;
        }
        let started_stale = !fresh;
        let threshold = self.params.refactor_iterations.max(1);
        let max_iterations = self.params.cg.max_iterations;
        let mut total = 0;
        loop {
            let cap = if fresh {
                max_iterations
            } else {
                max_iterations.min(2 * threshold)
            };
            let chol = &mut self.cholesky;
            let res = cg(
                |p, out| problem.apply(p, out),
                |r, z| {
                    z.copy_from_slice(r);
                    // Cannot fail: factorised above for this size.
                    let solved = chol.solve_in_place(z);
                    debug_assert!(solved.is_ok(), "{solved:?}");
                },
                b,
                x,
                cap,
                self.params.cg.relative_tolerance,
                &mut self.workspace,
            );
            match res {
                Ok(mut info) if info.converged || fresh => {
                    total += info.iterations;
                    if started_stale && (fresh || total > threshold) {
                        // The lagged factor was a poor preconditioner: the matrix is changing
                        // fast, refactorise for the next few solves.
                        self.fresh_solves_left = self.params.fresh_solves_after_slow;
                    }
                    info.iterations = total;
                    info.preconditioner = Preconditioner::Cholesky;
                    return Ok(info);
                }
                Err(e) if fresh => return Err(e),
                other => {
                    // The stale factor is no longer a good preconditioner (or the matrix moved
                    // too far): refactorise the current matrix and continue from the iterate
                    // reached (or from zero after a breakdown).
                    match other {
                        Ok(info) => total += info.iterations,
                        Err(_) => x.fill(0.0),
                    }
                    self.refactorize(a, version)?;
                    fresh = true;
                }
            }
        }
    }
}
