//! [`FactorizedPcg`]: CG preconditioned by a kept (lagged) sparse Cholesky factorisation.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::params::CgParams;
use super::problem::{LinearProblem, LinearSolver};
use crate::cholesky::SparseCholesky;
use crate::csr::CsrMatrix;
use crate::error::SolveError;
use crate::info::{Preconditioner, SolveInfo};
use crate::krylov::{CgWorkspace, cg};
use crate::vector::dot;

/// The LU factorisation of the Woodbury capacitance matrix `S = I + C U^T Z`.
type Capacitance = nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>;

/// Parameters of [`FactorizedPcg`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FactorizedPcgParams {
    /// CG iteration budget and tolerance (the budget of a solve with a fresh factor).
    pub cg: CgParams,
    /// When a solve with the lagged factor takes more than this many CG iterations (default
    /// 8), the next [`FactorizedPcgParams::fresh_solves_after_slow`] solves refactorise first,
    /// then the lagged factor is tried again. A solve with a lagged factor that does not
    /// converge within `2 x refactor_iterations` iterations (or breaks down numerically) is
    /// continued with a fresh factorisation of the current matrix; one that meets non-positive
    /// curvature returns it (the matrix is indefinite).
    pub refactor_iterations: usize,
    /// Solves that refactorise first after a slow one (default 6: two steps of three Newton
    /// iterations).
    pub fresh_solves_after_slow: usize,
    /// Run the numeric factorisation on the rayon pool (default `false`; needs the `parallel`
    /// feature).
    pub parallel: bool,
    /// The cost of one numeric factorisation in CG iterations (default 0: off). When set, the
    /// CG iterations that solves with the kept factor take beyond what the solve right after
    /// the last factorisation took are summed, and once that excess reaches this cost the next
    /// solve refactorises first: the factor is refreshed when keeping it has cost as much as
    /// refreshing it would (an amortisation rule; it counts iterations, not seconds, so runs
    /// repeat exactly).
    #[serde(default)]
    pub refactor_cost: usize,
    /// Keep the low-rank part of the preconditioner with the factor (default `true`): a
    /// solve with a kept factor uses the `U`, `Z = (L L^T)^-1 U` and coefficients prepared
    /// when the factor was made (or last refreshed) instead of solving for the current terms'
    /// `Z` (one pass over the factor fewer per solve). CG still solves the current problem,
    /// whose terms differ from the kept ones by a low-rank update; a solve with a fresh factor
    /// prepares `Z` for its own terms. With `false` every solve prepares `Z` for its terms.
    #[serde(default = "default_true")]
    pub lag_low_rank: bool,
    /// Apply the preconditioner with a single-precision copy of the factor when CG is asked
    /// for a relative residual of at least [`SINGLE_PRECISION_MIN_TOLERANCE`] (default
    /// `true`): the triangular solves, bound by reading the factor from memory, take about
    /// half the time, and a factor rounded to 7 digits preconditions a solve to a few digits as
    /// well as the exact one. Tighter solves use the factor itself.
    #[serde(default = "default_true")]
    pub single_precision_solves: bool,
    /// Compute the factor itself in single precision (default `true`;
    /// [`SparseCholesky::set_single_precision_factorization`]): it only preconditions CG,
    /// which applies the double-precision matrix, so a solve still meets its tolerance. A
    /// solve asked for less than [`SINGLE_PRECISION_MIN_TOLERANCE`] applies the rounded factor
    /// in double-precision arithmetic. A non-positive pivot in single precision is checked by
    /// a double-precision factorisation before the matrix is called indefinite.
    #[serde(default = "default_true")]
    pub single_precision_factorization: bool,
    /// When the caller retries with a larger shift ([`LinearSolver::set_shift_retries`]),
    /// call the matrix indefinite as soon as its single-precision factorisation meets a
    /// non-positive pivot, without the double-precision check (default `true`;
    /// [`SparseCholesky::set_single_precision_verdict`]).
    #[serde(default = "default_true")]
    pub single_precision_verdict: bool,
}

fn default_true() -> bool {
    true
}

/// The smallest CG tolerance a solve of [`FactorizedPcg`] applies a single-precision factor
/// for ([`FactorizedPcgParams::single_precision_solves`]). CG corrects the rounding of the
/// factor as it corrects a lagged one, but a solve asked for nearly as many digits as the
/// rounded factor carries (about 7, less the growth of the triangular solves) would pay extra
/// iterations for them: tighter solves use the factor itself. (On the teddy's Newton matrix,
/// nnz(L) = 3.8M, a solve with the rounded factor is 6.6e-7 from the exact one, relative:
/// `benches/examples/factor_profile.rs`.)
pub const SINGLE_PRECISION_MIN_TOLERANCE: f64 = 1e-5;

impl Default for FactorizedPcgParams {
    fn default() -> Self {
        Self {
            cg: CgParams::default(),
            refactor_iterations: 8,
            fresh_solves_after_slow: 6,
            parallel: false,
            refactor_cost: 0,
            lag_low_rank: true,
            single_precision_solves: true,
            single_precision_factorization: true,
            single_precision_verdict: true,
        }
    }
}

/// CG on the assembled matrix (low-rank terms applied matrix-free) preconditioned by a sparse
/// Cholesky factorisation of an *earlier* matrix, kept across solves while it pays:
///
/// 1. If there is no factor for the current pattern, or a refresh is pending, factorise the
///    current matrix (a *fresh* solve); otherwise keep the lagged factor (a *stale* solve).
/// 2. Run CG; a stale solve gets at most `2 x refactor_iterations` iterations.
/// 3. A stale solve that does not converge in that budget, or breaks down numerically,
///    refactorises the current matrix and continues CG from where it was (from zero after a
///    breakdown). A stale solve that meets non-positive curvature returns that error at once
///    and keeps the factor: `p^T A p <= 0` proves the current matrix indefinite, so a fresh
///    factorisation would fail too (the caller's shifted retry may reuse the kept factor).
/// 4. A solve that started stale and needed more than `refactor_iterations` iterations (or a
///    refactorisation) means the matrix changes fast: the next `fresh_solves_after_slow` solves
///    refactorise first.
///
/// The preconditioner is `P = L L^T + k_coef sum_i c_i u_i u_i^T`: the kept factor of the
/// sparse part plus low-rank terms (the gas coupling, Eq. 16-17), applied by Sherman-Morrison /
/// Woodbury (`P^-1 r = y - Z S^-1 C U^T y`, `y = (L L^T)^-1 r`, `Z = (L L^T)^-1 U`,
/// `S = I + C U^T Z`: no extra triangular solves per CG iteration), so that a dominant gas term
/// costs no CG iterations. A fresh factor gets the problem's current terms (their `Z` solved
/// in the same pass over the factor as the first preconditioned residual); a kept factor keeps
/// the terms it was made with, like the sparse part it factorises
/// ([`FactorizedPcgParams::lag_low_rank`]; a term that moves with the shape is then off by a
/// low-rank update, which CG absorbs in an iteration or two, and no solve for the new `Z` is
/// paid). Terms with a negative coefficient (which could make `P` indefinite) are left to CG.
///
/// The sparse part must be positive definite for the factorisation. With the exact tangent an
/// indefinite matrix is met as non-positive curvature in CG or a non-positive pivot, returned
/// as an error for the caller's mass-shift retry (`SolveError::is_indefinite`).
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
    /// `(L L^T)^-1 u_i` for the low-rank terms in the preconditioner (reused buffers).
    low_rank_z: Vec<Vec<f64>>,
    /// `k_coef c_i` of those terms.
    low_rank_c: Vec<f64>,
    /// Indices (into the problem's terms) of those terms.
    low_rank_terms: Vec<usize>,
    /// `(L L^T)^-1 b` for a solve from zero, solved together with the `low_rank_z` (one pass
    /// over the factor for all of them), handed to CG as its first preconditioned residual.
    first_y: Vec<f64>,
    /// The right-hand sides of that batched solve, column after column.
    batch: Vec<f64>,
    /// The vectors `U` the kept `low_rank_z` were solved for, and the factorisation (count)
    /// they were solved with: a solve with the same terms and factor (a chord step of the
    /// integrator, which reuses the last matrix and its terms) keeps `Z`.
    z_vectors: Vec<Vec<f64>>,
    /// The coefficients `k_coef c_i` the kept `low_rank_z` were prepared with.
    z_coefficients: Vec<f64>,
    z_factorization: Option<u64>,
    /// Whether the preconditioner of the current solve uses the kept `U`, `Z` and
    /// coefficients (a lagged low-rank part) instead of the problem's current terms.
    lagged_low_rank: bool,
    /// CG iterations of the first solve with the current factor.
    fresh_iterations: usize,
    /// CG iterations beyond `fresh_iterations` summed over the solves with a kept factor since
    /// the last factorisation ([`FactorizedPcgParams::refactor_cost`]).
    excess_iterations: usize,
    /// The caller retries a matrix called indefinite with a larger shift
    /// ([`LinearSolver::set_shift_retries`]).
    shift_retries: bool,
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

    /// Prepares the Sherman-Morrison / Woodbury part of the preconditioner for the problem's
    /// low-rank terms with the current factor; returns the LU of the capacitance matrix
    /// `S = I + C U^T Z`, or `None` when no term is used. With `first = Some(b)` (a solve from
    /// zero, whose first CG residual is `b`) it also solves `(L L^T) y = b` into
    /// `self.first_y`, in the same pass over the factor as the `Z` (returns whether it did).
    fn prepare_low_rank(
        &mut self,
        problem: &LinearProblem<'_>,
        first: Option<&[f64]>,
        lagged: bool,
    ) -> Result<(Option<Capacitance>, bool), SolveError> {
        self.lagged_low_rank = false;
        self.low_rank_terms.clear();
        self.low_rank_c.clear();
        for (i, t) in problem.low_rank.iter().enumerate() {
            let c = problem.k_coef * t.coefficient;
            if c > 0.0 && c.is_finite() {
                self.low_rank_terms.push(i);
                self.low_rank_c.push(c);
            }
        }
        let r = self.low_rank_terms.len();
        if r == 0 {
            return Ok((None, false));
        }
        let n = problem.low_rank[self.low_rank_terms[0]].vector.len();
        let same_z = self.z_factorization == Some(self.factorizations)
            && self.z_vectors.len() == r
            && self
                .low_rank_terms
                .iter()
                .zip(&self.z_vectors)
                .all(|(&i, kept)| problem.low_rank[i].vector == kept.as_slice());
        let lag = !same_z
            && lagged
            && self.params.lag_low_rank
            && self.z_factorization == Some(self.factorizations)
            && self.z_vectors.len() == r;
        if lag {
            self.lagged_low_rank = true;
        }
        if same_z || lag {
            if let Some(b) = first {
                self.first_y.clear();
                self.first_y.extend_from_slice(b);
                self.cholesky.solve_in_place(&mut self.first_y)?;
            }
            return Ok(self.capacitance(problem, first.is_some()));
        }
        // Z = (L L^T)^-1 U, and y = (L L^T)^-1 b after them: one batched solve.
        let columns = r + usize::from(first.is_some());
        self.batch.clear();
        for &i in &self.low_rank_terms {
            self.batch.extend_from_slice(&problem.low_rank[i].vector);
        }
        if let Some(b) = first {
            self.batch.extend_from_slice(b);
        }
        if self.batch.len() != columns * n {
            return Err(SolveError::Dimension {
                what: "low-rank vector",
                len: self.batch.len(),
                expected: columns * n,
            });
        }
        self.cholesky
            .solve_columns_in_place(&mut self.batch, columns)?;
        self.low_rank_z.resize_with(r, Vec::new);
        for (z, column) in self.low_rank_z.iter_mut().zip(self.batch.chunks_exact(n)) {
            z.clear();
            z.extend_from_slice(column);
        }
        if first.is_some() {
            self.first_y.clear();
            self.first_y.extend_from_slice(&self.batch[r * n..]);
        }
        self.z_vectors.resize_with(r, Vec::new);
        for (kept, &i) in self.z_vectors.iter_mut().zip(&self.low_rank_terms) {
            kept.clear();
            kept.extend_from_slice(&problem.low_rank[i].vector);
        }
        self.z_coefficients.clear();
        self.z_coefficients.extend_from_slice(&self.low_rank_c);
        self.z_factorization = Some(self.factorizations);
        Ok(self.capacitance(problem, first.is_some()))
    }

    /// The LU of the capacitance matrix `S = I + C U^T Z` of the prepared terms (`None` when
    /// it is not finite or singular), with the `batched` flag passed through.
    fn capacitance(
        &self,
        problem: &LinearProblem<'_>,
        batched: bool,
    ) -> (Option<Capacitance>, bool) {
        let r = self.low_rank_terms.len();
        let mut s = DMatrix::<f64>::identity(r, r);
        for (a, &i) in self.low_rank_terms.iter().enumerate() {
            let (u, c) = if self.lagged_low_rank {
                (&self.z_vectors[a][..], self.z_coefficients[a])
            } else {
                (&problem.low_rank[i].vector[..], self.low_rank_c[a])
            };
            for (b, z) in self.low_rank_z.iter().enumerate() {
                s[(a, b)] += c * dot(u, z);
            }
        }
        if !s.iter().all(|v| v.is_finite()) {
            return (None, batched);
        }
        let lu = s.lu();
        (lu.is_invertible().then_some(lu), batched)
    }
}

impl LinearSolver for FactorizedPcg {
    fn name(&self) -> &str {
        "factorized-pcg"
    }

    fn set_relative_tolerance(&mut self, tolerance: f64) {
        self.params.cg.relative_tolerance = tolerance;
    }

    fn needs_assembled_matrix(&self) -> bool {
        true
    }

    /// CG applies the whole problem; the matrix only preconditions.
    fn accepts_correction(&self) -> bool {
        true
    }

    fn factorizations(&self) -> u64 {
        self.factorizations
    }

    fn factorization_seconds(&self) -> f64 {
        self.cholesky.factorization_seconds()
    }

    /// The next solve refactorises first (then the kept factor is used again as usual).
    fn set_shift_retries(&mut self, retries: bool) {
        self.shift_retries = retries;
    }

    fn invalidate_factorization(&mut self) {
        self.fresh_solves_left = self.fresh_solves_left.max(1);
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
        self.cholesky.set_single_precision_solves(
            self.params.single_precision_solves
                && self.params.cg.relative_tolerance >= SINGLE_PRECISION_MIN_TOLERANCE,
        );
        self.cholesky
            .set_single_precision_factorization(self.params.single_precision_factorization);
        self.cholesky.set_single_precision_verdict(
            self.shift_retries && self.params.single_precision_verdict,
        );
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
            // From zero, CG's first residual is `b`: its preconditioned form is solved with the
            // low-rank terms' (one pass over the factor for both).
            let from_zero = x.iter().all(|&v| v == 0.0);
            let (capacitance, batched) =
                self.prepare_low_rank(problem, from_zero.then_some(b), !fresh)?;
            let chol = &mut self.cholesky;
            let lagged = self.lagged_low_rank;
            let (terms, zs) = (&self.low_rank_terms, &self.low_rank_z);
            let (kept_u, kept_c, cs) = (&self.z_vectors, &self.z_coefficients, &self.low_rank_c);
            let mut first_y = batched.then_some(self.first_y.as_slice());
            let mut w = DVector::<f64>::zeros(terms.len());
            let res = cg(
                |p, out| problem.apply(p, out),
                |r, z| {
                    match first_y.take() {
                        // The first residual of a solve from zero is `b` itself.
                        Some(y) if r == b => z.copy_from_slice(y),
                        _ => {
                            z.copy_from_slice(r);
                            // Cannot fail: factorised above for this size.
                            let solved = chol.solve_in_place(z);
                            debug_assert!(solved.is_ok(), "{solved:?}");
                        }
                    }
                    if let Some(lu) = &capacitance {
                        for (a, &i) in terms.iter().enumerate() {
                            w[a] = if lagged {
                                kept_c[a] * dot(&kept_u[a], z)
                            } else {
                                cs[a] * dot(&problem.low_rank[i].vector, z)
                            };
                        }
                        if lu.solve_mut(&mut w) {
                            for (coef, zj) in w.iter().zip(zs) {
                                for (zi, v) in z.iter_mut().zip(zj) {
                                    *zi -= coef * v;
                                }
                            }
                        }
                    }
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
                    if fresh {
                        self.fresh_iterations = info.iterations;
                        self.excess_iterations = 0;
                    } else if self.params.refactor_cost > 0 {
                        self.excess_iterations += total.saturating_sub(self.fresh_iterations);
                        if self.excess_iterations >= self.params.refactor_cost {
                            self.fresh_solves_left = self.fresh_solves_left.max(1);
                        }
                    }
                    info.iterations = total;
                    info.preconditioner = Preconditioner::Cholesky;
                    return Ok(info);
                }
                Err(e) if fresh => return Err(e),
                // Non-positive curvature `p^T A p <= 0` shows that the matrix itself is not
                // positive definite (the preconditioner does not enter `p^T A p`): a fresh
                // factorisation would meet a non-positive pivot. The kept factor stays for the
                // caller's shifted retry.
                Err(e @ SolveError::NonPositiveCurvature { .. }) => return Err(e),
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
