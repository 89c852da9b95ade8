//! Triangle soup -> tetrahedral lattice (Diziol, Bender and Bayer 2011, Sec. 3, after
//! Spillmann, Wagner and Teschner 2006).
//!
//! Pipeline of [`build_lattice`]:
//!
//! 1. **Distance field**: unsigned distance `d_min` from each voxel centre of a padded grid over
//!    the soup's bounding box to the closest triangle (exact point-triangle distance, narrow band
//!    of `band_voxels` voxels; see `distance.rs`), and the surface probability
//!    `P(x) = 1 - c |d_min(x)|` with `c = 1 / (band_voxels * voxel_size)`, so `0 <= P <= 1` and
//!    `P = 0` outside the band.
//! 2. **Ray voting**: rays along `rays` lattice directions (6 axes, then 8 body diagonals, then 12
//!    face diagonals) walk the voxel centres. A ray *enters or leaves* the pseudo volume where
//!    `P > P_in` and `dP/dv > 0`; the next change is only accepted after `P < P_subs` with
//!    `dP/dv < 0` in the meantime (Sec. 3). The change is placed at the local maximum of `P` (the
//!    voxel nearest the surface), before or after it depending on which neighbour is closer to the
//!    surface. A ray that ends "inside" (it crossed an odd number of surfaces, e.g. through a hole)
//!    abstains. Each voxel is inside when more non-abstaining rays vote inside than outside.
//! 3. **Cells**: the grid is tiled by cells of `voxels_per_cell^3` voxels; a cell is kept when its
//!    pseudo density `rho(V) = m(V) / M(V)` exceeds `density_threshold`; then, for
//!    `fill_iterations` rounds, every cell with more than three kept face neighbours is added.
//! 4. **Tetrahedra**: five per cell, the decomposition alternating with the parity of
//!    `i + j + k` so that the diagonals of shared faces match (a conforming mesh); lattice
//!    corners are shared between cells (welded), all tetrahedra positively oriented.
//! 5. **Smoothing**: `smoothing_iterations` of the second-order umbrella (bi-Laplacian) filter of
//!    Desbrun et al. 1999 on the surface vertices, with only the *axis-aligned* surface edges of
//!    the unsmoothed lattice in the umbrella (Fig. 2), followed each time by a uniform scaling
//!    about the vertex centroid that restores the tetrahedral volume (volume preservation).
//! 6. **Embedding**: each soup vertex gets the tetrahedron that contains it (or, outside the
//!    lattice, the nearest one) and its (possibly extrapolated) barycentric coordinates, so the
//!    original surface can be drawn from the deformed lattice ([`Embedding::surface`]).

mod build;
mod distance;
mod params;
mod sizing;
mod smooth;
mod types;

pub use build::build_lattice;
pub use params::{LatticeError, LatticeParams, MAX_VOXELS};
pub use sizing::{
    DEFAULT_TARGET_CELLS, Sizing, SizingParams, SizingTry, part_gap, size_lattice, surface_gap,
    vertex_gaps,
};
pub use types::{CELL_TETS, CORNERS, EmbeddedVertex, Embedding, Lattice, LatticeInfo};

#[cfg(test)]
mod tests;
