//! Expansion of a Hessian with respect to edge vectors to one with respect to vertex positions.

use nalgebra::SMatrix;

/// Given the Hessian `ke` (`N x N`, `N = 3 ne`) of an energy with respect to the edge vectors
/// `e_i = x_{i+1} - x_0`, `i = 0..ne`, returns its Hessian (`M x M`, `M = N + 3`) with respect to
/// the vertex positions `[x_0, ..., x_ne]` (vertex-major). With `S = de/dx`, this is
/// `S^T ke S`: the `x_0` rows and columns are minus the sums of the edge rows and columns.
#[inline]
pub(crate) fn edge_to_vertex_hessian<const N: usize, const M: usize>(
    ke: &SMatrix<f64, N, N>,
) -> SMatrix<f64, M, M> {
    debug_assert_eq!(M, N + 3);
    let mut k = SMatrix::<f64, M, M>::zeros();
    for c in 0..N {
        let mut s = [0.0; 3];
        for r in 0..N {
            let v = ke[(r, c)];
            k[(r + 3, c + 3)] = v;
            s[r % 3] += v;
        }
        for a in 0..3 {
            k[(a, c + 3)] = -s[a];
        }
    }
    for r in 0..M {
        let mut s = [0.0; 3];
        for c in 3..M {
            s[c % 3] += k[(r, c)];
        }
        for a in 0..3 {
            k[(r, a)] = -s[a];
        }
    }
    k
}
