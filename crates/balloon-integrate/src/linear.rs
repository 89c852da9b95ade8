//! Linear solvers behind Newton's method (seed 000, Eq. 23 is solved by CG in the paper).
//!
//! Three run-time choices ([`LinearSolverKind`]):
//!
//! * matrix-free conjugate gradients on `A p` built from force differentials (the paper), with a
//!   Jacobi preconditioner from the mass diagonal, or from `diag(A)` when the system offers the
//!   diagonal of its stiffness;
//! * preconditioned CG on an assembled sparse matrix ([`CsrMatrix`], built by a
//!   [`SparseAssembler`] that re-uses its pattern), the dense low-rank terms applied matrix-free
//!   inside the mat-vec;
//! * sparse Cholesky (faer, symbolic factorisation cached in [`SparseCholesky`]) on the sparse part,
//!   with the low-rank terms handled exactly by Sherman-Morrison / Woodbury
//!   ([`solve_with_low_rank`]).
//!
//! The generic pieces ([`cg`], [`CsrMatrix`], [`SparseAssembler`], [`solve_with_low_rank`]) are
//! public so other solvers can reuse them.

use std::str::FromStr;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

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
    /// `BackwardEulerParams::refactor_iterations` iterations (or fails); after such a slow
    /// solve the next six solves refactorise first (the matrix is changing fast). Needs
    /// `ForceSystem::add_stiffness_triplets` and an SPD sparse part: use it with the projected
    /// tangent (`TangentKind::Projected`); with the exact tangent an indefinite matrix makes the
    /// factorisation fail and the regularisation retries are costly.
    FactorizedPcg,
}

impl FromStr for LinearSolverKind {
    type Err = LinearSolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "matrix-free-cg" => Ok(Self::MatrixFreeCg),
            "pcg" => Ok(Self::Pcg),
            "cholesky" => Ok(Self::Cholesky),
            "factorized-pcg" => Ok(Self::FactorizedPcg),
            _ => Err(LinearSolveError::UnknownKind(s.to_string())),
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
    /// Zero-fill incomplete Cholesky of the sparse part ([`IncompleteCholesky`], `"ic0"`); the
    /// low-rank terms are left to CG.
    IncompleteCholesky,
}

impl FromStr for PcgPreconditioner {
    type Err = LinearSolveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "jacobi" => Ok(Self::Jacobi),
            "ic0" | "incomplete-cholesky" => Ok(Self::IncompleteCholesky),
            _ => Err(LinearSolveError::UnknownKind(format!(
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

/// Errors of the linear solvers.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LinearSolveError {
    /// CG met a search direction `p` with `p^T A p <= 0`: the matrix is not positive definite
    /// (e.g. a compressed, buckling state with the follower term on, or a negative time step).
    /// Use a smaller time step, turn off the follower term, or use a direct solver.
    #[error(
        "CG breakdown at iteration {iteration}: non-positive curvature p^T A p = {curvature:e} (|p|^2 = {direction_norm_squared:e}); the system matrix is not positive definite"
    )]
    NonPositiveCurvature {
        /// CG iteration (0-based).
        iteration: usize,
        /// The value of `p^T A p`.
        curvature: f64,
        /// `|p|^2`, for scale.
        direction_norm_squared: f64,
    },
    /// The sparse Cholesky factorisation failed: the sparse part of the matrix is not positive
    /// definite (pivot index given when known). Use PCG or the matrix-free solver.
    #[error("sparse Cholesky factorisation failed: {detail}")]
    Factorization {
        /// What faer reported, with the pivot when known.
        detail: String,
    },
    /// The small Woodbury capacitance matrix `I + C U^T A^-1 U` is singular.
    #[error("Woodbury capacitance matrix of the low-rank terms ({rank}x{rank}) is singular")]
    SingularCapacitance {
        /// Number of low-rank terms.
        rank: usize,
    },
    /// A NaN or infinity appeared in the solve (the right-hand side or matrix is not finite).
    #[error("non-finite value in the linear solve at iteration {iteration}")]
    NonFinite {
        /// Iteration at which it was detected.
        iteration: usize,
    },
    /// Vector or matrix sizes disagree.
    #[error("dimension mismatch: {what} has length {len}, expected {expected}")]
    Dimension {
        /// Which array.
        what: &'static str,
        /// Its length.
        len: usize,
        /// Expected length.
        expected: usize,
    },
    /// A triplet refers to a row or column outside the matrix.
    #[error("stiffness triplet ({row}, {col}) is outside the {n}x{n} matrix")]
    TripletOutOfRange {
        /// Row index.
        row: usize,
        /// Column index.
        col: usize,
        /// Matrix size.
        n: usize,
    },
    /// The solver name could not be parsed.
    #[error(
        "unknown linear solver `{0}`; expected one of \"matrix-free-cg\", \"pcg\", \"cholesky\", \"factorized-pcg\""
    )]
    UnknownKind(String),
}

/// What a linear solve achieved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LinearSolveInfo {
    /// Iterations used (CG), or 1 for a direct solve.
    pub iterations: usize,
    /// Final `||b - A x|| / ||b||` (0 when `b = 0`).
    pub relative_residual: f64,
    /// Whether the requested tolerance was met.
    pub converged: bool,
}

/// Scratch vectors of [`cg`], reused across calls.
#[derive(Clone, Debug, Default)]
pub struct CgWorkspace {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Preconditioned conjugate gradients for a symmetric positive definite operator.
///
/// * `apply(p, out)` writes `out = A p` (overwrite),
/// * `precondition(r, z)` writes `z = P^-1 r` (overwrite; the identity is `z.copy_from_slice(r)`),
/// * `x` holds the initial guess on entry and the solution on exit.
///
/// Stops when `||b - A x|| <= relative_tolerance ||b||` or after `max_iterations`; in the latter
/// case `converged` is `false` (not an error). Errors on non-positive curvature or non-finite
/// values.
pub fn cg(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    max_iterations: usize,
    relative_tolerance: f64,
    ws: &mut CgWorkspace,
) -> Result<LinearSolveInfo, LinearSolveError> {
    let n = b.len();
    if x.len() != n {
        return Err(LinearSolveError::Dimension {
            what: "x",
            len: x.len(),
            expected: n,
        });
    }
    for v in [&mut ws.r, &mut ws.z, &mut ws.p, &mut ws.ap] {
        v.resize(n, 0.0);
    }
    let bnorm = dot(b, b).sqrt();
    if !bnorm.is_finite() {
        return Err(LinearSolveError::NonFinite { iteration: 0 });
    }
    if bnorm == 0.0 {
        x.fill(0.0);
        return Ok(LinearSolveInfo {
            iterations: 0,
            relative_residual: 0.0,
            converged: true,
        });
    }
    apply(x, &mut ws.ap);
    for i in 0..n {
        ws.r[i] = b[i] - ws.ap[i];
    }
    let target = relative_tolerance * bnorm;
    let mut rnorm = dot(&ws.r, &ws.r).sqrt();
    if rnorm <= target {
        return Ok(LinearSolveInfo {
            iterations: 0,
            relative_residual: rnorm / bnorm,
            converged: true,
        });
    }
    precondition(&ws.r, &mut ws.z);
    ws.p.copy_from_slice(&ws.z);
    let mut rz = dot(&ws.r, &ws.z);
    for it in 0..max_iterations {
        apply(&ws.p, &mut ws.ap);
        let curvature = dot(&ws.p, &ws.ap);
        if !curvature.is_finite() {
            return Err(LinearSolveError::NonFinite { iteration: it });
        }
        if curvature <= 0.0 {
            return Err(LinearSolveError::NonPositiveCurvature {
                iteration: it,
                curvature,
                direction_norm_squared: dot(&ws.p, &ws.p),
            });
        }
        let alpha = rz / curvature;
        for i in 0..n {
            x[i] += alpha * ws.p[i];
            ws.r[i] -= alpha * ws.ap[i];
        }
        rnorm = dot(&ws.r, &ws.r).sqrt();
        if !rnorm.is_finite() {
            return Err(LinearSolveError::NonFinite { iteration: it });
        }
        if rnorm <= target {
            return Ok(LinearSolveInfo {
                iterations: it + 1,
                relative_residual: rnorm / bnorm,
                converged: true,
            });
        }
        precondition(&ws.r, &mut ws.z);
        let rz_new = dot(&ws.r, &ws.z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            ws.p[i] = ws.z[i] + beta * ws.p[i];
        }
    }
    Ok(LinearSolveInfo {
        iterations: max_iterations,
        relative_residual: rnorm / bnorm,
        converged: false,
    })
}

/// A square sparse matrix in compressed sparse row form with sorted, unique column indices per
/// row. For the symmetric matrices used here it is also the CSC form of the same matrix.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CsrMatrix {
    /// Number of rows (= columns).
    pub n: usize,
    /// Row pointers, length `n + 1`.
    pub row_ptr: Vec<usize>,
    /// Column index of each stored entry.
    pub col_idx: Vec<usize>,
    /// Value of each stored entry.
    pub values: Vec<f64>,
}

impl CsrMatrix {
    /// `out = self * x` (overwrite).
    pub fn mul_into(&self, x: &[f64], out: &mut [f64]) {
        for r in 0..self.n {
            let mut s = 0.0;
            for k in self.row_ptr[r]..self.row_ptr[r + 1] {
                s += self.values[k] * x[self.col_idx[k]];
            }
            out[r] = s;
        }
    }

    /// The diagonal entries (0 where none is stored) into `out` (length `n`).
    pub fn diagonal_into(&self, out: &mut [f64]) {
        for r in 0..self.n {
            out[r] = 0.0;
            for k in self.row_ptr[r]..self.row_ptr[r + 1] {
                if self.col_idx[k] == r {
                    out[r] = self.values[k];
                }
            }
        }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Checks the structure: `row_ptr` of length `n + 1`, non-decreasing, ending at the number
    /// of entries; column indices in range and strictly increasing within each row.
    pub fn check(&self) -> Result<(), LinearSolveError> {
        let n = self.n;
        let bad = |what: &'static str, len: usize, expected: usize| {
            Err(LinearSolveError::Dimension {
                what,
                len,
                expected,
            })
        };
        if self.row_ptr.len() != n + 1 {
            return bad("row_ptr", self.row_ptr.len(), n + 1);
        }
        let nnz = self.row_ptr[n];
        if self.col_idx.len() != nnz {
            return bad("col_idx", self.col_idx.len(), nnz);
        }
        if self.values.len() != nnz {
            return bad("values", self.values.len(), nnz);
        }
        for r in 0..n {
            let (a, b) = (self.row_ptr[r], self.row_ptr[r + 1]);
            if a > b || b > nnz {
                return bad("row_ptr (non-monotone)", b, a);
            }
            for k in a..b {
                let c = self.col_idx[k];
                if c >= n || (k > a && c <= self.col_idx[k - 1]) {
                    return Err(LinearSolveError::TripletOutOfRange { row: r, col: c, n });
                }
            }
        }
        Ok(())
    }
}

/// Builds `A = diag_scale * diag(d) + scale * sum(triplets)` as a [`CsrMatrix`], caching the
/// sparsity pattern: when the `(row, col)` sequence of the triplets is the same as last time
/// (the usual case across Newton iterations and steps), only the values are scattered.
#[derive(Clone, Debug, Default)]
pub struct SparseAssembler {
    /// Nodes of the blocks the pattern was last built from by [`SparseAssembler::assemble_blocks`]
    /// (with `block_k` nodes per block; 0 when built from triplets).
    block_nodes: Vec<usize>,
    block_k: usize,
    keys: Vec<(usize, usize)>,
    slots: Vec<usize>,
    diag_slots: Vec<usize>,
    matrix: CsrMatrix,
    pattern_version: u64,
}

impl SparseAssembler {
    /// An empty assembler.
    pub fn new() -> Self {
        Self::default()
    }

    /// The last assembled matrix.
    pub fn matrix(&self) -> &CsrMatrix {
        &self.matrix
    }

    /// A counter that changes whenever the pattern is rebuilt (to invalidate symbolic
    /// factorisations).
    pub fn pattern_version(&self) -> u64 {
        self.pattern_version
    }

    /// Assembles `diag_scale * diag(diagonal) + scale * sum(triplets)` (duplicates summed; the
    /// full diagonal is always in the pattern). Returns whether the pattern was rebuilt.
    pub fn assemble(
        &mut self,
        diagonal: &[f64],
        diag_scale: f64,
        triplets: &[(usize, usize, f64)],
        scale: f64,
    ) -> Result<bool, LinearSolveError> {
        let n = diagonal.len();
        let same = self.matrix.n == n
            && self.keys.len() == triplets.len()
            && self
                .keys
                .iter()
                .zip(triplets)
                .all(|(k, t)| k.0 == t.0 && k.1 == t.1);
        if !same {
            self.rebuild_pattern(n, triplets)?;
            self.block_k = 0;
            self.block_nodes.clear();
        }
        let m = &mut self.matrix;
        m.values.fill(0.0);
        for (t, &s) in triplets.iter().zip(&self.slots) {
            m.values[s] += scale * t.2;
        }
        for (i, &s) in self.diag_slots.iter().enumerate() {
            m.values[s] += diag_scale * diagonal[i];
        }
        Ok(!same)
    }

    /// Assembles `diag_scale * diag(diagonal) + scale * (sum of the blocks + sum(extra))`, the
    /// block form of [`SparseAssembler::assemble`] ([`crate::system::StiffnessBlocks`]): the
    /// pattern check compares only the block node lists and the `extra` keys, and the values are
    /// scattered straight from the blocks (no triplet list). Returns whether the pattern was
    /// rebuilt; the matrix equals the one `assemble` builds from the equivalent triplets.
    pub fn assemble_blocks(
        &mut self,
        diagonal: &[f64],
        diag_scale: f64,
        blocks: &crate::system::StiffnessBlocks<'_>,
        extra: &[(usize, usize, f64)],
        scale: f64,
    ) -> Result<bool, LinearSolveError> {
        let n = diagonal.len();
        let k = blocks.nodes_per_block;
        let bs = 9 * k * k;
        if k == 0
            || !blocks.nodes.len().is_multiple_of(k)
            || blocks.values.len() != blocks.nodes.len() / k * bs
        {
            return Err(LinearSolveError::Dimension {
                what: "stiffness block values",
                len: blocks.values.len(),
                expected: blocks.nodes.len() / k.max(1) * bs,
            });
        }
        let nb = blocks.values.len();
        let same = self.matrix.n == n
            && self.block_k == k
            && self.block_nodes == blocks.nodes
            && self.keys.len() == nb + extra.len()
            && self.keys[nb..]
                .iter()
                .zip(extra)
                .all(|(k, t)| k.0 == t.0 && k.1 == t.1);
        if !same {
            let d = 3 * k;
            let mut keys = Vec::with_capacity(nb + extra.len());
            for nodes in blocks.nodes.chunks_exact(k) {
                for j in 0..d {
                    for i in 0..d {
                        keys.push((3 * nodes[i / 3] + i % 3, 3 * nodes[j / 3] + j % 3, 0.0));
                    }
                }
            }
            keys.extend_from_slice(extra);
            self.rebuild_pattern(n, &keys)?;
            self.block_k = k;
            self.block_nodes.clear();
            self.block_nodes.extend_from_slice(blocks.nodes);
        }
        let m = &mut self.matrix;
        m.values.fill(0.0);
        for (v, &s) in blocks.values.iter().zip(&self.slots[..nb]) {
            m.values[s] += scale * v;
        }
        for (t, &s) in extra.iter().zip(&self.slots[nb..]) {
            m.values[s] += scale * t.2;
        }
        for (i, &s) in self.diag_slots.iter().enumerate() {
            m.values[s] += diag_scale * diagonal[i];
        }
        Ok(!same)
    }

    fn rebuild_pattern(
        &mut self,
        n: usize,
        triplets: &[(usize, usize, f64)],
    ) -> Result<(), LinearSolveError> {
        for t in triplets {
            if t.0 >= n || t.1 >= n {
                return Err(LinearSolveError::TripletOutOfRange {
                    row: t.0,
                    col: t.1,
                    n,
                });
            }
        }
        // Entries: triplets first, then one diagonal entry per row.
        let total = triplets.len() + n;
        let key = |e: usize| {
            if e < triplets.len() {
                (triplets[e].0, triplets[e].1)
            } else {
                (e - triplets.len(), e - triplets.len())
            }
        };
        let mut order: Vec<usize> = (0..total).collect();
        order.sort_unstable_by_key(|&e| key(e));
        let mut entry_slot = vec![0usize; total];
        let mut row_ptr = vec![0usize; n + 1];
        let mut col_idx = Vec::with_capacity(total);
        let mut last: Option<(usize, usize)> = None;
        for &e in &order {
            let k = key(e);
            if last != Some(k) {
                col_idx.push(k.1);
                row_ptr[k.0 + 1] += 1;
                last = Some(k);
            }
            entry_slot[e] = col_idx.len() - 1;
        }
        for r in 0..n {
            row_ptr[r + 1] += row_ptr[r];
        }
        self.slots = entry_slot[..triplets.len()].to_vec();
        self.diag_slots = entry_slot[triplets.len()..].to_vec();
        self.keys = triplets.iter().map(|t| (t.0, t.1)).collect();
        self.matrix = CsrMatrix {
            n,
            row_ptr,
            values: vec![0.0; col_idx.len()],
            col_idx,
        };
        self.pattern_version += 1;
        Ok(())
    }
}

/// Zero-fill incomplete Cholesky `A ~ L L^T` (IC(0)): `L` keeps exactly the lower-triangle
/// pattern of `A`. A preconditioner for [`cg`] on assembled matrices; exact (one CG iteration)
/// when the Cholesky factor has no fill, e.g. for tridiagonal matrices. When a pivot is not
/// positive the factorisation is retried on `A + shift diag(A)` with growing shifts
/// (Manteuffel's shifted IC); see [`IncompleteCholesky::shift`].
#[derive(Clone, Debug, Default)]
pub struct IncompleteCholesky {
    n: usize,
    row_ptr: Vec<usize>,
    col_idx: Vec<usize>,
    /// Position in `CsrMatrix::values` of each stored entry of `L`.
    source: Vec<usize>,
    values: Vec<f64>,
    pattern_version: Option<u64>,
    shift: f64,
}

impl IncompleteCholesky {
    /// An empty factorisation.
    pub fn new() -> Self {
        Self::default()
    }

    /// The diagonal shift used by the last factorisation (0 when none was needed).
    pub fn shift(&self) -> f64 {
        self.shift
    }

    /// Computes IC(0) of the symmetric matrix `a` (both triangles stored). The lower pattern is
    /// rebuilt only when `pattern_version` changes. Errors if no shift up to `1e3` gives positive
    /// pivots (the matrix is then far from positive definite).
    pub fn factorize(
        &mut self,
        a: &CsrMatrix,
        pattern_version: u64,
    ) -> Result<(), LinearSolveError> {
        a.check()?;
        if self.pattern_version != Some(pattern_version) || self.n != a.n {
            self.n = a.n;
            self.row_ptr.clear();
            self.col_idx.clear();
            self.source.clear();
            self.row_ptr.push(0);
            for r in 0..a.n {
                let mut has_diag = false;
                for k in a.row_ptr[r]..a.row_ptr[r + 1] {
                    let c = a.col_idx[k];
                    if c <= r {
                        self.col_idx.push(c);
                        self.source.push(k);
                        has_diag |= c == r;
                    }
                }
                if !has_diag {
                    return Err(LinearSolveError::Factorization {
                        detail: format!("IC(0): row {r} has no diagonal entry"),
                    });
                }
                self.row_ptr.push(self.col_idx.len());
            }
            self.values.resize(self.col_idx.len(), 0.0);
            self.pattern_version = Some(pattern_version);
        }
        let mut shift = 0.0;
        loop {
            match self.try_factorize(a, shift) {
                Ok(()) => {
                    self.shift = shift;
                    return Ok(());
                }
                Err(row) => {
                    shift = if shift == 0.0 { 1e-3 } else { shift * 10.0 };
                    if shift > 1e3 {
                        return Err(LinearSolveError::Factorization {
                            detail: format!(
                                "IC(0): non-positive pivot at row {row} even with diagonal shift {:e}",
                                shift / 10.0
                            ),
                        });
                    }
                }
            }
        }
    }

    /// One IC(0) attempt on `A + shift diag(A)`; `Err(row)` on a non-positive pivot.
    fn try_factorize(&mut self, a: &CsrMatrix, shift: f64) -> Result<(), usize> {
        for (v, &k) in self.values.iter_mut().zip(&self.source) {
            *v = a.values[k];
        }
        for i in 0..self.n {
            let (si, ei) = (self.row_ptr[i], self.row_ptr[i + 1]);
            for p in si..ei {
                let k = self.col_idx[p];
                // sum_{j < k} L[i, j] L[k, j] over the common pattern (sorted merge).
                let (sk, ek) = (self.row_ptr[k], self.row_ptr[k + 1]);
                let (mut a_i, mut a_k, mut sum) = (si, sk, 0.0);
                while a_i < p && a_k < ek - 1 {
                    let (ci, ck) = (self.col_idx[a_i], self.col_idx[a_k]);
                    match ci.cmp(&ck) {
                        std::cmp::Ordering::Less => a_i += 1,
                        std::cmp::Ordering::Greater => a_k += 1,
                        std::cmp::Ordering::Equal => {
                            sum += self.values[a_i] * self.values[a_k];
                            a_i += 1;
                            a_k += 1;
                        }
                    }
                }
                if k < i {
                    // The diagonal of row k is its last entry.
                    self.values[p] = (self.values[p] - sum) / self.values[ek - 1];
                } else {
                    let d = self.values[p] * (1.0 + shift) - sum;
                    if d.is_nan() || d <= 0.0 {
                        return Err(i);
                    }
                    self.values[p] = d.sqrt();
                }
            }
        }
        Ok(())
    }

    /// `z = (L L^T)^-1 r` (forward then backward substitution).
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.copy_from_slice(r);
        for i in 0..self.n {
            let (s, e) = (self.row_ptr[i], self.row_ptr[i + 1]);
            let mut acc = z[i];
            for p in s..e - 1 {
                acc -= self.values[p] * z[self.col_idx[p]];
            }
            z[i] = acc / self.values[e - 1];
        }
        for i in (0..self.n).rev() {
            let (s, e) = (self.row_ptr[i], self.row_ptr[i + 1]);
            z[i] /= self.values[e - 1];
            let zi = z[i];
            for p in s..e - 1 {
                z[self.col_idx[p]] -= self.values[p] * zi;
            }
        }
    }
}

/// Sparse `L L^T` factorisation (faer, supernodal or simplicial as faer's symbolic analysis
/// chooses, AMD ordering) whose symbolic analysis, factor storage and workspace are cached and
/// rebuilt only when the pattern version changes. Runs sequentially (`Par::Seq`): the matrices
/// of one balloon are small enough that thread start-up costs more than it saves on 2 cores.
#[derive(Default)]
pub struct SparseCholesky {
    symbolic: Option<(u64, SymbolicCholesky<usize>)>,
    values: Vec<f64>,
    workspace: Option<MemBuffer>,
    factorized: bool,
    n: usize,
    parallel: bool,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("n", &self.n)
            .field("pattern_version", &self.symbolic.as_ref().map(|(v, _)| *v))
            .field("factor_entries", &self.values.len())
            .field("factorized", &self.factorized)
            .finish()
    }
}

impl SparseCholesky {
    /// An empty factorisation.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether a symbolic factorisation is cached for `pattern_version`.
    pub fn has_symbolic_for(&self, pattern_version: u64) -> bool {
        matches!(&self.symbolic, Some((v, _)) if *v == pattern_version)
    }

    /// Factorises the symmetric matrix `a` (both triangles stored), re-using the symbolic
    /// factorisation when `pattern_version` matches the cached one. Errors (never panics) on an
    /// inconsistent [`CsrMatrix`] or a matrix that is not positive definite.
    pub fn factorize(
        &mut self,
        a: &CsrMatrix,
        pattern_version: u64,
    ) -> Result<(), LinearSolveError> {
        a.check()?;
        self.factorized = false;
        // CSR of a symmetric matrix read as CSC: column r holds row indices col_idx.
        let sym = SymbolicSparseColMatRef::new_checked(a.n, a.n, &a.row_ptr, None, &a.col_idx);
        if !self.has_symbolic_for(pattern_version) {
            let s = factorize_symbolic_cholesky(
                sym,
                Side::Lower,
                SymmetricOrdering::Amd,
                Default::default(),
            )
            .map_err(|e| LinearSolveError::Factorization {
                detail: format!("symbolic analysis failed: {e:?}"),
            })?;
            let req = s
                .factorize_numeric_llt_scratch::<f64>(Par::rayon(0), Default::default())
                .or(s.solve_in_place_scratch::<f64>(1, Par::rayon(0)));
            self.workspace =
                Some(
                    MemBuffer::try_new(req).map_err(|_| LinearSolveError::Factorization {
                        detail: "out of memory for the Cholesky workspace".into(),
                    })?,
                );
            self.values.clear();
            self.values.resize(s.len_val(), 0.0);
            self.symbolic = Some((pattern_version, s));
        }
        let par = self.par();
        let (Some((_, symbolic)), Some(work)) = (&self.symbolic, &mut self.workspace) else {
            return Err(LinearSolveError::Factorization {
                detail: "no symbolic factorisation".into(),
            });
        };
        let mat = SparseColMatRef::new(sym, &a.values);
        symbolic
            .factorize_numeric_llt(
                &mut self.values,
                mat,
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(work),
                Default::default(),
            )
            .map_err(|e| LinearSolveError::Factorization {
                detail: format!(
                    "matrix ({n}x{n}, {nnz} entries) is not positive definite: {e:?}",
                    n = a.n,
                    nnz = a.nnz()
                ),
            })?;
        self.factorized = true;
        self.n = a.n;
        Ok(())
    }

    /// Runs the numeric factorisation on the rayon thread pool (`true`) or on the calling
    /// thread (`false`, the default).
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
    }

    fn par(&self) -> Par {
        if self.parallel {
            Par::rayon(0)
        } else {
            Par::Seq
        }
    }

    /// Whether the last [`SparseCholesky::factorize`] succeeded (a factor is available).
    pub fn is_factorized(&self) -> bool {
        self.factorized
    }

    /// Forgets the numeric factor (keeps the symbolic analysis): the next solve needs a new
    /// [`SparseCholesky::factorize`].
    pub fn invalidate(&mut self) {
        self.factorized = false;
    }

    /// Solves `A x = rhs` in place with the last factorisation.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), LinearSolveError> {
        let (true, Some((_, symbolic)), Some(work)) =
            (self.factorized, &self.symbolic, &mut self.workspace)
        else {
            return Err(LinearSolveError::Factorization {
                detail: "solve called before a successful factorisation".into(),
            });
        };
        if rhs.len() != self.n {
            return Err(LinearSolveError::Dimension {
                what: "rhs",
                len: rhs.len(),
                expected: self.n,
            });
        }
        let n = rhs.len();
        let m = faer::MatMut::from_column_major_slice_mut(rhs, n, 1);
        LltRef::new(symbolic, &self.values).solve_in_place_with_conj(
            faer::Conj::No,
            m,
            Par::Seq,
            MemStack::new(work),
        );
        Ok(())
    }
}

/// Solves `(A + sum_i c_i u_i u_i^T) x = b` given a solver for `A` (`solve_a` overwrites its
/// argument with `A^-1` of it), by Sherman-Morrison (one term) / Woodbury (several):
/// `x = y - Z (I + C U^T Z)^-1 C U^T y` with `y = A^-1 b`, `Z = A^-1 U`, `C = diag(c_i)`.
/// For one term this is `x = y - c z (u^T y) / (1 + c u^T z)`.
///
/// `terms` are `(c_i, u_i)` pairs; terms with `c_i = 0` are skipped. `z_scratch` is reused.
pub fn solve_with_low_rank(
    mut solve_a: impl FnMut(&mut [f64]) -> Result<(), LinearSolveError>,
    terms: &[(f64, &[f64])],
    b: &[f64],
    x: &mut [f64],
    z_scratch: &mut Vec<Vec<f64>>,
) -> Result<(), LinearSolveError> {
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
            return Err(LinearSolveError::Dimension {
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
        .ok_or(LinearSolveError::SingularCapacitance { rank: r })?;
    for (j, z) in z_scratch.iter().take(r).enumerate() {
        for i in 0..n {
            x[i] -= coef[j] * z[i];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_test_support::Rng;

    /// A random sparse SPD matrix (banded, diagonally dominant) as triplets.
    fn spd_triplets(n: usize, seed: u64) -> Vec<(usize, usize, f64)> {
        let mut rng = Rng::new(seed);
        let mut t = Vec::new();
        for i in 0..n {
            t.push((i, i, 4.0 + rng.next_f64()));
            for d in [1usize, 3] {
                if i + d < n {
                    let v = 0.9 * rng.next_f64();
                    t.push((i, i + d, v));
                    t.push((i + d, i, v));
                }
            }
        }
        t
    }

    fn dense(n: usize, t: &[(usize, usize, f64)]) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(n, n);
        for &(r, c, v) in t {
            a[(r, c)] += v;
        }
        a
    }

    #[test]
    fn assembler_sums_duplicates_and_reuses_pattern() {
        let n = 12;
        let mut t = spd_triplets(n, 3);
        t.push((2, 5, 0.25));
        t.push((2, 5, 0.5));
        let d = vec![2.0; n];
        let mut asm = SparseAssembler::new();
        assert!(asm.assemble(&d, 0.5, &t, 2.0).unwrap());
        let v0 = asm.pattern_version();
        let expected = dense(n, &t) * 2.0 + DMatrix::identity(n, n);
        let x = DVector::from_vec(Rng::new(1).vector(n));
        let mut y = vec![0.0; n];
        asm.matrix().mul_into(x.as_slice(), &mut y);
        let y_ref = &expected * &x;
        for i in 0..n {
            assert!((y[i] - y_ref[i]).abs() < 1e-12);
        }
        // Same pattern, new values: no rebuild.
        for e in &mut t {
            e.2 *= 3.0;
        }
        assert!(!asm.assemble(&d, 0.5, &t, 2.0).unwrap());
        assert_eq!(asm.pattern_version(), v0);
        let err = asm.assemble(&d, 1.0, &[(0, 99, 1.0)], 1.0).unwrap_err();
        assert!(err.to_string().contains("(0, 99)"));
    }

    #[test]
    fn block_assembly_equals_triplet_assembly() {
        // Three "triangles" on 5 nodes (shared nodes, so couplings are summed) plus extras.
        let nodes = [0usize, 1, 2, 2, 3, 4, 4, 0, 2];
        let mut rng = Rng::new(12);
        let values = rng.vector(3 * 81);
        let extra = vec![(0, 14, 0.5), (14, 0, 0.5), (7, 7, -0.25)];
        let mut triplets = Vec::new();
        for (e, tri) in nodes.chunks(3).enumerate() {
            for j in 0..9 {
                for i in 0..9 {
                    let v = values[81 * e + 9 * j + i];
                    triplets.push((3 * tri[i / 3] + i % 3, 3 * tri[j / 3] + j % 3, v));
                }
            }
        }
        triplets.extend_from_slice(&extra);
        let n = 15;
        let d = rng.vector(n);
        let mut reference = SparseAssembler::new();
        reference.assemble(&d, 0.7, &triplets, 1.3).unwrap();
        let blocks = crate::system::StiffnessBlocks {
            nodes_per_block: 3,
            nodes: &nodes,
            values: &values,
        };
        let mut asm = SparseAssembler::new();
        assert!(asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap());
        assert_eq!(asm.matrix().row_ptr, reference.matrix().row_ptr);
        assert_eq!(asm.matrix().col_idx, reference.matrix().col_idx);
        for (a, b) in asm.matrix().values.iter().zip(&reference.matrix().values) {
            assert!((a - b).abs() <= 1e-14 * (1.0 + b.abs()));
        }
        // Same nodes and extra keys: the pattern is kept; new values are scattered.
        let v0 = asm.pattern_version();
        let doubled: Vec<f64> = values.iter().map(|v| 2.0 * v).collect();
        let blocks2 = crate::system::StiffnessBlocks {
            values: &doubled,
            ..blocks
        };
        assert!(!asm.assemble_blocks(&d, 0.7, &blocks2, &extra, 1.3).unwrap());
        assert_eq!(asm.pattern_version(), v0);
        // Switching to the triplet path with the same keys keeps the pattern too, and back.
        assert!(!asm.assemble(&d, 0.7, &triplets, 1.3).unwrap());
        assert_eq!(asm.matrix(), reference.matrix());
        assert!(!asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap());
        assert_eq!(asm.pattern_version(), v0);
        // Other nodes: rebuilt. Wrong sizes: an error, not a panic.
        let other = [0usize, 1, 3, 2, 3, 4, 4, 0, 2];
        let blocks3 = crate::system::StiffnessBlocks {
            nodes: &other,
            ..blocks
        };
        assert!(asm.assemble_blocks(&d, 0.7, &blocks3, &extra, 1.3).unwrap());
        let short = crate::system::StiffnessBlocks {
            values: &values[..100],
            ..blocks
        };
        assert!(asm.assemble_blocks(&d, 0.7, &short, &extra, 1.3).is_err());
        let out = crate::system::StiffnessBlocks {
            nodes: &[0, 1, 99, 2, 3, 4, 4, 0, 2],
            ..blocks
        };
        assert!(asm.assemble_blocks(&d, 0.7, &out, &extra, 1.3).is_err());
    }

    #[test]
    fn cg_solves_spd_system_and_reports_non_convergence() {
        let n = 40;
        let t = spd_triplets(n, 7);
        let mut asm = SparseAssembler::new();
        asm.assemble(&vec![0.0; n], 0.0, &t, 1.0).unwrap();
        let a = asm.matrix().clone();
        let b = Rng::new(2).vector(n);
        let mut x = vec![0.0; n];
        let mut ws = CgWorkspace::default();
        let info = cg(
            |p, o| a.mul_into(p, o),
            |r, z| z.copy_from_slice(r),
            &b,
            &mut x,
            200,
            1e-12,
            &mut ws,
        )
        .unwrap();
        assert!(info.converged && info.relative_residual <= 1e-12);
        let x_ref = dense(n, &t)
            .lu()
            .solve(&DVector::from_column_slice(&b))
            .unwrap();
        for i in 0..n {
            assert!((x[i] - x_ref[i]).abs() < 1e-9);
        }
        // Two iterations cannot solve a 40-dof system with a spread spectrum to 1e-12.
        let mut x = vec![0.0; n];
        let info = cg(
            |p, o| a.mul_into(p, o),
            |r, z| z.copy_from_slice(r),
            &b,
            &mut x,
            2,
            1e-12,
            &mut ws,
        )
        .unwrap();
        assert!(!info.converged);
        assert_eq!(info.iterations, 2);
        assert!(info.relative_residual > 1e-12);
        // An indefinite operator is reported as a breakdown with its curvature.
        let mut x = vec![0.0; 2];
        let err = cg(
            |p, o| {
                o[0] = p[0];
                o[1] = -p[1];
            },
            |r, z| z.copy_from_slice(r),
            &[0.1, 1.0],
            &mut x,
            10,
            1e-12,
            &mut ws,
        )
        .unwrap_err();
        assert!(
            matches!(err, LinearSolveError::NonPositiveCurvature { curvature, .. } if curvature < 0.0)
        );
    }

    #[test]
    fn cholesky_with_sherman_morrison_and_woodbury_matches_dense_solve() {
        let n = 30;
        let t = spd_triplets(n, 11);
        let mut asm = SparseAssembler::new();
        asm.assemble(&vec![1.0; n], 0.5, &t, 1.0).unwrap();
        let mut chol = SparseCholesky::new();
        chol.factorize(asm.matrix(), asm.pattern_version()).unwrap();
        assert!(chol.has_symbolic_for(asm.pattern_version()));
        let mut rng = Rng::new(5);
        let u1 = rng.vector(n);
        let u2 = rng.vector(n);
        let b = rng.vector(n);
        for terms in [
            vec![(3.0, u1.as_slice())],
            vec![(3.0, u1.as_slice()), (0.7, u2.as_slice())],
        ] {
            let mut a = dense(n, &t) + DMatrix::identity(n, n) * 0.5;
            for (c, u) in &terms {
                let u = DVector::from_column_slice(u);
                a += &u * u.transpose() * *c;
            }
            let x_ref = a.lu().solve(&DVector::from_column_slice(&b)).unwrap();
            let mut x = vec![0.0; n];
            let mut zs = Vec::new();
            solve_with_low_rank(|r| chol.solve_in_place(r), &terms, &b, &mut x, &mut zs).unwrap();
            for i in 0..n {
                assert!(
                    (x[i] - x_ref[i]).abs() < 1e-10 * (1.0 + x_ref[i].abs()),
                    "{i}"
                );
            }
        }
        // An inconsistent user-built matrix is an error, not a panic inside faer.
        let broken = CsrMatrix {
            n: 2,
            row_ptr: vec![0, 2],
            col_idx: vec![0, 1],
            values: vec![1.0, 0.0],
        };
        assert!(SparseCholesky::new().factorize(&broken, 99).is_err());
        let unsorted = CsrMatrix {
            n: 2,
            row_ptr: vec![0, 2, 3],
            col_idx: vec![1, 0, 1],
            values: vec![0.0, 1.0, 1.0],
        };
        assert!(unsorted.check().is_err());
        assert!(SparseCholesky::new().solve_in_place(&mut [1.0]).is_err());
        // A matrix that is not positive definite is reported, not mis-solved.
        let mut bad = t.clone();
        bad.push((4, 4, -100.0));
        asm.assemble(&vec![1.0; n], 0.0, &bad, 1.0).unwrap();
        let err = chol
            .factorize(asm.matrix(), asm.pattern_version())
            .unwrap_err();
        assert!(err.to_string().contains("not positive definite"), "{err}");
    }

    #[test]
    fn incomplete_cholesky_is_exact_without_fill_and_speeds_up_cg() {
        // Tridiagonal SPD matrix: its Cholesky factor has no fill, so IC(0) is exact and PCG
        // converges in one iteration.
        let n = 50;
        let mut t = Vec::new();
        for i in 0..n {
            t.push((i, i, 2.5 + (i % 3) as f64));
            if i + 1 < n {
                t.push((i, i + 1, -1.0));
                t.push((i + 1, i, -1.0));
            }
        }
        let mut asm = SparseAssembler::new();
        asm.assemble(&vec![0.0; n], 0.0, &t, 1.0).unwrap();
        let a = asm.matrix().clone();
        let mut ic = IncompleteCholesky::new();
        ic.factorize(&a, asm.pattern_version()).unwrap();
        assert_eq!(ic.shift(), 0.0);
        let b = Rng::new(8).vector(n);
        let mut ws = CgWorkspace::default();
        let mut x = vec![0.0; n];
        let info = cg(
            |p, o| a.mul_into(p, o),
            |r, z| ic.apply(r, z),
            &b,
            &mut x,
            50,
            1e-12,
            &mut ws,
        )
        .unwrap();
        assert!(info.converged && info.iterations == 1, "{info:?}");
        // A banded matrix with fill: IC(0) is approximate but beats Jacobi, same answer.
        let t = spd_triplets(120, 13);
        asm.assemble(&vec![0.0; 120], 0.0, &t, 1.0).unwrap();
        let a = asm.matrix().clone();
        ic.factorize(&a, asm.pattern_version()).unwrap();
        let mut d = vec![0.0; 120];
        a.diagonal_into(&mut d);
        let b = Rng::new(9).vector(120);
        let (mut x1, mut x2) = (vec![0.0; 120], vec![0.0; 120]);
        let jac = cg(
            |p, o| a.mul_into(p, o),
            |r, z| {
                z.iter_mut()
                    .zip(r)
                    .zip(&d)
                    .for_each(|((z, r), d)| *z = r / d)
            },
            &b,
            &mut x1,
            500,
            1e-12,
            &mut ws,
        )
        .unwrap();
        let icc = cg(
            |p, o| a.mul_into(p, o),
            |r, z| ic.apply(r, z),
            &b,
            &mut x2,
            500,
            1e-12,
            &mut ws,
        )
        .unwrap();
        assert!(icc.iterations < jac.iterations, "{icc:?} vs {jac:?}");
        for i in 0..120 {
            assert!((x1[i] - x2[i]).abs() < 1e-9);
        }
        // Far from SPD: reported, not a panic.
        let mut bad = t.clone();
        bad.push((7, 7, -1e6));
        asm.assemble(&vec![0.0; 120], 0.0, &bad, 1.0).unwrap();
        assert!(ic.factorize(asm.matrix(), asm.pattern_version()).is_err());
    }

    #[test]
    fn solver_kind_parses() {
        for k in [
            LinearSolverKind::MatrixFreeCg,
            LinearSolverKind::Pcg,
            LinearSolverKind::Cholesky,
            LinearSolverKind::FactorizedPcg,
        ] {
            assert_eq!(k.to_string().parse::<LinearSolverKind>().unwrap(), k);
        }
        assert!(
            "lu".parse::<LinearSolverKind>()
                .unwrap_err()
                .to_string()
                .contains("lu")
        );
    }
}
