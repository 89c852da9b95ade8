//! The triangle mesh type shared by every crate of the workspace.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// An indexed triangle mesh.
///
/// * `vertices`: positions in metres (world frame), one `Point3<f64>` per vertex.
/// * `triangles`: vertex indices, counter-clockwise seen from outside for an outward-oriented
///   closed surface (so the divergence-theorem volume is positive).
///
/// Construction does not validate; use [`crate::validate`] for that.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TriMesh {
    /// Vertex positions, metres.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as triples of vertex indices.
    pub triangles: Vec<[usize; 3]>,
}

impl TriMesh {
    /// Creates a mesh from vertices and triangles without checking them.
    pub fn new(vertices: Vec<Point3<f64>>, triangles: Vec<[usize; 3]>) -> Self {
        Self {
            vertices,
            triangles,
        }
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Vertex positions flattened to `[x0, y0, z0, x1, ...]` (length `3 * num_vertices`).
    pub fn positions_flat(&self) -> Vec<f64> {
        self.vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
    }

    /// Replaces the vertex positions from a flat `[x0, y0, z0, ...]` slice.
    ///
    /// # Panics
    /// If `flat.len() != 3 * num_vertices()` (a programming error, not a user error).
    pub fn set_positions_flat(&mut self, flat: &[f64]) {
        assert_eq!(flat.len(), 3 * self.vertices.len(), "flat position length");
        for (p, c) in self.vertices.iter_mut().zip(flat.chunks_exact(3)) {
            *p = Point3::new(c[0], c[1], c[2]);
        }
    }

    /// Scales every vertex about the origin by `factor`.
    pub fn scale(&mut self, factor: f64) {
        for p in &mut self.vertices {
            p.coords *= factor;
        }
    }
}
