//! Preconditioners for [`crate::cg`]: Jacobi ([`jacobi`]) and zero-fill incomplete Cholesky
//! ([`IncompleteCholesky`]). The kept (lagged) sparse Cholesky factorisation used as a
//! preconditioner lives in [`crate::FactorizedPcg`].

use crate::csr::CsrMatrix;
use crate::error::SolveError;

/// Jacobi preconditioner: `z = r / d` entrywise (`d` the diagonal of the matrix, positive).
#[inline]
pub fn jacobi(d: &[f64], r: &[f64], z: &mut [f64]) {
    for i in 0..z.len() {
        z[i] = r[i] / d[i];
    }
}

/// Zero-fill incomplete Cholesky `A ~ L L^T` (IC(0)): `L` keeps exactly the lower-triangle
/// pattern of `A`. A preconditioner for [`crate::cg`] on assembled matrices; exact (one CG iteration)
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
    pub fn factorize(&mut self, a: &CsrMatrix, pattern_version: u64) -> Result<(), SolveError> {
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
                    return Err(SolveError::MissingDiagonal { row: r });
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
                        return Err(SolveError::NotPositiveDefinite {
                            method: "IC(0)",
                            n: a.n,
                            nnz: self.col_idx.len(),
                            pivot: Some(row),
                            shift: shift / 10.0,
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
