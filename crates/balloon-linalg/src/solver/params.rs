//! What the solvers are chosen and tuned by: [`LinearSolverKind`] (the solver's name in a
//! configuration file or on a command line), [`PcgPreconditioner`], [`LinearSolverParams`] and
//! [`CgParams`].

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::SolveError;

/// Which linear solver Newton uses for `A dv = b` (Eq. 23).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinearSolverKind {
    /// Matrix-free CG on force differentials (the paper; `"matrix-free-cg"`) with a Jacobi
    /// preconditioner: `diag(A)` when the system implements
    /// `ForceSystem::add_stiffness_diagonal`, else the mass diagonal. Works with every
    /// `ForceSystem`.
    #[default]
    MatrixFreeCg,
    /// Jacobi-preconditioned CG on the assembled sparse matrix plus matrix-free low-rank terms
    /// (`"pcg"`). Needs `ForceSystem::add_stiffness_triplets`.
    Pcg,
    /// Sparse Cholesky (faer) plus Sherman-Morrison / Woodbury for the low-rank terms
    /// (`"cholesky"`). Needs `ForceSystem::add_stiffness_triplets`; the sparse part must be SPD.
    Cholesky,
    /// CG on the assembled matrix plus matrix-free low-rank terms, preconditioned by a sparse
    /// Cholesky factorisation of an *earlier* Newton matrix (`"factorized-pcg"`), kept across
    /// Newton iterations and steps and refreshed when CG needs more than
    /// [`crate::SolverSettings::refactor_iterations`] iterations (or fails); after such a slow
    /// solve the next six solves refactorise first (the matrix is changing fast). Needs
    /// `ForceSystem::add_stiffness_triplets` and an SPD sparse part: use it with the projected
    /// tangent (`TangentKind::Projected`); with the exact tangent an indefinite matrix makes the
    /// factorisation fail and the regularisation retries are costly.
    FactorizedPcg,
}

impl FromStr for LinearSolverKind {
    type Err = SolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "matrix-free-cg" => Ok(Self::MatrixFreeCg),
            "pcg" => Ok(Self::Pcg),
            "cholesky" => Ok(Self::Cholesky),
            "factorized-pcg" => Ok(Self::FactorizedPcg),
            _ => Err(SolveError::UnknownKind(s.to_string())),
        }
    }
}

impl std::fmt::Display for LinearSolverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::MatrixFreeCg => "matrix-free-cg",
            Self::Pcg => "pcg",
            Self::Cholesky => "cholesky",
            Self::FactorizedPcg => "factorized-pcg",
        })
    }
}

/// Preconditioner of the assembled PCG solver ([`LinearSolverKind::Pcg`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PcgPreconditioner {
    /// Jacobi, `diag(A)^-1` including the low-rank diagonal (`"jacobi"`, default).
    #[default]
    Jacobi,
    /// Zero-fill incomplete Cholesky of the sparse part ([`crate::IncompleteCholesky`], `"ic0"`); the
    /// low-rank terms are left to CG.
    IncompleteCholesky,
}

impl FromStr for PcgPreconditioner {
    type Err = SolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "jacobi" => Ok(Self::Jacobi),
            "ic0" | "incomplete-cholesky" => Ok(Self::IncompleteCholesky),
            _ => Err(SolveError::UnknownKind(format!(
                "{s} (preconditioner: expected \"jacobi\" or \"ic0\")"
            ))),
        }
    }
}

impl std::fmt::Display for PcgPreconditioner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Jacobi => "jacobi",
            Self::IncompleteCholesky => "ic0",
        })
    }
}

/// Parameters of the linear solve in each Newton iteration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LinearSolverParams {
    /// Which solver (default [`LinearSolverKind::MatrixFreeCg`], as the paper).
    pub kind: LinearSolverKind,
    /// Maximum CG iterations (default 500; ignored by Cholesky).
    pub max_iterations: usize,
    /// Stop CG when `||b - A x|| <= relative_tolerance * ||b||` (default `1e-8`; ignored by
    /// Cholesky, which reports its achieved residual).
    pub relative_tolerance: f64,
}

impl Default for LinearSolverParams {
    fn default() -> Self {
        Self {
            kind: LinearSolverKind::MatrixFreeCg,
            max_iterations: 500,
            relative_tolerance: 1e-8,
        }
    }
}

/// Parameters of every CG-based solver.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CgParams {
    /// Maximum CG iterations (default 500).
    pub max_iterations: usize,
    /// Stop when `||b - A x|| <= relative_tolerance * ||b||` (default `1e-8`).
    pub relative_tolerance: f64,
}

impl Default for CgParams {
    fn default() -> Self {
        let p = LinearSolverParams::default();
        Self {
            max_iterations: p.max_iterations,
            relative_tolerance: p.relative_tolerance,
        }
    }
}

impl From<LinearSolverParams> for CgParams {
    fn from(p: LinearSolverParams) -> Self {
        Self {
            max_iterations: p.max_iterations,
            relative_tolerance: p.relative_tolerance,
        }
    }
}
