//! Lattice resolution from the model: the resolution is searched for a target cell count
//! (the paper's bodies have hundreds to a few thousand cells) with every part of the soup still
//! resolved, instead of a fixed number of voxels along the longest side, which gives a handful
//! of cells on a torus and none on a thin model.
//!
//! [`size_lattice`] builds the lattice at a first guess from the soup's bounding box, then
//! rescales the number of cells along the longest side `n` by `(target / cells)^(1/3)` (the cell
//! count grows as `n^3`) until the count is within a factor 1.25 of the target; a resolution that
//! leaves no interior is doubled. Once near the target, the resolution is raised by 20 % at a
//! time (at most to [`SizingParams::max_cells`]) while a connected part of the soup lies farther
//! than [`SizingParams::max_gap_cells`] cell sizes from every cell ([`part_gap`]): a small or
//! thin part would otherwise have no cell and be drawn by extrapolation from a distant one.

use super::build::{build_lattice, check_soup};
use super::params::{LatticeError, LatticeParams, MAX_VOXELS};
use super::types::Lattice;
use crate::TriMesh;
use crate::lattice::distance::point_triangle_distance;
use crate::parallel::prelude::*;
use serde::{Deserialize, Serialize};

/// Default target number of cells (`balloon volumetric`'s default body size).
pub const DEFAULT_TARGET_CELLS: usize = 1000;

/// What [`size_lattice`] aims for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SizingParams {
    /// Cells wanted (>= 1). Default [`DEFAULT_TARGET_CELLS`].
    pub target_cells: usize,
    /// Largest cell count the search may reach while resolving thin parts (>= `target_cells`).
    /// Default 4 x the target.
    pub max_cells: usize,
    /// A connected part of the soup farther than this many cell sizes from the lattice (its
    /// nearest vertex, [`part_gap`]) is unresolved (> 0). Default 1.
    pub max_gap_cells: f64,
}

impl Default for SizingParams {
    fn default() -> Self {
        Self::for_cells(DEFAULT_TARGET_CELLS)
    }
}

impl SizingParams {
    /// Aims for `target_cells` cells, the other settings at their defaults.
    pub fn for_cells(target_cells: usize) -> Self {
        Self {
            target_cells,
            max_cells: 4 * target_cells,
            max_gap_cells: 1.0,
        }
    }

    fn validate(&self) -> Result<(), LatticeError> {
        let bad = |name: &'static str, value: String, reason: &str| {
            Err(LatticeError::InvalidParameter {
                name,
                value,
                reason: reason.into(),
            })
        };
        if self.target_cells == 0 || self.target_cells > 10_000_000 {
            return bad(
                "target_cells",
                self.target_cells.to_string(),
                "must be in 1..=10000000",
            );
        }
        if self.max_cells < self.target_cells {
            return bad(
                "max_cells",
                self.max_cells.to_string(),
                "must be >= target_cells",
            );
        }
        if !(self.max_gap_cells.is_finite() && self.max_gap_cells > 0.0) {
            return bad(
                "max_gap_cells",
                self.max_gap_cells.to_string(),
                "must be > 0",
            );
        }
        Ok(())
    }
}

/// One lattice tried by the search.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SizingTry {
    /// Voxels along the longest side.
    pub resolution: usize,
    /// Cells generated (0: no interior).
    pub cells: usize,
    /// [`part_gap`] in cell sizes (0 when there are no cells).
    pub gap_cells: f64,
}

/// How [`size_lattice`] chose the resolution.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sizing {
    /// The resolution chosen (voxels along the longest side).
    pub resolution: usize,
    /// Its cell count.
    pub cells: usize,
    /// Its [`part_gap`] in cell sizes.
    pub gap_cells: f64,
    /// Whether the gap is within [`SizingParams::max_gap_cells`] (every part has cells).
    pub resolved: bool,
    /// Every lattice tried, in order.
    pub tries: Vec<SizingTry>,
}

/// Distance (m) of each soup vertex outside `lattice`: zero for vertices inside their embedding
/// tetrahedron, otherwise the distance to that tetrahedron's faces (an upper bound of the
/// distance to the lattice).
pub fn vertex_gaps(soup: &TriMesh, lattice: &Lattice) -> Vec<f64> {
    let mesh = &lattice.tet_mesh;
    lattice
        .embedding
        .vertices
        .par_iter()
        .zip(soup.vertices.par_iter())
        .map(|(e, p)| {
            if e.weights.iter().all(|&w| w >= -1e-9) {
                return 0.0;
            }
            let [a, b, c, d] = mesh.tets[e.tet].map(|i| mesh.vertices[i]);
            [(a, b, c), (a, b, d), (a, c, d), (b, c, d)]
                .iter()
                .map(|(x, y, z)| point_triangle_distance(p, x, y, z))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Largest distance (m) of a soup vertex outside `lattice` (see [`vertex_gaps`]): how far the
/// drawn surface is extrapolated beyond the body.
pub fn surface_gap(soup: &TriMesh, lattice: &Lattice) -> f64 {
    vertex_gaps(soup, lattice).into_iter().fold(0.0, f64::max)
}

/// Over the connected parts of the soup (vertices joined by triangles), the largest distance
/// (m) from a part to the lattice: the smallest [`vertex_gaps`] entry of the part. Zero when
/// every part touches the lattice; large when a part got no cell near it.
pub fn part_gap(soup: &TriMesh, lattice: &Lattice) -> f64 {
    let gaps = vertex_gaps(soup, lattice);
    let n = soup.vertices.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in &soup.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut used = vec![false; n];
    for t in &soup.triangles {
        for &i in t {
            used[i] = true;
        }
    }
    let mut nearest = vec![f64::INFINITY; n];
    for i in (0..n).filter(|&i| used[i]) {
        let r = root(&mut parent, i);
        nearest[r] = nearest[r].min(gaps[i]);
    }
    nearest
        .into_iter()
        .filter(|g| g.is_finite())
        .fold(0.0, f64::max)
}

/// Builds the lattice of `soup` with the resolution chosen for `sizing` (see the module docs);
/// `params.resolution` is ignored, every other parameter is used as given.
///
/// # Errors
/// The parameters' or the soup's [`LatticeError`]; [`LatticeError::NoInteriorAtAnyResolution`]
/// when even the finest grid allowed ([`MAX_VOXELS`]) keeps no cell.
///
/// ```
/// use balloon_mesh::{generate::torus, lattice::{LatticeParams, SizingParams, size_lattice}};
/// let soup = torus(1.0, 0.25, 48, 16).unwrap();
/// let (lattice, sizing) =
///     size_lattice(&soup, &LatticeParams::default(), &SizingParams::for_cells(300)).unwrap();
/// assert_eq!(lattice.cells.len(), sizing.cells);
/// assert!((240..=375).contains(&sizing.cells), "{sizing:?}");
/// ```
pub fn size_lattice(
    soup: &TriMesh,
    params: &LatticeParams,
    sizing: &SizingParams,
) -> Result<(Lattice, Sizing), LatticeError> {
    sizing.validate()?;
    let vpc = params.voxels_per_cell.max(1);
    // Validate everything else once, with a resolution that is surely valid.
    LatticeParams {
        resolution: (4 * vpc).max(4),
        ..params.clone()
    }
    .validate()?;
    check_soup(soup)?;
    let (lo, hi) = soup
        .vertices
        .iter()
        .fold((soup.vertices[0], soup.vertices[0]), |(lo, hi), p| {
            (lo.inf(p), hi.sup(p))
        });
    let extent = hi - lo;
    let longest = extent.max();
    if longest <= 0.0 {
        return Err(LatticeError::ZeroExtent);
    }
    // Largest cells-along-the-longest-side whose padded grid stays below MAX_VOXELS.
    let pad = 2 * (params.band_voxels.ceil() as usize + 1);
    let voxels_at = |n: usize| -> usize {
        let h = longest / (n * vpc) as f64;
        (0..3)
            .map(|ax| ((extent[ax] / h).ceil() as usize + pad).div_ceil(vpc) * vpc)
            .product()
    };
    let mut n_max = 1usize;
    while n_max < 100_000 && voxels_at(n_max + 1) <= MAX_VOXELS {
        n_max = if voxels_at(2 * n_max) <= MAX_VOXELS {
            2 * n_max
        } else {
            n_max + 1
        };
    }
    // First guess: the soup fills a third of its bounding box.
    let fill = (extent.x * extent.y * extent.z / longest.powi(3)).max(1e-3) / 3.0;
    let target = sizing.target_cells as f64;
    let mut n = ((target / fill).cbrt().round() as usize).clamp(1, n_max);
    let mut tries: Vec<SizingTry> = Vec::new();
    let mut best: Option<(Lattice, SizingTry)> = None;
    let build = |n: usize, tries: &mut Vec<SizingTry>| -> Result<Option<Lattice>, LatticeError> {
        let p = LatticeParams {
            resolution: (n * vpc).max(4),
            ..params.clone()
        };
        match build_lattice(soup, &p) {
            Ok(l) => {
                let gap = part_gap(soup, &l) / l.info.cell_size;
                tries.push(SizingTry {
                    resolution: p.resolution,
                    cells: l.cells.len(),
                    gap_cells: gap,
                });
                Ok(Some(l))
            }
            Err(LatticeError::NoInterior { .. }) => {
                tries.push(SizingTry {
                    resolution: p.resolution,
                    cells: 0,
                    gap_cells: 0.0,
                });
                Ok(None)
            }
            Err(e) => Err(e),
        }
    };
    // Phase 1: reach the target count.
    for _ in 0..12 {
        if tries.iter().any(|t| t.resolution == (n * vpc).max(4)) {
            break;
        }
        let Some(l) = build(n, &mut tries)? else {
            if n >= n_max {
                break;
            }
            n = (2 * n).min(n_max);
            continue;
        };
        let t = *tries.last().expect("just pushed");
        let closer = best.as_ref().is_none_or(|(_, b)| {
            (t.cells as f64 / target).ln().abs() < (b.cells as f64 / target).ln().abs()
        });
        if closer {
            best = Some((l, t));
        }
        let ratio = t.cells as f64 / target;
        if (0.8..=1.25).contains(&ratio) {
            break;
        }
        let next = ((n as f64 * ratio.recip().cbrt()).round() as usize).clamp(1, n_max);
        n = if next == n {
            if ratio < 1.0 {
                n + 1
            } else {
                n.saturating_sub(1).max(1)
            }
        } else {
            next
        };
        if n > n_max {
            break;
        }
    }
    let Some((mut lattice, mut chosen)) = best else {
        let last = tries.last().copied();
        return Err(LatticeError::NoInteriorAtAnyResolution {
            largest_resolution: last.map_or(0, |t| t.resolution),
            density_threshold: params.density_threshold,
        });
    };
    // Phase 2: raise the resolution while a part of the soup lies outside the lattice.
    let mut n = chosen.resolution / vpc;
    while chosen.gap_cells > sizing.max_gap_cells && n < n_max {
        n = ((n as f64 * 1.2).ceil() as usize).min(n_max);
        let Some(l) = build(n, &mut tries)? else {
            continue;
        };
        let t = *tries.last().expect("just pushed");
        if t.cells > sizing.max_cells {
            break;
        }
        if t.gap_cells <= sizing.max_gap_cells {
            (lattice, chosen) = (l, t);
        }
    }
    Ok((
        lattice,
        Sizing {
            resolution: chosen.resolution,
            cells: chosen.cells,
            gap_cells: chosen.gap_cells,
            resolved: chosen.gap_cells <= sizing.max_gap_cells,
            tries,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{icosphere, torus};
    use nalgebra::{Point3, Vector3};

    #[test]
    fn a_thin_torus_gets_the_target_cell_count() {
        // A fixed 24 voxels along the longest side gives 8 cells on a torus of radii 1 / 0.25;
        // sized for 1000 cells it gets 800 to 1250 with the tube resolved.
        let soup = torus(1.0, 0.25, 48, 16).unwrap();
        let (lattice, s) = size_lattice(
            &soup,
            &LatticeParams {
                voxels_per_cell: 3,
                ..LatticeParams::default()
            },
            &SizingParams::default(),
        )
        .unwrap();
        assert!((800..=1250).contains(&s.cells), "{s:?}");
        assert_eq!(lattice.cells.len(), s.cells);
        assert!(s.resolved, "{s:?}");
        assert!(s.tries.len() <= 8, "{s:?}");
    }

    #[test]
    fn a_small_part_next_to_a_large_one_is_resolved() {
        // A large sphere and a far small one (radius 0.3 of the large, about a cell across at
        // 150 cells): whatever resolution the count search lands on, the chosen lattice has
        // cells in the small sphere.
        let big = icosphere(1.0, 2).unwrap();
        let mut small = icosphere(0.3, 2).unwrap();
        for p in &mut small.vertices {
            *p += Vector3::new(3.0, 0.0, 0.0);
        }
        let mut soup = big.clone();
        let n = soup.vertices.len();
        soup.vertices.extend(&small.vertices);
        soup.triangles
            .extend(small.triangles.iter().map(|t| t.map(|i| i + n)));
        let (lattice, s) = size_lattice(
            &soup,
            &LatticeParams::default(),
            &SizingParams::for_cells(150),
        )
        .unwrap();
        assert!(s.resolved, "{s:?}");
        assert!(s.cells > 150 && s.cells <= 600, "{s:?}");
        let c = Point3::new(3.0, 0.0, 0.0);
        let near_small = lattice
            .tet_mesh
            .vertices
            .iter()
            .filter(|p| (*p - c).norm() < 0.2)
            .count();
        assert!(near_small > 0, "{s:?}");
    }

    #[test]
    fn bad_sizing_parameters_are_named() {
        let soup = icosphere(1.0, 1).unwrap();
        let e = size_lattice(
            &soup,
            &LatticeParams::default(),
            &SizingParams::for_cells(0),
        )
        .unwrap_err();
        assert!(e.to_string().contains("target_cells"), "{e}");
    }
}
