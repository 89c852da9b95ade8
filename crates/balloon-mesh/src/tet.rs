//! Tetrahedral meshes.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// An indexed tetrahedral mesh. A tetrahedron `[a, b, c, d]` is positively oriented when
/// `(b - a) . ((c - a) x (d - a)) > 0`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TetMesh {
    /// Vertex positions, metres.
    pub vertices: Vec<Point3<f64>>,
    /// Tetrahedra as quadruples of vertex indices.
    pub tets: Vec<[usize; 4]>,
}

/// Signed volume of the tetrahedron `(a, b, c, d)`: `(b - a) . ((c - a) x (d - a)) / 6`.
pub fn signed_tet_volume(
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    d: &Point3<f64>,
) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

impl TetMesh {
    /// Creates a tetrahedral mesh without checking it.
    pub fn new(vertices: Vec<Point3<f64>>, tets: Vec<[usize; 4]>) -> Self {
        Self { vertices, tets }
    }

    /// Signed volume of tetrahedron `t`.
    pub fn tet_volume(&self, t: usize) -> f64 {
        let [a, b, c, d] = self.tets[t];
        signed_tet_volume(
            &self.vertices[a],
            &self.vertices[b],
            &self.vertices[c],
            &self.vertices[d],
        )
    }

    /// Sum of the signed volumes of all tetrahedra.
    pub fn total_volume(&self) -> f64 {
        (0..self.tets.len()).map(|t| self.tet_volume(t)).sum()
    }
}
