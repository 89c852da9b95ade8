//! Sparse Cholesky factorisation by faer ([`SparseCholesky`]), its symbolic analysis, factor
//! storage and workspace cached across factorisations of matrices with the same pattern.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::solvers::LltError;
use faer::sparse::FaerError;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};

use crate::csr::CsrMatrix;
use crate::error::SolveError;

/// faer's resource error in words.
fn faer_reason(e: FaerError) -> &'static str {
    match e {
        FaerError::OutOfMemory => "out of memory",
        FaerError::IndexOverflow => "index overflow",
        _ => "faer resource error",
    }
}

/// The widest parallelism available: the rayon pool with the `parallel` feature, else none.
fn max_par() -> Par {
    #[cfg(feature = "parallel")]
    {
        Par::rayon(0)
    }
    #[cfg(not(feature = "parallel"))]
    {
        Par::Seq
    }
}

/// The numeric `L L^T` factorisation of `a` (lower triangle) into `values`, in the precision
/// `T`, on the symbolic analysis `symbolic`.
fn numeric_llt<T: faer::traits::ComplexField>(
    symbolic: &SymbolicCholesky<usize>,
    values: &mut [T],
    a: SparseColMatRef<'_, usize, T>,
    par: Par,
    work: &mut MemBuffer,
) -> Result<(), LltError> {
    symbolic
        .factorize_numeric_llt(
            values,
            a,
            Side::Lower,
            LltRegularization::default(),
            par,
            MemStack::new(work),
            Default::default(),
        )
        .map(|_| ())
}

/// Right-hand sides [`SparseCholesky::solve_columns_in_place`] solves in one pass over the
/// factor (more are taken in groups of this many).
pub const SOLVE_BATCH_COLUMNS: usize = 4;

/// Matrices with at least this many rows are factorised on the rayon pool when
/// [`SparseCholesky::set_parallel`] asks for it.
pub const PARALLEL_FACTORIZATION_ROWS: usize = 20_000;

/// The fill-reducing permutation `P` of a [`SparseCholesky`] (faer's AMD on the pattern) and
/// the matrix in its order, `B = P A P^T` (`B[i][j] = A[fwd[i]][fwd[j]]`), so that faer
/// factorises `B` as given instead of permuting `A` at every factorisation (a pass of scattered
/// reads and writes that took a sixth of the factorisation phase on the bunny's matrices): the
/// values of `B` are gathered from `A`'s in one pass through `source`, and the right-hand sides
/// of the solves are permuted on their way in and out. The factor is the same as faer's own
/// permuted factorisation, bit for bit. Used for supernodal factorisations only (see
/// `active`).
#[derive(Default)]
struct Permuted {
    /// Whether the factorisation uses `B` (a supernodal factorisation); otherwise faer
    /// permutes `A` itself.
    active: bool,
    /// `fwd[i]`: the row of `A` that is row `i` of `B`.
    fwd: Vec<usize>,
    /// `B`'s lower triangle by columns (sorted rows) ...
    lower_ptr: Vec<usize>,
    lower_idx: Vec<usize>,
    /// ... and the index in `A`'s CSR values of each of its entries.
    source: Vec<usize>,
    /// `B`'s lower-triangle values of the last double-precision factorisation.
    values: Vec<f64>,
    /// Permuted right-hand sides of double-precision solves.
    rhs: Vec<f64>,
}

impl Permuted {
    /// The AMD permutation of `a`'s pattern `sym` (the CSR of a symmetric matrix read as CSC)
    /// and the lower triangle of `B = P A P^T`; returns `B`'s upper triangle by columns
    /// (`(column pointers, rows)`), which only the symbolic analysis reads.
    fn analyse(
        &mut self,
        a: &CsrMatrix,
        sym: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<(Vec<usize>, Vec<usize>), SolveError> {
        let n = a.n;
        let resources = |reason| SolveError::FactorResources {
            what: "fill-reducing ordering",
            n,
            reason,
        };
        let mut fwd = vec![0usize; n];
        let mut inv = vec![0usize; n];
        let mut work = MemBuffer::try_new(amd::order_maybe_unsorted_scratch::<usize>(n, a.nnz()))
            .map_err(|_| resources("out of memory"))?;
        amd::order_maybe_unsorted(
            &mut fwd,
            &mut inv,
            sym,
            amd::Control::default(),
            MemStack::new(&mut work),
        )
        .map_err(|e| resources(faer_reason(e)))?;
        let (lower_ptr, lower_idx, source) =
            (&mut self.lower_ptr, &mut self.lower_idx, &mut self.source);
        for v in [&mut *lower_ptr, &mut *lower_idx, &mut *source] {
            v.clear();
        }
        let (mut upper_ptr, mut upper_idx) = (Vec::with_capacity(n + 1), Vec::new());
        lower_ptr.push(0);
        upper_ptr.push(0);
        let mut column: Vec<(usize, usize)> = Vec::new();
        for (j, &old) in fwd.iter().enumerate() {
            // Column `old` of the symmetric `A` is its row `old` in CSR.
            column.clear();
            column.extend((a.row_ptr[old]..a.row_ptr[old + 1]).map(|k| (inv[a.col_idx[k]], k)));
            column.sort_unstable();
            for &(i, k) in &column {
                if i >= j {
                    lower_idx.push(i);
                    // The value faer's own permutation took: the entry of `A`'s lower triangle
                    // (row >= column), so that a matrix assembled a rounding error away from
                    // symmetric is factorised as before, bit for bit.
                    let r = a.col_idx[k];
                    let mirror = if r >= old {
                        None
                    } else {
                        let row = &a.col_idx[a.row_ptr[r]..a.row_ptr[r + 1]];
                        row.binary_search(&old).ok().map(|q| a.row_ptr[r] + q)
                    };
                    source.push(mirror.unwrap_or(k));
                }
                if i <= j {
                    upper_idx.push(i);
                }
            }
            lower_ptr.push(lower_idx.len());
            upper_ptr.push(upper_idx.len());
        }
        self.fwd = fwd;
        Ok((upper_ptr, upper_idx))
    }
}

/// Sparse `L L^T` factorisation (faer, supernodal or simplicial as faer's symbolic analysis
/// chooses, AMD ordering) whose symbolic analysis, factor storage and workspace are cached and
/// rebuilt only when the pattern version changes. The matrix is gathered into the AMD order in
/// one pass per factorisation through a map made with the analysis, and the right-hand sides
/// are permuted in and out of it. Runs sequentially (`Par::Seq`) unless
/// [`SparseCholesky::set_parallel`] asks for the rayon pool: the matrices
/// of one balloon are small enough that thread start-up costs more than it saves on 2 cores.
#[derive(Default)]
pub struct SparseCholesky {
    symbolic: Option<(u64, SymbolicCholesky<usize>)>,
    /// The fill-reducing permutation and the matrix's entries in its order.
    permuted: Permuted,
    /// The factor in double precision: computed by a double-precision factorisation, or the
    /// single-precision factor widened (made at the first double-precision solve after a
    /// single-precision factorisation; stale otherwise, see `values_current`).
    values: Vec<f64>,
    /// Whether `values` holds the current factor.
    values_current: bool,
    /// The factor in single precision: computed by a single-precision factorisation, or a
    /// copy of `values` for [`SparseCholesky::set_single_precision_solves`] (made at the first
    /// such solve after a double-precision factorisation; empty otherwise).
    values_f32: Vec<f32>,
    /// The matrix rounded to single precision for a single-precision factorisation.
    matrix_f32: Vec<f32>,
    /// The right-hand sides of a single-precision solve.
    rhs_f32: Vec<f32>,
    single_precision_solves: bool,
    single_precision_factorization: bool,
    /// A non-positive pivot in single precision is final (no double-precision check).
    single_precision_verdict: bool,
    /// Whether the current factor was computed in single precision.
    factored_in_single: bool,
    workspace: Option<MemBuffer>,
    factorized: bool,
    n: usize,
    parallel: bool,
    /// Wall-clock seconds spent in [`SparseCholesky::factorize`] (symbolic and numeric).
    factor_seconds: f64,
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
    pub fn factorize(&mut self, a: &CsrMatrix, pattern_version: u64) -> Result<(), SolveError> {
        let started = std::time::Instant::now();
        let result = self.factorize_untimed(a, pattern_version);
        self.factor_seconds += started.elapsed().as_secs_f64();
        result
    }

    /// Wall-clock seconds spent factorising (symbolic analyses and numeric factorisations,
    /// failed attempts included) since this value was made: for per-phase profiles.
    pub fn factorization_seconds(&self) -> f64 {
        self.factor_seconds
    }

    fn factorize_untimed(&mut self, a: &CsrMatrix, pattern_version: u64) -> Result<(), SolveError> {
        a.check()?;
        self.factorized = false;
        // CSR of a symmetric matrix read as CSC: column r holds row indices col_idx.
        let sym = SymbolicSparseColMatRef::new_checked(a.n, a.n, &a.row_ptr, None, &a.col_idx);
        if !self.has_symbolic_for(pattern_version) {
            self.symbolic = None;
            let (upper_ptr, upper_idx) = self.permuted.analyse(a, sym)?;
            let upper =
                SymbolicSparseColMatRef::new_checked(a.n, a.n, &upper_ptr, None, &upper_idx);
            let s = factorize_symbolic_cholesky(
                upper,
                Side::Upper,
                SymmetricOrdering::Identity,
                Default::default(),
            )
            .map_err(|e| SolveError::FactorResources {
                what: "symbolic analysis",
                n: a.n,
                reason: faer_reason(e),
            })?;
            // faer's simplicial factorisation sums in an order that follows the order of the
            // entries it is given, so it would round differently on the gathered matrix than
            // on its own permuted copy: small matrices (simplicial) keep faer's permutation.
            let s = if matches!(s.raw(), SymbolicCholeskyRaw::Supernodal(_)) {
                self.permuted.active = true;
                s
            } else {
                self.permuted = Permuted::default();
                factorize_symbolic_cholesky(
                    sym,
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    Default::default(),
                )
                .map_err(|e| SolveError::FactorResources {
                    what: "symbolic analysis",
                    n: a.n,
                    reason: faer_reason(e),
                })?
            };
            let req = s
                .factorize_numeric_llt_scratch::<f64>(max_par(), Default::default())
                .or(s.solve_in_place_scratch::<f64>(SOLVE_BATCH_COLUMNS, max_par()))
                .or(s.solve_in_place_scratch::<f32>(SOLVE_BATCH_COLUMNS, max_par()));
            self.workspace =
                Some(
                    MemBuffer::try_new(req).map_err(|_| SolveError::FactorResources {
                        what: "workspace allocation",
                        n: a.n,
                        reason: "out of memory",
                    })?,
                );
            self.values.clear();
            self.values.resize(s.len_val(), 0.0);
            self.symbolic = Some((pattern_version, s));
        }
        let par = self.par_for(a.n);
        let (Some((_, symbolic)), Some(work)) = (&self.symbolic, &mut self.workspace) else {
            return Err(SolveError::NotFactorized);
        };
        let permuted = &mut self.permuted;
        let pattern = if permuted.active {
            SymbolicSparseColMatRef::new_checked(
                a.n,
                a.n,
                &permuted.lower_ptr,
                None,
                &permuted.lower_idx,
            )
        } else {
            sym
        };
        if self.single_precision_factorization {
            self.matrix_f32.clear();
            if permuted.active {
                self.matrix_f32
                    .extend(permuted.source.iter().map(|&k| a.values[k] as f32));
            } else {
                self.matrix_f32.extend(a.values.iter().map(|&v| v as f32));
            }
            self.values_f32.clear();
            self.values_f32.resize(symbolic.len_val(), 0.0);
            let mat = SparseColMatRef::new(pattern, &self.matrix_f32[..]);
            match numeric_llt(symbolic, &mut self.values_f32, mat, par, work) {
                Ok(()) => {
                    self.factorized = true;
                    self.factored_in_single = true;
                    self.values_current = false;
                    self.n = a.n;
                    return Ok(());
                }
                Err(LltError::NonPositivePivot { index }) if self.single_precision_verdict => {
                    return Err(SolveError::NotPositiveDefinite {
                        method: "sparse Cholesky (single precision)",
                        n: a.n,
                        nnz: a.nnz(),
                        pivot: Some(index),
                        shift: 0.0,
                    });
                }
                // A non-positive pivot in single precision may be the rounding of a positive
                // definite but ill-conditioned matrix: only the double-precision
                // factorisation below decides that the matrix is not positive definite.
                Err(_) => {}
            }
        }
        let values = if permuted.active {
            permuted.values.clear();
            permuted
                .values
                .extend(permuted.source.iter().map(|&k| a.values[k]));
            &permuted.values[..]
        } else {
            &a.values[..]
        };
        let mat = SparseColMatRef::new(pattern, values);
        numeric_llt(symbolic, &mut self.values, mat, par, work).map_err(
            |LltError::NonPositivePivot { index }| SolveError::NotPositiveDefinite {
                method: "sparse Cholesky",
                n: a.n,
                nnz: a.nnz(),
                pivot: Some(index),
                shift: 0.0,
            },
        )?;
        self.factorized = true;
        self.factored_in_single = false;
        self.values_current = true;
        self.values_f32.clear();
        self.n = a.n;
        Ok(())
    }

    /// Runs the numeric factorisation on the rayon thread pool (`true`) or on the calling
    /// thread (`false`, the default). Matrices of fewer than [`PARALLEL_FACTORIZATION_ROWS`]
    /// rows are factorised on the calling thread either way (thread hand-offs cost more than
    /// they save there: 2.3 ms sequential against 5.6 ms on the pool for 3912 rows, measured
    /// on 2 busy cores). Without the `parallel` feature it always runs on the calling thread.
    /// The factor is bit-identical either way (checked on the teddy's Newton matrix by
    /// `benches/examples/factor_profile.rs`).
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
    }

    fn par_for(&self, rows: usize) -> Par {
        if self.parallel && rows >= PARALLEL_FACTORIZATION_ROWS {
            max_par()
        } else {
            Par::Seq
        }
    }

    /// Makes the triangular solves read a single-precision copy of the factor (`true`) or the
    /// factor itself (`false`, the default). The solves are bound by reading the factor from
    /// memory, so the copy halves their cost (on the teddy's Newton matrix, nnz(L) = 3.8M:
    /// `benches/examples/factor_profile.rs`); the answer is then that of a factor rounded to
    /// about 7 digits, good for a preconditioner whose CG is asked for a few digits, not for a
    /// direct solve. The factorisation itself stays in double precision; the copy is made at
    /// the first such solve after each factorisation.
    pub fn set_single_precision_solves(&mut self, single: bool) {
        self.single_precision_solves = single;
    }

    /// Computes the factor in single precision (`true`) or in double precision (`false`, the
    /// default) from the next [`SparseCholesky::factorize`] on. The numeric factorisation,
    /// bound by memory traffic and by its dense kernels' width, takes about two thirds of the
    /// time (a third less on the peer sphere's static matrix, n = 30726); the factor is that of
    /// the matrix rounded to about 7 digits, good for a preconditioner, not for a direct solve.
    /// Solves use it in single precision with [`SparseCholesky::set_single_precision_solves`],
    /// else widened to double precision (the exact solve of the rounded factor, a fixed linear
    /// operator for CG's tight solves). When the single-precision factorisation meets a
    /// non-positive pivot (an indefinite matrix, or the rounding of an ill-conditioned one) the
    /// matrix is factorised again in double precision, which alone reports
    /// [`SolveError::NotPositiveDefinite`].
    pub fn set_single_precision_factorization(&mut self, single: bool) {
        self.single_precision_factorization = single;
    }

    /// Makes a non-positive pivot of the single-precision factorisation
    /// ([`SparseCholesky::set_single_precision_factorization`]) final (`true`): the matrix is
    /// reported not positive definite without the double-precision factorisation that would
    /// otherwise check it (default `false`). For a caller that answers such a verdict with a
    /// larger diagonal shift (a Newton shift ladder): a positive definite matrix whose rounding
    /// to 7 digits is not costs it a larger shift, never a wrong answer, and an indefinite one
    /// costs one failed factorisation instead of two.
    pub fn set_single_precision_verdict(&mut self, final_verdict: bool) {
        self.single_precision_verdict = final_verdict;
    }

    /// Whether the factorisation gathers the matrix into the factor's order itself (supernodal
    /// factorisations) rather than letting faer permute it.
    #[cfg(test)]
    pub(crate) fn gathers_in_factor_order(&self) -> bool {
        self.permuted.active
    }

    /// Whether the current factor was computed in single precision
    /// ([`SparseCholesky::set_single_precision_factorization`]; `false` before the first
    /// factorisation).
    pub fn factored_in_single_precision(&self) -> bool {
        self.factorized && self.factored_in_single
    }

    /// Stored entries of the factor `L` (its fill, from the symbolic analysis; 0 before the
    /// first factorisation).
    pub fn factor_entries(&self) -> usize {
        self.symbolic.as_ref().map_or(0, |(_, s)| s.len_val())
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

    /// Solves `A X = RHS` in place for `columns` right-hand sides stored one after the other in
    /// `rhs` (column-major, `n` rows each), reading the factor once per
    /// [`SOLVE_BATCH_COLUMNS`] columns: the triangular solves are bound by reading the factor
    /// from memory, so two columns cost little more than one (on the teddy's Newton matrix,
    /// nnz(L) = 3.8M: 4.9 ms for two columns against 3.4 ms for one, measured with
    /// `benches/examples/factor_profile.rs`). Each column equals its single-column solve to
    /// round-off (not bit for bit: the kernels for several columns sum in another order).
    pub fn solve_columns_in_place(
        &mut self,
        rhs: &mut [f64],
        columns: usize,
    ) -> Result<(), SolveError> {
        if !self.factorized {
            return Err(SolveError::NotFactorized);
        }
        if columns == 0 || rhs.len() != columns * self.n {
            return Err(SolveError::Dimension {
                what: "rhs columns",
                len: rhs.len(),
                expected: columns.max(1) * self.n,
            });
        }
        for group in rhs.chunks_mut(SOLVE_BATCH_COLUMNS * self.n) {
            self.solve_block(group)?;
        }
        Ok(())
    }

    /// Solves `A x = rhs` in place with the last factorisation.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), SolveError> {
        if !self.factorized {
            return Err(SolveError::NotFactorized);
        }
        if rhs.len() != self.n {
            return Err(SolveError::Dimension {
                what: "rhs",
                len: rhs.len(),
                expected: self.n,
            });
        }
        self.solve_block(rhs)
    }

    /// Solves for the columns of `rhs` (a whole number of columns, at most
    /// [`SOLVE_BATCH_COLUMNS`]: the workspace is sized for that).
    fn solve_block(&mut self, rhs: &mut [f64]) -> Result<(), SolveError> {
        let (true, Some((_, symbolic)), Some(work)) =
            (self.factorized, &self.symbolic, &mut self.workspace)
        else {
            return Err(SolveError::NotFactorized);
        };
        let n = self.n;
        if n == 0 || !rhs.len().is_multiple_of(n) || rhs.len() > SOLVE_BATCH_COLUMNS * n {
            return Err(SolveError::Dimension {
                what: "rhs",
                len: rhs.len(),
                expected: n,
            });
        }
        let columns = rhs.len() / n;
        if self.single_precision_solves {
            if !self.factored_in_single && self.values_f32.len() != self.values.len() {
                self.values_f32.clear();
                self.values_f32
                    .extend(self.values.iter().map(|&v| v as f32));
            }
            let fwd = &self.permuted.fwd;
            self.rhs_f32.clear();
            if self.permuted.active {
                for column in rhs.chunks_exact(n) {
                    self.rhs_f32
                        .extend(fwd.iter().map(|&old| column[old] as f32));
                }
            } else {
                self.rhs_f32.extend(rhs.iter().map(|&v| v as f32));
            }
            let m = faer::MatMut::from_column_major_slice_mut(&mut self.rhs_f32[..], n, columns);
            LltRef::new(symbolic, &self.values_f32).solve_in_place_with_conj(
                faer::Conj::No,
                m,
                Par::Seq,
                MemStack::new(work),
            );
            if self.permuted.active {
                for (column, solved) in rhs.chunks_exact_mut(n).zip(self.rhs_f32.chunks_exact(n)) {
                    for (&old, &v) in fwd.iter().zip(solved) {
                        column[old] = f64::from(v);
                    }
                }
            } else {
                for (out, &v) in rhs.iter_mut().zip(&self.rhs_f32) {
                    *out = f64::from(v);
                }
            }
            return Ok(());
        }
        if !self.values_current {
            // The single-precision factor, widened: solved in double precision.
            self.values.clear();
            self.values
                .extend(self.values_f32.iter().map(|&v| f64::from(v)));
            self.values_current = true;
        }
        if !self.permuted.active {
            let m = faer::MatMut::from_column_major_slice_mut(rhs, n, columns);
            LltRef::new(symbolic, &self.values).solve_in_place_with_conj(
                faer::Conj::No,
                m,
                Par::Seq,
                MemStack::new(work),
            );
            return Ok(());
        }
        let (fwd, scratch) = (&self.permuted.fwd, &mut self.permuted.rhs);
        scratch.clear();
        for column in rhs.chunks_exact(n) {
            scratch.extend(fwd.iter().map(|&old| column[old]));
        }
        let m = faer::MatMut::from_column_major_slice_mut(&mut scratch[..], n, columns);
        LltRef::new(symbolic, &self.values).solve_in_place_with_conj(
            faer::Conj::No,
            m,
            Par::Seq,
            MemStack::new(work),
        );
        for (column, solved) in rhs.chunks_exact_mut(n).zip(scratch.chunks_exact(n)) {
            for (&old, &v) in fwd.iter().zip(solved) {
                column[old] = v;
            }
        }
        Ok(())
    }
}
