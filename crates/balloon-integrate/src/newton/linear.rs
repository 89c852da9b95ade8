//! The Newton matrix `A = m_coef M + k_coef K` of a force system (the dense low-rank terms of
//! `K` kept apart, Wang et al. 2015, Eq. 16-17) and its solve by the configured
//! [`LinearSolver`]: the stiffness handed to the solver (assembled into a reused sparse pattern,
//! or as a matrix-free operator), the low-rank terms kept with an assembled matrix for its
//! reuse, and the time of each phase.

use std::time::Instant;

use balloon_linalg::sprs::CsMat;
use balloon_linalg::{
    LinearProblem, LinearSolver, Preconditioner, SolveError, SolveInfo, SparseAssembler,
    StiffnessCorrection, StiffnessOperator,
};

use super::NewtonError;
use crate::system::{ForceSystem, LowRankTerm, collect_stiffness};
use crate::timing::{PhaseTimes, ms_since};

/// The stiffness of a [`ForceSystem`] as a matrix-free operator: `K p = -df(p)` from its force
/// differentials (low-rank terms included), and the diagonal of its sparse part when offered.
pub(crate) struct SystemStiffness<'a, S: ?Sized>(pub(crate) &'a S);

impl<S: ForceSystem + ?Sized> StiffnessOperator for SystemStiffness<'_, S> {
    fn apply(&self, p: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        self.0.add_force_differential(p, out);
        for o in out.iter_mut() {
            *o = -*o;
        }
    }

    fn add_diagonal(&self, diagonal: &mut [f64]) -> bool {
        self.0.add_stiffness_diagonal(diagonal).is_ok()
    }
}

/// The correction of a split stiffness ([`ForceSystem::set_stiffness_split`]) as the linear
/// problem's [`StiffnessCorrection`].
struct SystemCorrection<'a, S: ?Sized>(&'a S);

impl<S: ForceSystem + ?Sized> StiffnessCorrection for SystemCorrection<'_, S> {
    fn add_scaled(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        self.0.add_stiffness_correction(scale, p, out);
    }
}

/// The linear algebra of one Newton solver: the linear solver, the sparse pattern and matrix it
/// assembles into, reused across iterations, steps and solves.
#[derive(Debug)]
pub(crate) struct NewtonMatrix {
    /// The linear solver.
    pub(crate) solver: Box<dyn LinearSolver>,
    assembler: SparseAssembler,
    /// The stiffness triplets of the last linearisation (only those beyond the element blocks
    /// when `use_blocks`).
    triplets: Vec<(usize, usize, f64)>,
    /// The system gave its stiffness as element blocks.
    use_blocks: bool,
    /// The system's stiffness is split at the last linearisation: the matrix holds a
    /// preconditioner's `K_sparse`, the rest is the system's correction
    /// ([`ForceSystem::set_stiffness_split`]).
    split: bool,
    /// Whether the assembler holds the matrix of the last linear solve.
    pub(crate) assembled_last: bool,
    /// The low-rank terms that go with the assembled matrix (for its reuse).
    kept_low_rank: Vec<LowRankTerm>,
    /// The preconditioner of the last successful solve.
    pub(crate) last_preconditioner: Preconditioner,
    /// `m_coef` of the matrix the solver last factorised.
    pub(crate) factored_mass_coefficient: Option<f64>,
}

impl NewtonMatrix {
    /// A Newton matrix solved by `solver`.
    pub(crate) fn new(solver: Box<dyn LinearSolver>) -> Self {
        Self {
            solver,
            assembler: SparseAssembler::new(),
            triplets: Vec::new(),
            use_blocks: false,
            split: false,
            assembled_last: false,
            kept_low_rank: Vec::new(),
            last_preconditioner: Preconditioner::Unreported,
            factored_mass_coefficient: None,
        }
    }

    /// Replaces the linear solver (its factorisation is then unknown).
    pub(crate) fn set_solver(&mut self, solver: Box<dyn LinearSolver>) {
        self.solver = solver;
        self.factored_mass_coefficient = None;
    }

    /// Linearises `system` at its last force evaluation: its stiffness
    /// ([`ForceSystem::refresh_stiffness`]) and, for an assembled solver, the triplets of the
    /// part of `K` beyond its element blocks.
    pub(crate) fn linearize<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        iteration: usize,
        times: &mut PhaseTimes,
    ) -> Result<(), NewtonError> {
        let started = Instant::now();
        self.split = system.set_stiffness_split(
            self.solver.needs_assembled_matrix() && self.solver.accepts_correction(),
        );
        let refreshed = system.refresh_stiffness();
        times.forces_ms += ms_since(started);
        refreshed.map_err(|source| NewtonError::System { iteration, source })?;
        if self.solver.needs_assembled_matrix() {
            let started = Instant::now();
            let collected = collect_stiffness(&*system, &mut self.triplets);
            times.assembly_ms += ms_since(started);
            self.use_blocks =
                collected.map_err(|source| NewtonError::System { iteration, source })?;
        }
        Ok(())
    }

    /// Solves `(m_coef M + k_coef K) out = rhs`, assembling `A` first when the solver needs it
    /// (from the triplets of the last [`NewtonMatrix::linearize`]), or with the matrix already
    /// in the assembler and its kept low-rank terms when `reuse` is set (a chord step).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve<S: ForceSystem + ?Sized>(
        &mut self,
        system: &S,
        m_coef: f64,
        k_coef: f64,
        rhs: &[f64],
        out: &mut [f64],
        reuse: bool,
        times: &mut PhaseTimes,
    ) -> Result<SolveInfo, SolveError> {
        let masses = system.masses();
        out.fill(0.0);
        let factor_before = self.solver.factorization_seconds();
        let factorizations = self.solver.factorizations();
        let started = Instant::now();
        let result = if self.solver.needs_assembled_matrix() {
            if !reuse {
                let blocks = if self.use_blocks {
                    system.stiffness_blocks()
                } else {
                    None
                };
                self.assembled_last = false;
                match blocks {
                    Some(b) => self.assembler.assemble_blocks(
                        masses,
                        m_coef,
                        &b,
                        &self.triplets,
                        k_coef,
                    )?,
                    None => self
                        .assembler
                        .assemble(masses, m_coef, &self.triplets, k_coef)?,
                };
                self.assembled_last = true;
                keep_low_rank(&mut self.kept_low_rank, system.low_rank_terms());
                times.assembly_ms += ms_since(started);
            }
            let started = Instant::now();
            // A chord step solves with the whole earlier tangent: its low-rank terms too (the
            // system's may wait for `refresh_stiffness` after `residual_forces`).
            let low_rank = if reuse {
                self.kept_low_rank.as_slice()
            } else {
                system.low_rank_terms()
            };
            let mut problem = LinearProblem::assembled(
                self.assembler.matrix(),
                self.assembler.pattern_version(),
                m_coef,
                k_coef,
                low_rank,
            );
            let correction = SystemCorrection(system);
            if self.split {
                problem = problem.with_correction(&correction);
            }
            let solved = self.solver.solve(&problem, rhs, out);
            (solved, ms_since(started))
        } else {
            self.assembled_last = false;
            let stiffness = SystemStiffness(system);
            let low_rank = system.low_rank_terms();
            let problem = LinearProblem::matrix_free(m_coef, k_coef, masses, &stiffness, low_rank);
            let solved = self.solver.solve(&problem, rhs, out);
            (solved, ms_since(started))
        };
        if self.solver.factorizations() != factorizations {
            self.factored_mass_coefficient = Some(m_coef);
        }
        let factor_ms = (self.solver.factorization_seconds() - factor_before) * 1e3;
        times.factorization_ms += factor_ms;
        times.solve_ms += (result.1 - factor_ms).max(0.0);
        let result = result.0;
        if let Ok(info) = &result {
            self.last_preconditioner = info.preconditioner;
        }
        result
    }

    /// The sparse part of the last assembled matrix as a `sprs` matrix, when the last solve
    /// assembled one and it was the whole sparse part (not a split stiffness's
    /// preconditioning matrix, [`ForceSystem::set_stiffness_split`]).
    pub(crate) fn matrix(&self) -> Option<CsMat<f64>> {
        if self.assembled_last && !self.split {
            self.assembler.to_csmat().ok()
        } else {
            None
        }
    }

    /// How many times the sparse pattern (and with it the symbolic factorisation) was built.
    pub(crate) fn pattern_builds(&self) -> u64 {
        self.assembler.pattern_version()
    }
}

/// Copies `terms` into `kept`, re-using its buffers.
fn keep_low_rank(kept: &mut Vec<LowRankTerm>, terms: &[LowRankTerm]) {
    kept.resize_with(terms.len(), LowRankTerm::default);
    for (k, t) in kept.iter_mut().zip(terms) {
        k.coefficient = t.coefficient;
        k.vector.clear();
        k.vector.extend_from_slice(&t.vector);
    }
}
