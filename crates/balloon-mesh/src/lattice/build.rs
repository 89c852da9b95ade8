//! The generator itself ([`build_lattice`]): distance field, ray voting, cells, tetrahedra,
//! smoothing and embedding (the pipeline of the module documentation).

use super::distance::{self, VoxelGrid};
use super::params::{LatticeError, LatticeParams, MAX_VOXELS};
use super::smooth;
use super::types::{CELL_TETS, CORNERS, EmbeddedVertex, Embedding, Lattice, LatticeInfo};
use crate::parallel::prelude::*;
use crate::{TetMesh, TriMesh, tet::signed_tet_volume};
use nalgebra::{Matrix3, Point3, Vector3};

/// The ray directions in voting order: 6 axes, 8 body diagonals, 12 face diagonals.
fn ray_directions() -> Vec<[i64; 3]> {
    let mut dirs = vec![
        [1, 0, 0],
        [-1, 0, 0],
        [0, 1, 0],
        [0, -1, 0],
        [0, 0, 1],
        [0, 0, -1],
    ];
    for s in [
        [1, 1, 1],
        [-1, -1, -1],
        [1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [-1, 1, -1],
        [-1, 1, 1],
        [1, -1, -1],
    ] {
        dirs.push(s);
    }
    for s in [
        [1, 1, 0],
        [-1, -1, 0],
        [1, -1, 0],
        [-1, 1, 0],
        [1, 0, 1],
        [-1, 0, -1],
        [1, 0, -1],
        [-1, 0, 1],
        [0, 1, 1],
        [0, -1, -1],
        [0, 1, -1],
        [0, -1, 1],
    ] {
        dirs.push(s);
    }
    dirs
}

pub(super) fn check_soup(soup: &TriMesh) -> Result<(), LatticeError> {
    if soup.vertices.is_empty() || soup.triangles.is_empty() {
        return Err(LatticeError::EmptySoup {
            vertices: soup.vertices.len(),
            triangles: soup.triangles.len(),
        });
    }
    for (v, p) in soup.vertices.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(LatticeError::NonFiniteVertex { vertex: v });
        }
    }
    for (t, tri) in soup.triangles.iter().enumerate() {
        for &i in tri {
            if i >= soup.vertices.len() {
                return Err(LatticeError::BadIndex {
                    triangle: t,
                    index: i,
                    vertices: soup.vertices.len(),
                });
            }
        }
    }
    Ok(())
}

/// Classifies the voxels by ray voting (step 2 of the module doc). `prob` is `P` per voxel.
fn classify_voxels(grid: &VoxelGrid, prob: &[f64], params: &LatticeParams) -> Vec<bool> {
    let dirs = ray_directions();
    let dirs = &dirs[..params.rays];
    let [nx, ny, nz] = grid.dims;
    let n = [nx as i64, ny as i64, nz as i64];
    // votes[v] = (inside, outside)
    let mut votes = vec![(0u16, 0u16); grid.len()];
    let inside_of = |p: [i64; 3]| p.iter().zip(&n).all(|(&c, &m)| c >= 0 && c < m);
    let at = |p: [i64; 3]| grid.index(p[0] as usize, p[1] as usize, p[2] as usize);
    for d in dirs {
        // Start points: voxels whose predecessor along d lies outside the grid.
        let mut starts = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let p = [i, j, k];
                    if inside_of(p) && !inside_of([i - d[0], j - d[1], k - d[2]]) {
                        starts.push(p);
                    }
                }
            }
        }
        let rays: Vec<Option<Vec<(usize, bool)>>> = starts
            .par_iter()
            .map(|&s| {
                let mut line = Vec::new();
                let mut p = s;
                while inside_of(p) {
                    line.push(at(p));
                    p = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                }
                walk_ray(&line, prob, params.p_in, params.p_subs)
            })
            .collect();
        for labels in rays.into_iter().flatten() {
            for (v, inside) in labels {
                if inside {
                    votes[v].0 += 1;
                } else {
                    votes[v].1 += 1;
                }
            }
        }
    }
    votes.into_iter().map(|(i, o)| i > o).collect()
}

/// Walks one ray over the voxels `line` (in order) and labels them inside/outside with the
/// `P_in` / `P_subs` rule of Sec. 3. Returns `None` (abstain) when the ray ends inside.
fn walk_ray(line: &[usize], prob: &[f64], p_in: f64, p_subs: f64) -> Option<Vec<(usize, bool)>> {
    let p = |k: isize| -> f64 {
        if k < 0 || k as usize >= line.len() {
            0.0
        } else {
            prob[line[k as usize]]
        }
    };
    let mut inside = false;
    let mut armed = true;
    let mut pending = false;
    let mut out = Vec::with_capacity(line.len());
    for (k, &v) in line.iter().enumerate() {
        let k = k as isize;
        let (prev, cur, next) = (p(k - 1), p(k), p(k + 1));
        let slope = next - prev; // central difference of dP/dv
        if armed && cur > p_in && slope > 0.0 {
            pending = true;
            armed = false;
        }
        let mut toggle_after = false;
        if pending && next <= cur {
            // `k` is the voxel nearest the surface: the crossing lies on the side of the closer
            // neighbour (larger P).
            if prev > next {
                inside = !inside;
            } else {
                toggle_after = true;
            }
            pending = false;
        }
        out.push((v, inside));
        if toggle_after {
            inside = !inside;
        }
        if !armed && !pending && cur < p_subs && slope < 0.0 {
            armed = true;
        }
    }
    if inside || pending { None } else { Some(out) }
}

/// Generates the tetrahedral lattice of a triangle soup (Sec. 3; the steps are listed in the
/// module documentation).
///
/// ```
/// use balloon_mesh::{generate::icosphere, lattice::{build_lattice, LatticeParams}};
/// let soup = icosphere(1.0, 2).unwrap();
/// let params = LatticeParams { resolution: 24, ..LatticeParams::default() };
/// let lattice = build_lattice(&soup, &params).unwrap();
/// assert_eq!(lattice.cell_tets.len(), lattice.cells.len());
/// assert!(lattice.tet_mesh.total_volume() > 3.0);
/// ```
pub fn build_lattice(soup: &TriMesh, params: &LatticeParams) -> Result<Lattice, LatticeError> {
    params.validate()?;
    check_soup(soup)?;
    let mut lo = soup.vertices[0];
    let mut hi = lo;
    for p in &soup.vertices {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let extent = hi - lo;
    let longest = extent.max();
    if longest <= 0.0 {
        return Err(LatticeError::ZeroExtent);
    }
    let h = longest / params.resolution as f64;
    let vpc = params.voxels_per_cell;
    let pad = params.band_voxels.ceil() as usize + 1;
    // Cells per axis: cover extent + padding, centred on the bounding box so mirror-symmetric
    // soups give mirror-symmetric grids.
    let mut cell_dims = [0usize; 3];
    for ax in 0..3 {
        let voxels = (extent[ax] / h).ceil() as usize + 2 * pad;
        cell_dims[ax] = voxels.div_ceil(vpc);
    }
    let dims = cell_dims.map(|c| c * vpc);
    let voxels = dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]);
    if voxels > MAX_VOXELS {
        return Err(LatticeError::GridTooLarge {
            voxels,
            limit: MAX_VOXELS,
        });
    }
    let centre = lo + extent * 0.5;
    let origin = centre - Vector3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * (0.5 * h);
    let grid = VoxelGrid {
        origin,
        voxel_size: h,
        dims,
    };

    // 1. Distance field and P.
    let band = params.band_voxels * h;
    let dist = distance::distance_field(&grid, &soup.vertices, &soup.triangles, band);
    let prob: Vec<f64> = dist.iter().map(|d| (1.0 - d / band).max(0.0)).collect();

    // 2. Ray voting.
    let inside = classify_voxels(&grid, &prob, params);
    let inside_voxels = inside.iter().filter(|&&b| b).count();

    // 3. Cells by pseudo density, then hole filling.
    let [cx, cy, cz] = cell_dims;
    let cidx = |i: usize, j: usize, k: usize| i + cx * (j + cy * k);
    let mut kept = vec![false; cx * cy * cz];
    let m_total = (vpc * vpc * vpc) as f64;
    for k in 0..cz {
        for j in 0..cy {
            for i in 0..cx {
                let mut m = 0usize;
                for c in 0..vpc {
                    for b in 0..vpc {
                        for a in 0..vpc {
                            if inside[grid.index(i * vpc + a, j * vpc + b, k * vpc + c)] {
                                m += 1;
                            }
                        }
                    }
                }
                kept[cidx(i, j, k)] = m as f64 / m_total > params.density_threshold;
            }
        }
    }
    let density_cells = kept.iter().filter(|&&b| b).count();
    if density_cells == 0 {
        return Err(LatticeError::NoInterior {
            resolution: params.resolution,
            inside_voxels,
            voxels,
            density_threshold: params.density_threshold,
        });
    }
    for _ in 0..params.fill_iterations {
        let snapshot = kept.clone();
        let mut added = 0;
        for k in 0..cz {
            for j in 0..cy {
                for i in 0..cx {
                    if snapshot[cidx(i, j, k)] {
                        continue;
                    }
                    let mut nb = 0;
                    let (i, j, k) = (i as i64, j as i64, k as i64);
                    for (a, b, c) in [
                        (i - 1, j, k),
                        (i + 1, j, k),
                        (i, j - 1, k),
                        (i, j + 1, k),
                        (i, j, k - 1),
                        (i, j, k + 1),
                    ] {
                        if a >= 0
                            && b >= 0
                            && c >= 0
                            && (a as usize) < cx
                            && (b as usize) < cy
                            && (c as usize) < cz
                            && snapshot[cidx(a as usize, b as usize, c as usize)]
                        {
                            nb += 1;
                        }
                    }
                    if nb > 3 {
                        kept[cidx(i as usize, j as usize, k as usize)] = true;
                        added += 1;
                    }
                }
            }
        }
        if added == 0 {
            break;
        }
    }
    let filled_cells = kept.iter().filter(|&&b| b).count() - density_cells;

    // 4. Welded vertices and five tetrahedra per cell.
    let (vx, vy) = (cx + 1, cy + 1);
    let vidx = |i: usize, j: usize, k: usize| i + vx * (j + vy * k);
    let mut vertex_of = vec![usize::MAX; vx * vy * (cz + 1)];
    let mut grid_of_vertex: Vec<[usize; 3]> = Vec::new();
    let mut vertices = Vec::new();
    let mut cells = Vec::new();
    let mut cell_coords = Vec::new();
    let mut cell_tets = Vec::new();
    let mut tets = Vec::new();
    let cell_size = h * vpc as f64;
    for k in 0..cz {
        for j in 0..cy {
            for i in 0..cx {
                if !kept[cidx(i, j, k)] {
                    continue;
                }
                let corners = CORNERS.map(|[a, b, c]| {
                    let g = vidx(i + a, j + b, k + c);
                    if vertex_of[g] == usize::MAX {
                        vertex_of[g] = vertices.len();
                        grid_of_vertex.push([i + a, j + b, k + c]);
                        vertices.push(
                            origin
                                + Vector3::new((i + a) as f64, (j + b) as f64, (k + c) as f64)
                                    * cell_size,
                        );
                    }
                    vertex_of[g]
                });
                let parity = (i + j + k) % 2;
                let mut ids = [0usize; 5];
                for (t, local) in CELL_TETS[parity].iter().enumerate() {
                    let mut tet = local.map(|l| corners[l]);
                    let v = signed_tet_volume(
                        &vertices[tet[0]],
                        &vertices[tet[1]],
                        &vertices[tet[2]],
                        &vertices[tet[3]],
                    );
                    if v < 0.0 {
                        tet.swap(2, 3);
                    }
                    ids[t] = tets.len();
                    tets.push(tet);
                }
                cells.push(corners);
                cell_coords.push([i, j, k]);
                cell_tets.push(ids);
            }
        }
    }
    let mut tet_mesh = TetMesh::new(vertices, tets);
    let volume_before_smoothing = tet_mesh.total_volume();

    // 5. Smoothing of the surface with axis-aligned umbrellas.
    let surface = smooth::surface_graph(&kept, cell_dims, &vertex_of, &grid_of_vertex);
    let surface_vertices = surface.vertices.len();
    for _ in 0..params.smoothing_iterations {
        smooth::bilaplacian_step(&mut tet_mesh.vertices, &surface, params.smoothing_weight);
        smooth::restore_volume(&mut tet_mesh, volume_before_smoothing);
    }
    for t in 0..tet_mesh.tets.len() {
        let v = tet_mesh.tet_volume(t);
        if v.is_nan() || v <= 0.0 {
            return Err(LatticeError::InvertedTetrahedron { tet: t, volume: v });
        }
    }

    // 6. Embedding.
    let embedding = embed(soup, &tet_mesh, &cell_tets, &cell_coords, &grid, vpc);

    Ok(Lattice {
        tet_mesh,
        cells,
        cell_tets,
        cell_coords,
        embedding,
        info: LatticeInfo {
            voxel_size: h,
            cell_size,
            voxel_dims: dims,
            cell_dims,
            inside_voxels,
            pseudo_volume: inside_voxels as f64 * h * h * h,
            density_cells,
            filled_cells,
            volume_before_smoothing,
            surface_vertices,
        },
    })
}

/// Barycentric coordinates of `p` in tetrahedron `t` (weights of its four vertices).
fn barycentric(mesh: &TetMesh, t: usize, p: &Point3<f64>) -> [f64; 4] {
    let [a, b, c, d] = mesh.tets[t].map(|i| mesh.vertices[i]);
    let m = Matrix3::from_columns(&[b - a, c - a, d - a]);
    match m.try_inverse() {
        Some(inv) => {
            let l = inv * (p - a);
            [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
        }
        None => [0.25; 4],
    }
}

/// Step 6: the tetrahedron of each soup vertex (the one whose smallest barycentric coordinate is
/// largest among the cells near the vertex, searching outward ring by ring).
fn embed(
    soup: &TriMesh,
    mesh: &TetMesh,
    cell_tets: &[[usize; 5]],
    cell_coords: &[[usize; 3]],
    grid: &VoxelGrid,
    vpc: usize,
) -> Embedding {
    let cell_dims = grid.dims.map(|d| d / vpc);
    let mut cell_at = vec![usize::MAX; cell_dims[0] * cell_dims[1] * cell_dims[2]];
    for (c, &[i, j, k]) in cell_coords.iter().enumerate() {
        cell_at[i + cell_dims[0] * (j + cell_dims[1] * k)] = c;
    }
    let cell_size = grid.voxel_size * vpc as f64;
    let max_ring = cell_dims.iter().copied().max().unwrap_or(1) as i64;
    let vertices = soup
        .vertices
        .par_iter()
        .map(|p| {
            let g = [0, 1, 2].map(|ax| ((p[ax] - grid.origin[ax]) / cell_size).floor() as i64);
            let mut best: Option<(f64, usize, [f64; 4])> = None;
            for ring in 1..=max_ring {
                for k in g[2] - ring..=g[2] + ring {
                    for j in g[1] - ring..=g[1] + ring {
                        for i in g[0] - ring..=g[0] + ring {
                            if i < 0
                                || j < 0
                                || k < 0
                                || i >= cell_dims[0] as i64
                                || j >= cell_dims[1] as i64
                                || k >= cell_dims[2] as i64
                            {
                                continue;
                            }
                            let c = cell_at[i as usize
                                + cell_dims[0] * (j as usize + cell_dims[1] * k as usize)];
                            if c == usize::MAX {
                                continue;
                            }
                            for &t in &cell_tets[c] {
                                let w = barycentric(mesh, t, p);
                                let score = w.iter().copied().fold(f64::INFINITY, f64::min);
                                if best.is_none_or(|b| score > b.0) {
                                    best = Some((score, t, w));
                                }
                            }
                        }
                    }
                }
                if best.is_some_and(|b| b.0 >= -1e-9) {
                    break;
                }
                if best.is_some() && ring >= 2 {
                    break;
                }
            }
            // `cells` is non-empty, so some tetrahedron was found.
            let (_, t, w) = best.unwrap_or((0.0, cell_tets[0][0], [0.25; 4]));
            EmbeddedVertex {
                tet: t,
                particles: mesh.tets[t],
                weights: w,
            }
        })
        .collect();
    Embedding {
        vertices,
        triangles: soup.triangles.clone(),
    }
}
