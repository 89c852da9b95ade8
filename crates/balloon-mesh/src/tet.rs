//! Tetrahedral meshes.

use crate::MeshError;
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

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of tetrahedra.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// Checks that every tetrahedron index is `< num_vertices()` (call before any method that
    /// indexes vertices on a mesh from outside).
    ///
    /// # Errors
    /// [`MeshError::TetIndexOutOfRange`] naming the first bad tetrahedron.
    pub fn check_indices(&self) -> Result<(), MeshError> {
        let n = self.vertices.len();
        for (t, tet) in self.tets.iter().enumerate() {
            if let Some(&i) = tet.iter().find(|&&i| i >= n) {
                return Err(MeshError::TetIndexOutOfRange {
                    tet: t,
                    index: i,
                    num_vertices: n,
                });
            }
        }
        Ok(())
    }

    /// Tetrahedra whose signed volume is `<= min_volume` (m^3): inverted (negative), flat (zero)
    /// or, with a positive threshold, nearly flat. Assumes in-range indices
    /// ([`Self::check_indices`]).
    pub fn inverted_tets(&self, min_volume: f64) -> Vec<usize> {
        (0..self.tets.len())
            .filter(|&t| self.tet_volume(t) <= min_volume)
            .collect()
    }

    /// Tetrahedra using a vertex twice.
    pub fn repeated_index_tets(&self) -> Vec<usize> {
        self.tets
            .iter()
            .enumerate()
            .filter(|(_, t)| (0..4).any(|i| (i + 1..4).any(|j| t[i] == t[j])))
            .map(|(k, _)| k)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validity_helpers_find_bad_tets() {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        // Swapping two vertices inverts a tetrahedron: its signed volume changes sign.
        let mut m = TetMesh::new(v, vec![[0, 1, 2, 3], [1, 0, 2, 3], [0, 1, 1, 3]]);
        assert!((m.tet_volume(0) - 1.0 / 6.0).abs() < 1e-15);
        assert_eq!(m.inverted_tets(0.0), vec![1, 2]);
        assert_eq!(m.repeated_index_tets(), vec![2]);
        m.check_indices().unwrap();
        m.tets.push([0, 1, 2, 9]);
        let err = m.check_indices().unwrap_err().to_string();
        assert!(
            err.contains("tetrahedron 3") && err.contains("vertex 9"),
            "{err}"
        );
        assert_eq!(m.num_tets(), 4);
        assert_eq!(m.num_vertices(), 4);
    }
}
