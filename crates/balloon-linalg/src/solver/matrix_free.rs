//! [`MatrixFreeCg`]: CG on `A p` without assembling `A` (Wang et al. 2015, Eq. 23 solved as in the
//! paper).

use super::params::CgParams;
use super::problem::{LinearProblem, LinearSolver, ProblemForm};
use crate::error::SolveError;
use crate::info::{Preconditioner, SolveInfo};
use crate::krylov::{CgWorkspace, cg};
use crate::precond::jacobi;

/// Matrix-free conjugate gradients with a Jacobi preconditioner: `diag(A)` when the
/// [`super::StiffnessOperator`] offers the diagonal of `K` (plus the diagonal of the low-rank
/// terms) and it is positive, else the mass part `m_coef M` alone. Also accepts an assembled
/// problem (Jacobi on `diag(A)`, the identity if that is not positive).
#[derive(Clone, Debug, Default)]
pub struct MatrixFreeCg {
    params: CgParams,
    diag: Vec<f64>,
    workspace: CgWorkspace,
}

impl MatrixFreeCg {
    /// A solver with these parameters.
    pub fn new(params: CgParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// The parameters.
    pub fn params(&self) -> &CgParams {
        &self.params
    }

    /// Fills `self.diag` with the Jacobi diagonal of `problem` and says which it is.
    fn jacobi_diagonal(&mut self, problem: &LinearProblem<'_>) -> Preconditioner {
        let n = problem.dim();
        let (m_coef, k_coef) = (problem.m_coef, problem.k_coef);
        let diag = &mut self.diag;
        diag.clear();
        diag.resize(n, 0.0);
        match problem.form {
            ProblemForm::MatrixFree { masses, stiffness } => {
                let with_k = stiffness.add_diagonal(diag);
                for t in problem.low_rank.iter().filter(|_| with_k) {
                    for i in 0..n.min(t.vector.len()) {
                        diag[i] += t.coefficient * t.vector[i] * t.vector[i];
                    }
                }
                for i in 0..n {
                    diag[i] = m_coef * masses[i] + if with_k { k_coef * diag[i] } else { 0.0 };
                }
                if diag.iter().any(|d| d.is_nan() || *d <= 0.0) {
                    for i in 0..n {
                        diag[i] = m_coef * masses[i];
                    }
                    return Preconditioner::MassJacobi;
                }
                if with_k {
                    Preconditioner::DiagonalJacobi
                } else {
                    Preconditioner::MassJacobi
                }
            }
            ProblemForm::Assembled { matrix, .. } => {
                matrix.diagonal_into(diag);
                for t in problem.low_rank {
                    for i in 0..n.min(t.vector.len()) {
                        diag[i] += k_coef * t.coefficient * t.vector[i] * t.vector[i];
                    }
                }
                if diag.iter().any(|d| d.is_nan() || *d <= 0.0) {
                    diag.fill(1.0);
                    return Preconditioner::None;
                }
                Preconditioner::DiagonalJacobi
            }
        }
    }
}

impl LinearSolver for MatrixFreeCg {
    fn name(&self) -> &str {
        "matrix-free-cg"
    }

    fn set_relative_tolerance(&mut self, tolerance: f64) {
        self.params.relative_tolerance = tolerance;
    }

    fn needs_assembled_matrix(&self) -> bool {
        false
    }

    /// CG applies the whole problem; an assembled matrix only gives the Jacobi diagonal.
    fn accepts_correction(&self) -> bool {
        true
    }

    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError> {
        problem.check_dimensions(b, x)?;
        let preconditioner = self.jacobi_diagonal(problem);
        let diag = &self.diag;
        let mut info = cg(
            |p, out| problem.apply(p, out),
            |r, z| jacobi(diag, r, z),
            b,
            x,
            self.params.max_iterations,
            self.params.relative_tolerance,
            &mut self.workspace,
        )?;
        info.preconditioner = preconditioner;
        Ok(info)
    }
}
