//! Parameters of the lattice generator ([`LatticeParams`]) and what can go wrong
//! ([`LatticeError`]).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Largest voxel grid accepted (voxels), to turn a typo in `resolution` into an error rather
/// than an out-of-memory abort.
pub const MAX_VOXELS: usize = 64_000_000;

/// Parameters of the lattice generator. Defaults give a coarse but smooth body in well under a
/// second for a few thousand triangles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LatticeParams {
    /// Voxels along the longest side of the soup's bounding box (>= 4). Default 48.
    pub resolution: usize,
    /// Voxels along one side of a lattice cell (>= 1). Default 4 (so 12 cells across).
    pub voxels_per_cell: usize,
    /// Number of ray directions in the vote, 1 to 26: the first 6 are the axis directions, then
    /// the 8 body diagonals, then the 12 face diagonals. Use 6, 14 or 26 for symmetric votes.
    /// Default 14.
    pub rays: usize,
    /// Width of the distance band in voxels (>= 1.5): `c = 1 / (band_voxels * voxel_size)` in
    /// `P = 1 - c |d|`. Default 4.
    pub band_voxels: f64,
    /// `P_in` in (0, 1): a ray changes inside/outside where `P > P_in` and `dP/dv > 0`. A
    /// surface passing midway between two voxel centres only reaches `P = 1 - 0.5 / band_voxels`
    /// at the nearer centre, so keep `P_in` below that (0.875 for the default band). Default 0.8.
    pub p_in: f64,
    /// `P_subs` in (0, `p_in`]: a subsequent change is only reported after `P < P_subs` with
    /// `dP/dv < 0`. Smaller values merge close surfaces (thin parts). Default 0.6.
    pub p_subs: f64,
    /// Pseudo-density threshold in [0, 1): a cell is kept when `m(V)/M(V)` exceeds it. Default 0.5.
    pub density_threshold: f64,
    /// Rounds of hole filling (cells with more than three kept face neighbours are added).
    /// Default 2.
    pub fill_iterations: usize,
    /// Iterations of the volume-preserving second-order Laplacian smoothing. Default 2.
    pub smoothing_iterations: usize,
    /// Step weight of one smoothing iteration, in (0, 0.5] (the explicit bi-Laplacian step is
    /// stable up to 0.5). Default 0.25.
    pub smoothing_weight: f64,
}

impl Default for LatticeParams {
    fn default() -> Self {
        Self {
            resolution: 48,
            voxels_per_cell: 4,
            rays: 14,
            band_voxels: 4.0,
            p_in: 0.8,
            p_subs: 0.6,
            density_threshold: 0.5,
            fill_iterations: 2,
            smoothing_iterations: 2,
            smoothing_weight: 0.25,
        }
    }
}

impl LatticeParams {
    /// Checks every parameter; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), LatticeError> {
        let bad = |name: &'static str, value: String, reason: &str| {
            Err(LatticeError::InvalidParameter {
                name,
                value,
                reason: reason.into(),
            })
        };
        if self.resolution < 4 {
            return bad("resolution", self.resolution.to_string(), "must be >= 4");
        }
        if self.voxels_per_cell == 0 {
            return bad("voxels_per_cell", "0".into(), "must be >= 1");
        }
        if self.voxels_per_cell > self.resolution {
            return bad(
                "voxels_per_cell",
                self.voxels_per_cell.to_string(),
                "must not exceed `resolution`",
            );
        }
        if !(1..=26).contains(&self.rays) {
            return bad("rays", self.rays.to_string(), "must be in 1..=26");
        }
        if !(self.band_voxels.is_finite() && self.band_voxels >= 1.5 && self.band_voxels <= 64.0) {
            return bad(
                "band_voxels",
                self.band_voxels.to_string(),
                "must be in [1.5, 64]",
            );
        }
        if !(self.p_in > 0.0 && self.p_in < 1.0) {
            return bad("p_in", self.p_in.to_string(), "must be in (0, 1)");
        }
        if !(self.p_subs > 0.0 && self.p_subs <= self.p_in) {
            return bad("p_subs", self.p_subs.to_string(), "must be in (0, p_in]");
        }
        if !(self.density_threshold >= 0.0 && self.density_threshold < 1.0) {
            return bad(
                "density_threshold",
                self.density_threshold.to_string(),
                "must be in [0, 1)",
            );
        }
        if self.fill_iterations > 1000 {
            return bad(
                "fill_iterations",
                self.fill_iterations.to_string(),
                "must be <= 1000",
            );
        }
        if self.smoothing_iterations > 1000 {
            return bad(
                "smoothing_iterations",
                self.smoothing_iterations.to_string(),
                "must be <= 1000",
            );
        }
        if !(self.smoothing_weight > 0.0 && self.smoothing_weight <= 0.5) {
            return bad(
                "smoothing_weight",
                self.smoothing_weight.to_string(),
                "must be in (0, 0.5]",
            );
        }
        Ok(())
    }
}

/// What can go wrong generating a lattice.
#[derive(Debug, Error)]
pub enum LatticeError {
    /// A parameter is out of range; the message names it and the allowed range.
    #[error("invalid lattice parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// The parameter (field of [`LatticeParams`]).
        name: &'static str,
        /// Its value.
        value: String,
        /// The allowed range.
        reason: String,
    },
    /// The soup has no vertices or no triangles. Pass a mesh with at least one triangle.
    #[error("empty triangle soup ({vertices} vertices, {triangles} triangles)")]
    EmptySoup {
        /// Vertex count.
        vertices: usize,
        /// Triangle count.
        triangles: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but the soup has {vertices} vertices")]
    BadIndex {
        /// The triangle.
        triangle: usize,
        /// The bad index.
        index: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// The vertex.
        vertex: usize,
    },
    /// The soup's bounding box has zero extent (all vertices coincide).
    #[error("the soup's bounding box has zero size; nothing to fill")]
    ZeroExtent,
    /// The voxel grid would be too large; lower `resolution`.
    #[error("voxel grid of {voxels} voxels exceeds the limit of {limit}; lower `resolution`")]
    GridTooLarge {
        /// Voxels requested.
        voxels: usize,
        /// [`MAX_VOXELS`].
        limit: usize,
    },
    /// No cell passed the pseudo-density threshold: the soup encloses nothing at this resolution
    /// (flat, or too thin). Raise `resolution`, lower `density_threshold` or `p_subs`.
    #[error(
        "no interior at resolution {resolution}: {inside_voxels} of {voxels} voxels inside, no cell above density {density_threshold}; raise `resolution` or size the lattice by cell count (`size_lattice`)"
    )]
    NoInterior {
        /// Voxels along the longest side.
        resolution: usize,
        /// Voxels classified inside.
        inside_voxels: usize,
        /// All voxels.
        voxels: usize,
        /// The threshold used.
        density_threshold: f64,
    },
    /// Even the finest grid allowed ([`MAX_VOXELS`]) keeps no cell: the soup is flat or encloses
    /// nothing. Lower `density_threshold` or `p_subs`, or check that the soup is a surface.
    #[error(
        "no interior at any resolution up to {largest_resolution}: no cell above density {density_threshold}; lower density_threshold or p_subs"
    )]
    NoInteriorAtAnyResolution {
        /// The finest resolution tried (voxels along the longest side).
        largest_resolution: usize,
        /// The threshold used.
        density_threshold: f64,
    },
    /// Smoothing inverted a tetrahedron. Use fewer `smoothing_iterations` or a smaller
    /// `smoothing_weight`.
    #[error(
        "smoothing inverted tetrahedron {tet} (volume {volume:.3e} m^3); lower smoothing_iterations or smoothing_weight"
    )]
    InvertedTetrahedron {
        /// The tetrahedron.
        tet: usize,
        /// Its signed volume.
        volume: f64,
    },
}
