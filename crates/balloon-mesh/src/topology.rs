//! Mesh topology: unique edges, vertex/edge/triangle adjacency in compressed (CSR) form, one-rings,
//! boundary edges, connected components, Euler characteristic, genus and manifoldness.
//!
//! Edge `k` of triangle `t = [a, b, c]` is the directed edge `(t[k], t[(k + 1) % 3])`, i.e.
//! `(a, b)`, `(b, c)`, `(c, a)`.

use crate::TriMesh;

/// Adjacency of a triangle mesh, built once in `O(F log F)`.
///
/// Requires every triangle index to be `< num_vertices` (check with [`crate::validate`] first for
/// user-built meshes; the readers guarantee it).
#[derive(Clone, Debug)]
pub struct Topology {
    num_vertices: usize,
    edges: Vec<[usize; 2]>,
    triangle_edges: Vec<[usize; 3]>,
    edge_tri_offsets: Vec<usize>,
    edge_tris: Vec<usize>,
    vert_tri_offsets: Vec<usize>,
    vert_tris: Vec<usize>,
    vert_nbr_offsets: Vec<usize>,
    vert_nbrs: Vec<usize>,
}

fn csr(n: usize, pairs: &mut [(usize, usize)]) -> (Vec<usize>, Vec<usize>) {
    pairs.sort_unstable();
    let mut offsets = vec![0usize; n + 1];
    for &(k, _) in pairs.iter() {
        offsets[k + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    (offsets, pairs.iter().map(|&(_, v)| v).collect())
}

/// A bending hinge of an oriented triangle mesh: an edge shared by exactly two triangles that
/// run along it in opposite directions, `A = (x0, x1, x2)` and `B = (x1, x0, x3)` up to
/// rotation of their corners.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeHinge {
    /// `[x0, x1, x2, x3]`: the edge `x0 x1` (`x0 < x1`) and the corners opposite it in `A`
    /// and `B`.
    pub corners: [usize; 4],
    /// The triangles `A` and `B` (indices into the triangle list).
    pub faces: [usize; 2],
}

/// The hinges of `triangles`, sorted by edge: every edge with exactly one triangle along each
/// of its two directions. Edges of an open or non-manifold part (one triangle, or a second
/// triangle along the same direction) have none. Used by the wall's bending term and the
/// design's rest-mesh bending term (discrete-shell hinges, Grinspun et al. 2003).
pub fn hinges(triangles: &[[usize; 3]]) -> Vec<EdgeHinge> {
    let mut directed: Vec<((usize, usize), usize, usize)> = Vec::with_capacity(3 * triangles.len());
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            directed.push(((t[k], t[(k + 1) % 3]), t[(k + 2) % 3], f));
        }
    }
    directed.sort_unstable_by_key(|d| d.0);
    // The one triangle along directed edge `key`, if exactly one runs along it.
    let unique = |key: (usize, usize)| {
        let i = directed.partition_point(|d| d.0 < key);
        let j = directed.partition_point(|d| d.0 <= key);
        (j == i + 1).then(|| (directed[i].1, directed[i].2))
    };
    let mut out = Vec::new();
    for (i, d) in directed.iter().enumerate() {
        let (a, b) = d.0;
        if a >= b || (i > 0 && directed[i - 1].0 == d.0) {
            continue;
        }
        if let (Some((c, fa)), Some((dd, fb))) = (unique((a, b)), unique((b, a))) {
            out.push(EdgeHinge {
                corners: [a, b, c, dd],
                faces: [fa, fb],
            });
        }
    }
    out
}

impl Topology {
    /// Builds the adjacency of `mesh`.
    ///
    /// # Panics
    /// If a triangle index is `>= mesh.num_vertices()`.
    pub fn new(mesh: &TriMesh) -> Self {
        Self::from_triangles(mesh.num_vertices(), &mesh.triangles)
    }

    /// Builds the adjacency of `triangles` over `num_vertices` vertices.
    ///
    /// # Panics
    /// If a triangle index is `>= num_vertices`.
    pub fn from_triangles(num_vertices: usize, triangles: &[[usize; 3]]) -> Self {
        let nf = triangles.len();
        // (edge key, triangle, local edge)
        let mut keyed: Vec<([usize; 2], usize, usize)> = Vec::with_capacity(3 * nf);
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                assert!(
                    a < num_vertices && b < num_vertices,
                    "triangle {t} index out of range"
                );
                keyed.push(([a.min(b), a.max(b)], t, k));
            }
        }
        keyed.sort_unstable();
        let mut edges: Vec<[usize; 2]> = Vec::new();
        let mut triangle_edges = vec![[0usize; 3]; nf];
        let mut edge_tri_offsets = vec![0usize];
        let mut edge_tris = Vec::with_capacity(3 * nf);
        for (key, t, k) in keyed {
            if edges.last() != Some(&key) {
                edges.push(key);
                edge_tri_offsets.push(*edge_tri_offsets.last().unwrap_or(&0));
            }
            let e = edges.len() - 1;
            triangle_edges[t][k] = e;
            edge_tris.push(t);
            edge_tri_offsets[e + 1] += 1;
        }
        let mut vt: Vec<(usize, usize)> = Vec::with_capacity(3 * nf);
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                vt.push((v, t));
            }
        }
        let (vert_tri_offsets, mut vert_tris) = csr(num_vertices, &mut vt);
        // A triangle with a repeated index appears twice in its vertex's list: keep it once.
        for v in 0..num_vertices {
            let s = &mut vert_tris[vert_tri_offsets[v]..vert_tri_offsets[v + 1]];
            s.sort_unstable();
        }
        let mut vn: Vec<(usize, usize)> = Vec::with_capacity(2 * edges.len());
        for &[a, b] in &edges {
            if a != b {
                vn.push((a, b));
                vn.push((b, a));
            }
        }
        let (vert_nbr_offsets, vert_nbrs) = csr(num_vertices, &mut vn);
        Self {
            num_vertices,
            edges,
            triangle_edges,
            edge_tri_offsets,
            edge_tris,
            vert_tri_offsets,
            vert_tris,
            vert_nbr_offsets,
            vert_nbrs,
        }
    }

    /// Number of vertices (including unreferenced ones).
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangle_edges.len()
    }

    /// Number of unique undirected edges.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// Unique undirected edges `[a, b]` with `a <= b`, sorted.
    pub fn edges(&self) -> &[[usize; 2]] {
        &self.edges
    }

    /// For each triangle, the indices (into [`Self::edges`]) of its edges `(a, b)`, `(b, c)`,
    /// `(c, a)`.
    pub fn triangle_edges(&self) -> &[[usize; 3]] {
        &self.triangle_edges
    }

    /// Triangles containing edge `e` (sorted; a triangle appears once per occurrence of the edge).
    pub fn edge_triangles(&self, e: usize) -> &[usize] {
        &self.edge_tris[self.edge_tri_offsets[e]..self.edge_tri_offsets[e + 1]]
    }

    /// Triangles incident to vertex `v` (sorted).
    pub fn vertex_triangles(&self, v: usize) -> &[usize] {
        &self.vert_tris[self.vert_tri_offsets[v]..self.vert_tri_offsets[v + 1]]
    }

    /// The one-ring of vertex `v`: its distinct edge neighbours (sorted).
    pub fn vertex_neighbors(&self, v: usize) -> &[usize] {
        &self.vert_nbrs[self.vert_nbr_offsets[v]..self.vert_nbr_offsets[v + 1]]
    }

    /// Edges with exactly one incident triangle (the boundary of an open mesh).
    pub fn boundary_edges(&self) -> Vec<usize> {
        (0..self.num_edges())
            .filter(|&e| self.edge_triangles(e).len() == 1)
            .collect()
    }

    /// Edges with more than two incident triangles.
    pub fn non_manifold_edges(&self) -> Vec<usize> {
        (0..self.num_edges())
            .filter(|&e| self.edge_triangles(e).len() > 2)
            .collect()
    }

    /// Number of edge-connected fans of triangles around `v` (two incident triangles are in the
    /// same fan when they share an edge through `v`). A manifold vertex has exactly one fan
    /// (a disk, or a half-disk on the boundary); 0 for an unreferenced vertex.
    ///
    /// Runs in `O(k log k)` for a vertex of valence `k` (its incident triangles are grouped by
    /// the other corners they share, not compared pairwise), so a vertex with a million incident
    /// triangles is checked in a fraction of a second.
    pub fn vertex_fan_count(&self, v: usize, triangles: &[[usize; 3]]) -> usize {
        let tris = self.vertex_triangles(v);
        let n = tris.len();
        if n <= 1 {
            return n;
        }
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        // (other corner w, entry i): entries sharing a corner w != v share the edge (v, w).
        let mut by_corner: Vec<(usize, usize)> = Vec::with_capacity(2 * n);
        for (i, &t) in tris.iter().enumerate() {
            for w in triangles[t] {
                if w != v {
                    by_corner.push((w, i));
                }
            }
        }
        by_corner.sort_unstable();
        // Two entries are joined when they share a corner and are different triangles (a
        // triangle listed twice, through a repeated index, is not joined to itself): a group of
        // entries with one corner is one fan as soon as it holds two different triangles.
        for group in by_corner.chunk_by(|a, b| a.0 == b.0) {
            let first = group[0].1;
            if group.iter().any(|&(_, i)| tris[i] != tris[first]) {
                for &(_, i) in &group[1..] {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, first));
                    parent[a] = b;
                }
            }
        }
        let mut roots: Vec<usize> = (0..n).map(|i| find(&mut parent, i)).collect();
        roots.sort_unstable();
        roots.dedup();
        roots.len()
    }

    /// Vertices whose incident triangles form more than one fan (see
    /// [`Self::vertex_fan_count`]): two surfaces touching at a point.
    pub fn non_manifold_vertices(&self, triangles: &[[usize; 3]]) -> Vec<usize> {
        (0..self.num_vertices)
            .filter(|&v| self.vertex_fan_count(v, triangles) > 1)
            .collect()
    }

    /// Connected components of triangles (connected through shared edges): a label per triangle
    /// and the number of components. Labels are numbered in order of first triangle.
    pub fn triangle_components(&self) -> (Vec<usize>, usize) {
        // Union-find over the edges' triangle lists: linear in the number of edge-triangle
        // incidences, also when thousands of triangles share one (non-manifold) edge, where a
        // search from every triangle over its edges' lists would be quadratic.
        let nf = self.num_triangles();
        let mut parent: Vec<usize> = (0..nf).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for e in 0..self.num_edges() {
            let tris = self.edge_triangles(e);
            if let Some((&first, rest)) = tris.split_first() {
                for &u in rest {
                    let (a, b) = (find(&mut parent, u), find(&mut parent, first));
                    if a != b {
                        parent[a] = b;
                    }
                }
            }
        }
        // Components numbered in the order of their lowest triangle.
        let mut label_of_root = vec![usize::MAX; nf];
        let mut label = vec![0; nf];
        let mut count = 0;
        for t in 0..nf {
            let r = find(&mut parent, t);
            if label_of_root[r] == usize::MAX {
                label_of_root[r] = count;
                count += 1;
            }
            label[t] = label_of_root[r];
        }
        (label, count)
    }

    /// Number of referenced vertices (vertices with at least one incident triangle).
    pub fn num_referenced_vertices(&self) -> usize {
        (0..self.num_vertices)
            .filter(|&v| !self.vertex_triangles(v).is_empty())
            .count()
    }

    /// Euler characteristic `chi = V - E + F`, counting only referenced vertices.
    pub fn euler_characteristic(&self) -> i64 {
        self.num_referenced_vertices() as i64 - self.num_edges() as i64
            + self.num_triangles() as i64
    }

    /// `true` when every edge has exactly two triangles (no boundary, no non-manifold edge).
    pub fn is_closed(&self) -> bool {
        (0..self.num_edges()).all(|e| self.edge_triangles(e).len() == 2)
    }

    /// `true` when no edge has more than two triangles and every vertex has at most one fan.
    pub fn is_manifold(&self, triangles: &[[usize; 3]]) -> bool {
        self.non_manifold_edges().is_empty() && self.non_manifold_vertices(triangles).is_empty()
    }

    /// Genus of a closed orientable 2-manifold: the sum over connected components of
    /// `g_c = (2 - chi_c) / 2`, where `chi_c = V_c - E_c + F_c`. `None` when the mesh is not closed
    /// or not manifold, or a component has odd Euler characteristic.
    pub fn genus(&self, triangles: &[[usize; 3]]) -> Option<usize> {
        if !self.is_closed() || !self.is_manifold(triangles) {
            return None;
        }
        let (label, count) = self.triangle_components();
        let mut chi = vec![0i64; count];
        for &l in &label {
            chi[l] += 1;
        }
        for e in 0..self.num_edges() {
            chi[label[self.edge_triangles(e)[0]]] -= 1;
        }
        for v in 0..self.num_vertices {
            if let Some(&t) = self.vertex_triangles(v).first() {
                chi[label[t]] += 1;
            }
        }
        let mut g = 0usize;
        for c in chi {
            if c > 2 || (2 - c) % 2 != 0 {
                return None;
            }
            g += ((2 - c) / 2) as usize;
        }
        Some(g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{icosphere, torus};

    #[test]
    fn icosphere_topology() {
        // A sphere is a closed genus-0 surface: chi = V - E + F = 2 and E = 3F/2.
        let m = icosphere(1.0, 2).unwrap();
        let t = Topology::new(&m);
        assert_eq!(t.num_edges(), 3 * m.num_triangles() / 2);
        assert_eq!(t.euler_characteristic(), 2);
        assert!(t.is_closed());
        assert!(t.is_manifold(&m.triangles));
        assert_eq!(t.genus(&m.triangles), Some(0));
        assert_eq!(t.triangle_components().1, 1);
        // Icosahedron vertices keep valence 5, the others 6.
        assert_eq!(t.vertex_neighbors(0).len(), 5);
        assert_eq!(t.vertex_neighbors(m.num_vertices() - 1).len(), 6);
        assert_eq!(t.vertex_triangles(0).len(), 5);
    }

    /// Every edge of a closed manifold mesh is one hinge whose corners are the edge and the
    /// two opposite corners of its triangles (checked against each triangle's own corner
    /// order); an open edge and an edge with a third triangle along it have none.
    #[test]
    fn hinges_are_the_edges_with_one_triangle_each_way() {
        let m = icosphere(1.0, 2).unwrap();
        let h = hinges(&m.triangles);
        assert_eq!(h.len(), Topology::new(&m).num_edges());
        assert!(h.windows(2).all(|w| w[0].corners[..2] < w[1].corners[..2]));
        for e in &h {
            let [a, b, c, d] = e.corners;
            assert!(a < b);
            let ta = m.triangles[e.faces[0]];
            let tb = m.triangles[e.faces[1]];
            let rotations = |t: [usize; 3]| [t, [t[1], t[2], t[0]], [t[2], t[0], t[1]]];
            assert!(
                rotations(ta).contains(&[a, b, c]),
                "{ta:?} vs {:?}",
                [a, b, c]
            );
            assert!(
                rotations(tb).contains(&[b, a, d]),
                "{tb:?} vs {:?}",
                [b, a, d]
            );
        }
        // Open: drop a triangle; its three edges lose their hinge.
        let open = &m.triangles[1..];
        assert_eq!(hinges(open).len(), h.len() - 3);
        // Non-manifold: a second copy of triangle 0 runs along its edges in the same direction.
        let mut doubled = m.triangles.clone();
        doubled.push(m.triangles[0]);
        assert_eq!(hinges(&doubled).len(), h.len() - 3);
    }

    #[test]
    fn torus_has_genus_one_and_two_spheres_two_components() {
        let m = torus(1.0, 0.3, 24, 12).unwrap();
        let t = Topology::new(&m);
        assert_eq!(t.euler_characteristic(), 0);
        assert_eq!(t.genus(&m.triangles), Some(1));
        // Two disjoint spheres: genus 0 + 0, two components.
        let a = icosphere(1.0, 1).unwrap();
        let n = a.num_vertices();
        let mut both = a.clone();
        both.vertices
            .extend(a.vertices.iter().map(|p| p + nalgebra::Vector3::x() * 5.0));
        both.triangles
            .extend(a.triangles.iter().map(|t| t.map(|i| i + n)));
        let t2 = Topology::new(&both);
        assert_eq!(t2.triangle_components().1, 2);
        assert_eq!(t2.genus(&both.triangles), Some(0));
    }

    #[test]
    fn open_and_bowtie_meshes_are_detected() {
        // Removing one triangle opens the sphere: three boundary edges, genus undefined.
        let mut m = icosphere(1.0, 1).unwrap();
        m.triangles.pop();
        let t = Topology::new(&m);
        assert_eq!(t.boundary_edges().len(), 3);
        assert!(!t.is_closed());
        assert_eq!(t.genus(&m.triangles), None);
        // Two triangles sharing only a vertex (a bow tie) make that vertex non-manifold.
        let tris = [[0, 1, 2], [0, 3, 4]];
        let t = Topology::from_triangles(5, &tris);
        assert_eq!(t.non_manifold_vertices(&tris), vec![0]);
        // Three triangles on one edge make it non-manifold.
        let tris = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        let t = Topology::from_triangles(5, &tris);
        assert_eq!(t.non_manifold_edges().len(), 1);
    }
}

#[cfg(test)]
mod valence_tests {
    use super::Topology;

    /// A disk of `k` triangles around vertex 0 (rim vertices 1..=k, closed when `closed`).
    fn fan(k: usize, closed: bool) -> Vec<[usize; 3]> {
        let last = if closed { k } else { k - 1 };
        (0..last).map(|i| [0, 1 + i, 1 + (i + 1) % k]).collect()
    }

    #[test]
    fn a_million_valence_vertex_has_one_fan_and_a_split_one_two() {
        let k = 1_000_000;
        let tris = fan(k, true);
        let topo = Topology::from_triangles(k + 1, &tris);
        assert_eq!(topo.vertex_fan_count(0, &tris), 1);
        assert!(topo.non_manifold_vertices(&tris).is_empty());
        // Remove two triangles on opposite sides: two fans meet at the centre.
        let split: Vec<[usize; 3]> = tris
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != 0 && i != k / 2)
            .map(|(_, t)| *t)
            .collect();
        let topo = Topology::from_triangles(k + 1, &split);
        assert_eq!(topo.vertex_fan_count(0, &split), 2);
    }

    #[test]
    fn one_face_repeated_many_times_is_one_fan_per_corner() {
        let tris = vec![[0, 1, 2]; 40_000];
        let topo = Topology::from_triangles(3, &tris);
        for v in 0..3 {
            assert_eq!(topo.vertex_fan_count(v, &tris), 1);
        }
        assert!(!topo.is_manifold(&tris));
    }

    #[test]
    fn a_triangle_listed_twice_through_a_repeated_index_is_not_joined_to_itself() {
        // [0, 0, 1] appears twice in vertex 0's list; alone it forms two separate entries, as
        // the pairwise definition says.
        let tris = vec![[0, 0, 1]];
        let topo = Topology::from_triangles(2, &tris);
        assert_eq!(topo.vertex_fan_count(0, &tris), 2);
        // Joined through a different triangle sharing corner 1: one fan.
        let tris = vec![[0, 0, 1], [0, 1, 2]];
        let topo = Topology::from_triangles(3, &tris);
        assert_eq!(topo.vertex_fan_count(0, &tris), 1);
    }
}

#[cfg(test)]
mod component_tests {
    use super::Topology;

    #[test]
    fn components_through_a_heavily_shared_edge_and_apart() {
        // 40k copies of one triangle plus a separate triangle: two components, found in linear
        // time (the copies all share three edges).
        let mut tris = vec![[0, 1, 2]; 40_000];
        tris.push([3, 4, 5]);
        tris.push([0, 1, 6]);
        let topo = Topology::from_triangles(7, &tris);
        let (label, count) = topo.triangle_components();
        assert_eq!(count, 2);
        assert_eq!(label[0], 0);
        assert_eq!(
            label[40_000], 1,
            "numbered in the order of their lowest triangle"
        );
        assert_eq!(label[40_001], 0, "joined through edge (0, 1)");
    }
}
