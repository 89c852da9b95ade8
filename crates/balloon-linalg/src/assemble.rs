//! Assembly of `diag_scale * diag(d) + scale * K` into a [`CsrMatrix`] from triplets or dense
//! element blocks ([`StiffnessBlocks`]), re-using the sparsity pattern while it is unchanged.

use crate::csr::CsrMatrix;
use crate::error::SolveError;

/// The sparse part of a stiffness matrix as dense element blocks: block `e` couples the nodes
/// `nodes[e * nodes_per_block..(e + 1) * nodes_per_block]` (3 degrees of freedom each, dof
/// `3 node + c`) and holds `(3 k)^2` values, `k = nodes_per_block`, column-major in node-major
/// dof order `[x1 y1 z1 x2 ...]`, at `values[e * (3 k)^2..]`. Duplicate couplings are summed.
#[derive(Clone, Copy, Debug)]
pub struct StiffnessBlocks<'a> {
    /// Nodes per block (`k`; 3 for a triangle).
    pub nodes_per_block: usize,
    /// Node indices, `k` per block.
    pub nodes: &'a [usize],
    /// Block values, `(3 k)^2` per block, column-major.
    pub values: &'a [f64],
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
    /// The block part of the pattern inverted for [`SparseAssembler::assemble_blocks`]: the
    /// block values summed into matrix entry `s` are
    /// `gather_src[gather_ptr[s]..gather_ptr[s + 1]]`, in increasing order (empty when the
    /// pattern was built from triplets).
    gather_ptr: Vec<u32>,
    gather_src: Vec<u32>,
    /// Whether the pattern was built by the node-level path of
    /// [`SparseAssembler::assemble_blocks`] (blocks only, no extra triplets), which keeps no
    /// per-triplet `keys` and `slots`: the triplet path then rebuilds.
    node_pattern: bool,
    matrix: CsrMatrix,
    pattern_version: u64,
}

/// Matrices with at least this many stored entries are assembled from blocks on the rayon
/// pool (with the `parallel` feature); smaller ones on the calling thread.
#[cfg(feature = "parallel")]
const PARALLEL_ASSEMBLY_ENTRIES: usize = 1 << 16;

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
    ) -> Result<bool, SolveError> {
        let n = diagonal.len();
        let same = self.matrix.n == n
            && !self.node_pattern
            && self.keys.len() == triplets.len()
            && self
                .keys
                .iter()
                .zip(triplets)
                .all(|(k, t)| k.0 == t.0 && k.1 == t.1);
        if !same {
            self.rebuild_pattern(n, triplets)?;
            self.node_pattern = false;
            self.block_k = 0;
            self.block_nodes.clear();
            self.gather_ptr.clear();
            self.gather_src.clear();
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
    /// block form of [`SparseAssembler::assemble`] ([`StiffnessBlocks`]): the
    /// pattern check compares only the block node lists and the `extra` keys, and the values are
    /// scattered straight from the blocks (no triplet list). Returns whether the pattern was
    /// rebuilt; the matrix equals the one `assemble` builds from the equivalent triplets.
    pub fn assemble_blocks(
        &mut self,
        diagonal: &[f64],
        diag_scale: f64,
        blocks: &StiffnessBlocks<'_>,
        extra: &[(usize, usize, f64)],
        scale: f64,
    ) -> Result<bool, SolveError> {
        let n = diagonal.len();
        let k = blocks.nodes_per_block;
        let bs = 9 * k * k;
        if k == 0
            || !blocks.nodes.len().is_multiple_of(k)
            || blocks.values.len() != blocks.nodes.len() / k * bs
        {
            return Err(SolveError::Dimension {
                what: "stiffness block values",
                len: blocks.values.len(),
                expected: blocks.nodes.len() / k.max(1) * bs,
            });
        }
        let nb = blocks.values.len();
        let same = self.matrix.n == n
            && self.block_k == k
            && self.block_nodes == blocks.nodes
            && if self.node_pattern {
                extra.is_empty()
            } else {
                self.keys.len() == nb + extra.len()
                    && self.keys[nb..]
                        .iter()
                        .zip(extra)
                        .all(|(k, t)| k.0 == t.0 && k.1 == t.1)
            };
        if !same && extra.is_empty() && self.rebuild_node_pattern(n, k, blocks.nodes)? {
            self.block_k = k;
            self.block_nodes.clear();
            self.block_nodes.extend_from_slice(blocks.nodes);
        } else if !same {
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
            self.node_pattern = false;
            self.build_gather(nb)?;
            self.block_k = k;
            self.block_nodes.clear();
            self.block_nodes.extend_from_slice(blocks.nodes);
        }
        // Each entry is the sum of its block sources in increasing order, starting from 0,
        // then the extra triplets, then the diagonal: the same additions in the same order as
        // scattering the sources one by one, so the result is bit-identical to that (and to
        // itself on any number of threads).
        let (ptr, src) = (&self.gather_ptr, &self.gather_src);
        let values = blocks.values;
        let entry = |s: usize| {
            let mut acc = 0.0;
            for &j in &src[ptr[s] as usize..ptr[s + 1] as usize] {
                acc += scale * values[j as usize];
            }
            acc
        };
        let out = &mut self.matrix.values;
        fill_entries(out, entry);
        let extra_slots = if self.node_pattern {
            &[][..]
        } else {
            &self.slots[nb..]
        };
        for (t, &s) in extra.iter().zip(extra_slots) {
            out[s] += scale * t.2;
        }
        for (i, &s) in self.diag_slots.iter().enumerate() {
            out[s] += diag_scale * diagonal[i];
        }
        Ok(!same)
    }

    /// The pattern and gather lists of [`SparseAssembler::assemble_blocks`] from the blocks'
    /// node couplings alone (no extra triplets), in `O(blocks k^2)` node pairs instead of
    /// `O(blocks (3k)^2)` scalar entries: every coupled node pair is a dense 3x3 block of the
    /// matrix, so each scalar row `3a + c` holds the columns `3v, 3v + 1, 3v + 2` of the sorted
    /// node neighbours `v` of `a`. The result (row pointers, columns, diagonal slots and
    /// per-entry sources in increasing order) is the one the scalar path builds, so the
    /// assembled values are bit-identical. Returns `false` (nothing changed) when `n` is not a
    /// multiple of 3 or a node is in no block (its rows would hold the diagonal alone in the
    /// scalar pattern): the caller takes the scalar path.
    fn rebuild_node_pattern(
        &mut self,
        n: usize,
        k: usize,
        nodes: &[usize],
    ) -> Result<bool, SolveError> {
        if !n.is_multiple_of(3) {
            return Ok(false);
        }
        let nv = n / 3;
        if let Some(&bad) = nodes.iter().find(|&&a| a >= nv) {
            return Err(SolveError::TripletOutOfRange {
                row: 3 * bad,
                col: 3 * bad,
                n,
            });
        }
        let blocks = nodes.len() / k;
        let d = 3 * k;
        let bs = d * d;
        u32::try_from(blocks * bs).map_err(|_| SolveError::Dimension {
            what: "stiffness block values (at most u32::MAX)",
            len: blocks * bs,
            expected: u32::MAX as usize,
        })?;
        // Node-pair entries `(block, q, p)` (row node `nodes[p]`, column node `nodes[q]`),
        // enumerated block by block, `q` before `p`: for a fixed scalar offset `(ci, cj)` their
        // value indices `block bs + (3q + cj) d + 3p + ci` increase with the enumeration.
        let pairs = blocks * k * k;
        let entry = |e: usize| {
            let (b, r) = (e / (k * k), e % (k * k));
            let (q, p) = (r / k, r % k);
            (b, p, q)
        };
        let mut row_start = vec![0usize; nv + 1];
        for &a in nodes {
            row_start[a + 1] += k;
        }
        if row_start[1..].contains(&0) {
            return Ok(false);
        }
        for a in 0..nv {
            row_start[a + 1] += row_start[a];
        }
        // Stable bucketing by row node, then a stable sort by column node within each row:
        // the entries of one node pair stay in enumeration order.
        let mut next = row_start.clone();
        let mut order = vec![0u32; pairs];
        for e in 0..pairs {
            let (b, p, _) = entry(e);
            let a = nodes[b * k + p];
            order[next[a]] = e as u32;
            next[a] += 1;
        }
        let col_node = |e: u32| {
            let (b, _, q) = entry(e as usize);
            nodes[b * k + q]
        };
        for a in 0..nv {
            order[row_start[a]..row_start[a + 1]].sort_by_key(|&e| col_node(e));
        }
        // Distinct neighbours per row node, and where each one's entries start in `order`.
        let mut nbr_ptr = vec![0usize; nv + 1];
        let mut nbr_node = Vec::new();
        let mut nbr_first = Vec::new();
        for a in 0..nv {
            let mut last = usize::MAX;
            for (i, &e) in order[row_start[a]..row_start[a + 1]].iter().enumerate() {
                let v = col_node(e);
                if v != last {
                    nbr_node.push(v);
                    nbr_first.push(row_start[a] + i);
                    last = v;
                }
            }
            nbr_ptr[a + 1] = nbr_node.len();
        }
        nbr_first.push(pairs);
        // Scalar rows, columns, diagonal slots and gather lists.
        let nnz = 9 * nbr_node.len();
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col_idx = Vec::with_capacity(nnz);
        let mut diag_slots = vec![0usize; n];
        let mut gather_ptr = Vec::with_capacity(nnz + 1);
        let mut gather_src = Vec::with_capacity(blocks * bs);
        gather_ptr.push(0u32);
        for a in 0..nv {
            let neighbours = nbr_ptr[a]..nbr_ptr[a + 1];
            for ci in 0..3 {
                row_ptr.push(col_idx.len());
                for u in neighbours.clone() {
                    let v = nbr_node[u];
                    for cj in 0..3 {
                        if v == a && cj == ci {
                            diag_slots[3 * a + ci] = col_idx.len();
                        }
                        col_idx.push(3 * v + cj);
                        for &e in &order[nbr_first[u]..nbr_first[u + 1]] {
                            let (b, p, q) = entry(e as usize);
                            gather_src.push((b * bs + (3 * q + cj) * d + 3 * p + ci) as u32);
                        }
                        gather_ptr.push(gather_src.len() as u32);
                    }
                }
            }
        }
        row_ptr.push(col_idx.len());
        self.slots.clear();
        self.keys.clear();
        self.diag_slots = diag_slots;
        self.gather_ptr = gather_ptr;
        self.gather_src = gather_src;
        self.matrix = CsrMatrix {
            n,
            row_ptr,
            values: vec![0.0; col_idx.len()],
            col_idx,
        };
        self.node_pattern = true;
        self.pattern_version += 1;
        Ok(true)
    }

    /// Inverts the block part of `slots` (the first `nb`) into the per-entry source lists of
    /// [`SparseAssembler::assemble_blocks`] (counting sort: sources stay in increasing order).
    fn build_gather(&mut self, nb: usize) -> Result<(), SolveError> {
        let entries = self.matrix.values.len();
        let too_many = |len: usize| SolveError::Dimension {
            what: "stiffness block values (at most u32::MAX)",
            len,
            expected: u32::MAX as usize,
        };
        u32::try_from(nb).map_err(|_| too_many(nb))?;
        let mut ptr = vec![0u32; entries + 1];
        for &s in &self.slots[..nb] {
            ptr[s + 1] += 1;
        }
        for s in 0..entries {
            ptr[s + 1] += ptr[s];
        }
        let mut next = ptr.clone();
        let mut src = vec![0u32; nb];
        for (j, &s) in self.slots[..nb].iter().enumerate() {
            src[next[s] as usize] = j as u32;
            next[s] += 1;
        }
        self.gather_ptr = ptr;
        self.gather_src = src;
        Ok(())
    }

    fn rebuild_pattern(
        &mut self,
        n: usize,
        triplets: &[(usize, usize, f64)],
    ) -> Result<(), SolveError> {
        for t in triplets {
            if t.0 >= n || t.1 >= n {
                return Err(SolveError::TripletOutOfRange {
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
        // Entries bucketed by row (a counting sort, stable), then each row's by column: the
        // order of sorting all the keys at once, in O(entries) plus small per-row sorts.
        let mut row_start = vec![0usize; n + 1];
        for e in 0..total {
            row_start[key(e).0 + 1] += 1;
        }
        for r in 0..n {
            row_start[r + 1] += row_start[r];
        }
        let mut next = row_start.clone();
        let mut order = vec![0usize; total];
        for e in 0..total {
            let r = key(e).0;
            order[next[r]] = e;
            next[r] += 1;
        }
        for r in 0..n {
            order[row_start[r]..row_start[r + 1]].sort_unstable_by_key(|&e| key(e).1);
        }
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

/// `out[s] = entry(s)` for every entry, on the rayon pool for large matrices (each entry is
/// computed by one closure call, so the result does not depend on the thread count).
fn fill_entries(out: &mut [f64], entry: impl Fn(usize) -> f64 + Sync) {
    #[cfg(feature = "parallel")]
    if out.len() >= PARALLEL_ASSEMBLY_ENTRIES {
        use rayon::prelude::*;
        const CHUNK: usize = 4096;
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (i, v) in chunk.iter_mut().enumerate() {
                    *v = entry(c * CHUNK + i);
                }
            });
        return;
    }
    for (s, v) in out.iter_mut().enumerate() {
        *v = entry(s);
    }
}

impl SparseAssembler {
    /// The last assembled matrix as a [`sprs::CsMat`] (a copy, for users; the solvers work on
    /// [`SparseAssembler::matrix`]).
    pub fn to_csmat(&self) -> Result<sprs::CsMat<f64>, SolveError> {
        self.matrix.to_csmat()
    }
}
