//! Volume-preserving second-order Laplacian smoothing of the lattice surface with axis-aligned
//! umbrellas (Diziol, Bender and Bayer 2011, Sec. 3 and Fig. 2; Desbrun et al. 1999).

use crate::TetMesh;
use nalgebra::{Point3, Vector3};
use std::collections::BTreeSet;

/// Surface vertices of the lattice and, for each, its neighbours over axis-aligned *surface*
/// edges of the unsmoothed lattice (indices into `vertices`).
pub(crate) struct SurfaceGraph {
    /// Lattice vertex index of each surface vertex.
    pub vertices: Vec<usize>,
    /// Neighbours (positions in `vertices`).
    pub neighbours: Vec<Vec<usize>>,
}

/// Builds the surface graph: a cell face is on the surface when the cell across it is not kept;
/// its four corners are surface vertices and its four (axis-aligned) edges surface edges. The
/// face diagonals of the tetrahedra are deliberately left out (Fig. 2, right).
pub(crate) fn surface_graph(
    kept: &[bool],
    cell_dims: [usize; 3],
    vertex_of: &[usize],
    grid_of_vertex: &[[usize; 3]],
) -> SurfaceGraph {
    let [cx, cy, cz] = cell_dims;
    let (vx, vy) = (cx + 1, cy + 1);
    let vidx = |p: [usize; 3]| vertex_of[p[0] + vx * (p[1] + vy * p[2])];
    let is_kept = |i: i64, j: i64, k: i64| {
        i >= 0
            && j >= 0
            && k >= 0
            && (i as usize) < cx
            && (j as usize) < cy
            && (k as usize) < cz
            && kept[i as usize + cx * (j as usize + cy * k as usize)]
    };
    let mut edges: BTreeSet<(usize, usize)> = BTreeSet::new();
    for k in 0..cz {
        for j in 0..cy {
            for i in 0..cx {
                if !kept[i + cx * (j + cy * k)] {
                    continue;
                }
                for axis in 0..3 {
                    for side in 0..2usize {
                        let mut nb = [i as i64, j as i64, k as i64];
                        nb[axis] += if side == 0 { -1 } else { 1 };
                        if is_kept(nb[0], nb[1], nb[2]) {
                            continue;
                        }
                        // The face's four corners in cyclic order.
                        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                        let corner = |a: usize, b: usize| {
                            let mut p = [i, j, k];
                            p[axis] += side;
                            p[u] += a;
                            p[w] += b;
                            vidx(p)
                        };
                        let ring = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                        for e in 0..4 {
                            let (a, b) = (ring[e], ring[(e + 1) % 4]);
                            edges.insert((a.min(b), a.max(b)));
                        }
                    }
                }
            }
        }
    }
    let mut slot = vec![usize::MAX; grid_of_vertex.len()];
    let mut vertices = Vec::new();
    for &(a, b) in &edges {
        for v in [a, b] {
            if slot[v] == usize::MAX {
                slot[v] = 0;
                vertices.push(v);
            }
        }
    }
    vertices.sort_unstable();
    for (s, &v) in vertices.iter().enumerate() {
        slot[v] = s;
    }
    let mut neighbours = vec![Vec::new(); vertices.len()];
    for &(a, b) in &edges {
        neighbours[slot[a]].push(slot[b]);
        neighbours[slot[b]].push(slot[a]);
    }
    SurfaceGraph {
        vertices,
        neighbours,
    }
}

/// Umbrella operator `U(x_i) = mean_j(x_j) - x_i` over the graph.
fn umbrella(values: &[Vector3<f64>], graph: &SurfaceGraph) -> Vec<Vector3<f64>> {
    graph
        .neighbours
        .iter()
        .enumerate()
        .map(|(i, nb)| {
            let mut m = Vector3::zeros();
            for &j in nb {
                m += values[j];
            }
            m / nb.len() as f64 - values[i]
        })
        .collect()
}

/// One explicit step of the second-order (bi-Laplacian) filter `x <- x - w U(U(x))` on the
/// surface vertices (stable for `w <= 0.5`).
pub(crate) fn bilaplacian_step(positions: &mut [Point3<f64>], graph: &SurfaceGraph, weight: f64) {
    let x: Vec<Vector3<f64>> = graph
        .vertices
        .iter()
        .map(|&v| positions[v].coords)
        .collect();
    let u = umbrella(&x, graph);
    let u2 = umbrella(&u, graph);
    for (s, &v) in graph.vertices.iter().enumerate() {
        positions[v] -= u2[s] * weight;
    }
}

/// Scales all vertices uniformly about their centroid so that the total tetrahedral volume is
/// `target` again (the volume preservation of Desbrun et al.).
pub(crate) fn restore_volume(mesh: &mut TetMesh, target: f64) {
    let v = mesh.total_volume();
    if v.is_nan() || v <= 0.0 || mesh.vertices.is_empty() {
        return;
    }
    let s = (target / v).cbrt();
    let mut c = Vector3::zeros();
    for p in &mesh.vertices {
        c += p.coords;
    }
    c /= mesh.vertices.len() as f64;
    for p in &mut mesh.vertices {
        p.coords = c + (p.coords - c) * s;
    }
}
