//! What the generator makes: the [`Lattice`] (tetrahedral mesh, cells, the soup's
//! [`Embedding`], [`LatticeInfo`]) and the cell layout ([`CORNERS`], [`CELL_TETS`]).

use crate::{TetMesh, TriMesh};
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// Where one soup vertex sits in the lattice.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EmbeddedVertex {
    /// Tetrahedron index in [`Lattice::tet_mesh`].
    pub tet: usize,
    /// Its four lattice vertices (particles).
    pub particles: [usize; 4],
    /// Barycentric weights (sum 1; some negative when the vertex lies outside the lattice).
    pub weights: [f64; 4],
}

/// The soup embedded in the lattice (free-form deformation by barycentric interpolation).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Embedding {
    /// One entry per soup vertex.
    pub vertices: Vec<EmbeddedVertex>,
    /// The soup's triangles (unchanged).
    pub triangles: Vec<[usize; 3]>,
}

impl Embedding {
    /// Positions of the soup vertices for lattice vertex positions `particles` (m).
    pub fn positions(&self, particles: &[Point3<f64>]) -> Vec<Point3<f64>> {
        self.vertices
            .iter()
            .map(|e| {
                let mut p = Vector3::zeros();
                for (&i, &w) in e.particles.iter().zip(&e.weights) {
                    p += particles[i].coords * w;
                }
                Point3::from(p)
            })
            .collect()
    }

    /// The soup deformed with the lattice: a [`TriMesh`] with the soup's triangles.
    pub fn surface(&self, particles: &[Point3<f64>]) -> TriMesh {
        TriMesh::new(self.positions(particles), self.triangles.clone())
    }

    /// Number of soup vertices lying inside or on their tetrahedron (all weights >= -1e-9).
    pub fn inside_count(&self) -> usize {
        self.vertices
            .iter()
            .filter(|e| e.weights.iter().all(|&w| w >= -1e-9))
            .count()
    }
}

/// Numbers describing a generated lattice.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LatticeInfo {
    /// Voxel edge length (m).
    pub voxel_size: f64,
    /// Cell edge length (m).
    pub cell_size: f64,
    /// Voxel grid dimensions.
    pub voxel_dims: [usize; 3],
    /// Cell grid dimensions.
    pub cell_dims: [usize; 3],
    /// Voxels classified inside the pseudo volume.
    pub inside_voxels: usize,
    /// Pseudo volume `inside_voxels * voxel_size^3` (m^3).
    pub pseudo_volume: f64,
    /// Cells kept by the density threshold.
    pub density_cells: usize,
    /// Cells added by hole filling.
    pub filled_cells: usize,
    /// Tetrahedral volume before smoothing (m^3).
    pub volume_before_smoothing: f64,
    /// Surface (boundary) lattice vertices.
    pub surface_vertices: usize,
}

/// A tetrahedral lattice generated from a soup.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lattice {
    /// The welded, smoothed tetrahedral mesh (vertices = particles), positively oriented.
    pub tet_mesh: TetMesh,
    /// Per cell its eight corner particles, in the order `(0,0,0), (1,0,0), (1,1,0), (0,1,0),
    /// (0,0,1), (1,0,1), (1,1,1), (0,1,1)` of the cell's local axes.
    pub cells: Vec<[usize; 8]>,
    /// Per cell its five tetrahedra (indices into `tet_mesh.tets`).
    pub cell_tets: Vec<[usize; 5]>,
    /// Per cell its integer position in the cell grid.
    pub cell_coords: Vec<[usize; 3]>,
    /// The soup embedded in the lattice.
    pub embedding: Embedding,
    /// Numbers from the generation.
    pub info: LatticeInfo,
}

/// Unit cube corners in the cell corner order of [`Lattice::cells`].
pub const CORNERS: [[usize; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// The five tetrahedra of a cell as local corner indices: `[0]` for even `i + j + k`, `[1]` for
/// odd. The first tetrahedron is the central one; the other four cut off the remaining corners.
/// Neighbouring cells have opposite parity, so both use the same diagonal on the shared face.
pub const CELL_TETS: [[[usize; 4]; 5]; 2] = [
    [
        [1, 3, 4, 6],
        [0, 1, 3, 4],
        [2, 3, 1, 6],
        [5, 4, 6, 1],
        [7, 3, 4, 6],
    ],
    [
        [0, 2, 5, 7],
        [1, 0, 2, 5],
        [3, 2, 0, 7],
        [4, 5, 7, 0],
        [6, 7, 5, 2],
    ],
];
