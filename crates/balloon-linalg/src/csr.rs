//! Compressed sparse row storage ([`CsrMatrix`], the hot-path type) and its conversion to
//! [`sprs::CsMat`], the type downstream users see, with Matrix Market export.

use std::path::Path;

use sprs::CsMat;

use crate::error::SolveError;

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
    pub fn check(&self) -> Result<(), SolveError> {
        let n = self.n;
        let bad = |what: &'static str, len: usize, expected: usize| {
            Err(SolveError::Dimension {
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
                    return Err(SolveError::TripletOutOfRange { row: r, col: c, n });
                }
            }
        }
        Ok(())
    }
}

impl CsrMatrix {
    /// The same matrix as a [`sprs::CsMat`] in CSR storage (copies the three arrays; the hot
    /// path keeps working on `self`). Errors if the structure is inconsistent (see
    /// [`CsrMatrix::check`]).
    pub fn to_csmat(&self) -> Result<CsMat<f64>, SolveError> {
        self.check()?;
        CsMat::try_new(
            (self.n, self.n),
            self.row_ptr.clone(),
            self.col_idx.clone(),
            self.values.clone(),
        )
        .map_err(|(.., e)| SolveError::InvalidCsr(e))
    }

    /// A square [`sprs::CsMat`] (CSR or CSC; a CSC matrix is converted) as a [`CsrMatrix`].
    /// Errors if the matrix is not square.
    pub fn from_csmat(m: &CsMat<f64>) -> Result<Self, SolveError> {
        if m.rows() != m.cols() {
            return Err(SolveError::Dimension {
                what: "columns of a square matrix",
                len: m.cols(),
                expected: m.rows(),
            });
        }
        let csr = m.to_csr();
        let out = Self {
            n: csr.rows(),
            row_ptr: csr.indptr().to_proper().into_owned(),
            col_idx: csr.indices().to_vec(),
            values: csr.data().to_vec(),
        };
        out.check()?;
        Ok(out)
    }
}

/// Writes `m` to `path` in Matrix Market coordinate format (`sprs::io::write_matrix_market`),
/// readable by SciPy, Octave, MATLAB, Julia and `sprs::io::read_matrix_market`.
pub fn write_matrix_market(m: &CsMat<f64>, path: impl AsRef<Path>) -> Result<(), SolveError> {
    let path = path.as_ref();
    sprs::io::write_matrix_market(path, m).map_err(|e| SolveError::MatrixMarket {
        path: path.display().to_string(),
        detail: e.to_string(),
    })
}

/// Reads a real Matrix Market coordinate file (`sprs::io::read_matrix_market`) as a CSR
/// [`sprs::CsMat`]; duplicate entries are summed.
pub fn read_matrix_market(path: impl AsRef<Path>) -> Result<CsMat<f64>, SolveError> {
    let path = path.as_ref();
    sprs::io::read_matrix_market::<f64, usize, _>(path)
        .map(|t| t.to_csr())
        .map_err(|e| SolveError::MatrixMarket {
            path: path.display().to_string(),
            detail: e.to_string(),
        })
}
