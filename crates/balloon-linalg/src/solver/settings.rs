//! [`SolverSettings`]: everything needed to make the boxed solver of a [`LinearSolverKind`].

use serde::{Deserialize, Serialize};

use super::direct::{CholeskyParams, CholeskySolver};
use super::factorized::{FactorizedPcg, FactorizedPcgParams};
use super::matrix_free::MatrixFreeCg;
use super::params::{CgParams, LinearSolverKind, LinearSolverParams, PcgPreconditioner};
use super::pcg::AssembledPcg;
use super::problem::LinearSolver;

/// Everything [`SolverSettings::build`] needs to make the solver of a [`LinearSolverKind`]
/// (each field is used by the kinds that have it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SolverSettings {
    /// The kind and the CG tolerances.
    pub linear: LinearSolverParams,
    /// Preconditioner of [`LinearSolverKind::Pcg`].
    pub pcg_preconditioner: PcgPreconditioner,
    /// [`LinearSolverKind::FactorizedPcg`]: CG iterations above which the lagged factor is
    /// judged stale (see [`FactorizedPcgParams::refactor_iterations`]; default 8).
    pub refactor_iterations: usize,
    /// Run the numeric sparse Cholesky factorisation on the rayon pool (needs the `parallel`
    /// feature; otherwise ignored).
    pub parallel_factorization: bool,
    /// [`LinearSolverKind::FactorizedPcg`]: the cost of a factorisation in CG iterations for
    /// the amortised refresh (see [`FactorizedPcgParams::refactor_cost`]; default 0: off).
    pub refactor_cost: usize,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            linear: LinearSolverParams::default(),
            pcg_preconditioner: PcgPreconditioner::default(),
            refactor_iterations: FactorizedPcgParams::default().refactor_iterations,
            parallel_factorization: false,
            refactor_cost: 0,
        }
    }
}

impl SolverSettings {
    /// A new boxed solver of `self.linear.kind` with these settings.
    pub fn build(&self) -> Box<dyn LinearSolver> {
        let cg = CgParams::from(self.linear);
        match self.linear.kind {
            LinearSolverKind::MatrixFreeCg => Box::new(MatrixFreeCg::new(cg)),
            LinearSolverKind::Pcg => Box::new(AssembledPcg::new(cg, self.pcg_preconditioner)),
            LinearSolverKind::Cholesky => Box::new(CholeskySolver::new(CholeskyParams {
                relative_tolerance: self.linear.relative_tolerance,
                parallel: self.parallel_factorization,
                ..CholeskyParams::default()
            })),
            LinearSolverKind::FactorizedPcg => Box::new(FactorizedPcg::new(FactorizedPcgParams {
                cg,
                refactor_iterations: self.refactor_iterations,
                parallel: self.parallel_factorization,
                refactor_cost: self.refactor_cost,
                ..FactorizedPcgParams::default()
            })),
        }
    }
}
