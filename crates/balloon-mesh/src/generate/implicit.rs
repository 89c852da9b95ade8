//! Meshing of implicit surfaces `{x : f(x) = 0}` (inside where `f < 0`) by marching tetrahedra
//! followed by tangential relaxation re-projected onto the surface.
//!
//! Why marching tetrahedra: with every grid value non-zero and the grid's outer layer outside,
//! each tetrahedron of the (globally consistent, Kuhn) 6-tet split of each cube contributes a
//! triangle or a quad whose edges are shared with exactly one neighbour, so the output is a closed
//! 2-manifold by construction, without the ambiguous cases of marching cubes; orientation follows
//! combinatorially from the sign of each tetrahedron. Its triangles are poorly shaped, which the
//! relaxation fixes. Every crossed grid edge gets exactly one vertex shared by all tetrahedra
//! around it, so no welding is needed.
//!
//! Steps: (1) sample `f` on the grid; values with `|f| < clamp_fraction * h` are pushed to
//! `+-clamp_fraction * h` (so no vertex lands on a grid node and no triangle is degenerate) and the
//! outer layer of nodes is forced outside (so the surface is closed); (2) marching tetrahedra, one
//! vertex per crossed grid edge; (3) `relax_iterations` of tangential Laplacian smoothing (move each
//! vertex towards the mean of its one-ring, minus the component along the surface normal
//! `grad f / |grad f|`), each followed by two Newton projections `x -= f(x) grad f / |grad f|^2`
//! back onto the surface; (4) edge flips that improve the smallest angle where they keep the mesh
//! manifold, then a final relaxation pass.

use crate::geometry::Aabb;
use crate::topology::Topology;
use crate::{MeshError, TriMesh};
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// Parameters of [`implicit_surface`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitParams {
    /// Grid spacing `h` (m). Smaller is finer; the vertex count grows like `area / h^2`.
    pub cell_size: f64,
    /// Tangential relaxation iterations (default 8; 0 keeps raw marching-tetrahedra output).
    pub relax_iterations: usize,
    /// Grid values closer to zero than `clamp_fraction * h` are pushed away from zero
    /// (default 0.05).
    pub clamp_fraction: f64,
}

impl Default for ImplicitParams {
    fn default() -> Self {
        Self {
            cell_size: 0.01,
            relax_iterations: 8,
            clamp_fraction: 0.05,
        }
    }
}

/// Central-difference gradient of `f` at `p` with step `eps`.
fn fd_gradient(f: &impl Fn(&Point3<f64>) -> f64, p: &Point3<f64>, eps: f64) -> Vector3<f64> {
    let mut g = Vector3::zeros();
    for k in 0..3 {
        let mut a = *p;
        let mut b = *p;
        a[k] += eps;
        b[k] -= eps;
        g[k] = (f(&a) - f(&b)) / (2.0 * eps);
    }
    g
}

/// Parity (0 even, 1 odd) of a permutation of `0..4` given as positions.
fn parity(p: [usize; 4]) -> usize {
    let mut inv = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            if p[i] > p[j] {
                inv += 1;
            }
        }
    }
    inv % 2
}

/// Meshes the zero level set of `f` (negative inside, positive outside; ideally a signed
/// distance in metres) inside `bounds`, enlarged by two cells on every side.
///
/// The result is closed, 2-manifold and outward-oriented by construction (see the module doc);
/// surface parts crossing `bounds` are capped by the boundary of the grid.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a non-positive or non-finite `cell_size`, a grid of more
/// than 2^27 nodes, a non-finite field value, or a field with no zero crossing in the grid.
pub fn implicit_surface(
    f: impl Fn(&Point3<f64>) -> f64,
    bounds: Aabb,
    params: &ImplicitParams,
) -> Result<TriMesh, MeshError> {
    let h = params.cell_size;
    if !(h.is_finite() && h > 0.0) {
        return Err(MeshError::InvalidParameter {
            name: "cell_size",
            value: h.to_string(),
            reason: "must be a positive finite length in metres".into(),
        });
    }
    if !(params.clamp_fraction.is_finite()
        && params.clamp_fraction > 0.0
        && params.clamp_fraction < 0.5)
    {
        return Err(MeshError::InvalidParameter {
            name: "clamp_fraction",
            value: params.clamp_fraction.to_string(),
            reason: "must be in (0, 0.5)".into(),
        });
    }
    let ext = bounds.extent();
    if !(ext.iter().all(|e| e.is_finite() && *e >= 0.0)) {
        return Err(MeshError::InvalidParameter {
            name: "bounds",
            value: format!("{:?}..{:?}", bounds.min, bounds.max),
            reason: "must be finite with min <= max".into(),
        });
    }
    let origin = bounds.min - Vector3::repeat(2.0 * h);
    let dims: Vec<usize> = (0..3).map(|k| (ext[k] / h).ceil() as usize + 5).collect();
    let (nx, ny, nz) = (dims[0], dims[1], dims[2]);
    let total = nx as f64 * ny as f64 * nz as f64;
    if total > (1u64 << 27) as f64 {
        return Err(MeshError::InvalidParameter {
            name: "cell_size",
            value: h.to_string(),
            reason: format!("gives a grid of {total:.0} nodes (max 2^27); use a larger cell"),
        });
    }
    let node = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    let pos = |i: usize, j: usize, k: usize| {
        origin + Vector3::new(i as f64 * h, j as f64 * h, k as f64 * h)
    };
    let delta = params.clamp_fraction * h;
    let mut val = vec![0.0f64; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let mut v = f(&pos(i, j, k));
                if !v.is_finite() {
                    return Err(MeshError::InvalidParameter {
                        name: "f",
                        value: v.to_string(),
                        reason: format!("non-finite field value at {:?}", pos(i, j, k)),
                    });
                }
                let border =
                    i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                if border {
                    v = v.max(delta);
                } else if v.abs() < delta {
                    v = if v < 0.0 { -delta } else { delta };
                }
                val[node(i, j, k)] = v;
            }
        }
    }
    // Kuhn split: tet = (000, e_p0, e_p0 + e_p1, 111) for each permutation p; its orientation
    // sign is the permutation's parity, fixed by swapping its two middle vertices.
    let perms = [
        [0, 1, 2],
        [1, 2, 0],
        [2, 0, 1],
        [0, 2, 1],
        [2, 1, 0],
        [1, 0, 2],
    ];
    let mut tets: Vec<[[usize; 3]; 4]> = Vec::new();
    for (pi, p) in perms.iter().enumerate() {
        let mut c1 = [0usize; 3];
        c1[p[0]] = 1;
        let mut c2 = c1;
        c2[p[1]] = 1;
        let t = if pi < 3 {
            [[0, 0, 0], c1, c2, [1, 1, 1]]
        } else {
            [[0, 0, 0], c2, c1, [1, 1, 1]]
        };
        tets.push(t);
    }
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    let mut edge_vertex: HashMap<(usize, usize), usize> = HashMap::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    let mut cut = |a: (usize, Point3<f64>, f64),
                   b: (usize, Point3<f64>, f64),
                   vertices: &mut Vec<Point3<f64>>| {
        let key = (a.0.min(b.0), a.0.max(b.0));
        *edge_vertex.entry(key).or_insert_with(|| {
            let t = a.2 / (a.2 - b.2);
            vertices.push(a.1 + (b.1 - a.1) * t);
            vertices.len() - 1
        })
    };
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let mut any_in = false;
                let mut any_out = false;
                for c in 0..8 {
                    let v = val[node(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2))];
                    any_in |= v < 0.0;
                    any_out |= v > 0.0;
                }
                if !(any_in && any_out) {
                    continue;
                }
                for tet in &tets {
                    let corner = |c: usize| {
                        let (a, b, d) = (i + tet[c][0], j + tet[c][1], k + tet[c][2]);
                        let n = node(a, b, d);
                        (n, pos(a, b, d), val[n])
                    };
                    let cs = [corner(0), corner(1), corner(2), corner(3)];
                    let ins: Vec<usize> = (0..4).filter(|&c| cs[c].2 < 0.0).collect();
                    let outs: Vec<usize> = (0..4).filter(|&c| cs[c].2 > 0.0).collect();
                    match ins.len() {
                        1 | 3 => {
                            let (lone, rest) = if ins.len() == 1 {
                                (ins[0], &outs)
                            } else {
                                (outs[0], &ins)
                            };
                            let (mut a, mut b, c) = (rest[0], rest[1], rest[2]);
                            if parity([lone, a, b, c]) == 1 {
                                std::mem::swap(&mut a, &mut b);
                            }
                            // Now (lone, a, b, c) is positively oriented: the triangle
                            // (la, lb, lc) faces away from `lone`.
                            let la = cut(cs[lone], cs[a], &mut vertices);
                            let lb = cut(cs[lone], cs[b], &mut vertices);
                            let lc = cut(cs[lone], cs[c], &mut vertices);
                            if ins.len() == 1 {
                                triangles.push([la, lb, lc]);
                            } else {
                                triangles.push([la, lc, lb]);
                            }
                        }
                        2 => {
                            let (p, q) = (ins[0], ins[1]);
                            let (mut r, mut s) = (outs[0], outs[1]);
                            if parity([p, q, r, s]) == 1 {
                                std::mem::swap(&mut r, &mut s);
                            }
                            // Quad (pr, ps, qs, qr) faces from {p, q} to {r, s}.
                            let q1 = cut(cs[p], cs[r], &mut vertices);
                            let q2 = cut(cs[p], cs[s], &mut vertices);
                            let q3 = cut(cs[q], cs[s], &mut vertices);
                            let q4 = cut(cs[q], cs[r], &mut vertices);
                            let d13 = (vertices[q1] - vertices[q3]).norm_squared();
                            let d24 = (vertices[q2] - vertices[q4]).norm_squared();
                            if d13 <= d24 {
                                triangles.push([q1, q2, q3]);
                                triangles.push([q1, q3, q4]);
                            } else {
                                triangles.push([q2, q3, q4]);
                                triangles.push([q2, q4, q1]);
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
    }
    if triangles.is_empty() {
        return Err(MeshError::InvalidParameter {
            name: "f",
            value: "field".into(),
            reason: "has no zero crossing inside the bounds (no surface to mesh)".into(),
        });
    }
    let mut mesh = TriMesh::new(vertices, triangles);
    let eps = 1e-4 * h;
    let project = |p: Point3<f64>| {
        let mut x = p;
        for _ in 0..3 {
            let g = fd_gradient(&f, &x, eps);
            let g2 = g.norm_squared();
            if g2 <= 1e-24 {
                break;
            }
            let step = g * (f(&x) / g2);
            // Never jump further than a cell: keeps the projection local.
            let len = step.norm();
            x -= if len > h { step * (h / len) } else { step };
        }
        x
    };
    if params.relax_iterations > 0 {
        relax(&mut mesh, &f, eps, params.relax_iterations, &project);
        improve_by_flips(&mut mesh, 3);
        relax(&mut mesh, &f, eps, 3, &project);
    }
    Ok(mesh)
}

/// Tangential Laplacian relaxation with re-projection (module doc, step 3).
fn relax(
    mesh: &mut TriMesh,
    f: &impl Fn(&Point3<f64>) -> f64,
    eps: f64,
    iterations: usize,
    project: &impl Fn(Point3<f64>) -> Point3<f64>,
) {
    let topo = Topology::new(mesh);
    let mut next = mesh.vertices.clone();
    for _ in 0..iterations {
        for v in 0..mesh.num_vertices() {
            let nb = topo.vertex_neighbors(v);
            if nb.is_empty() {
                continue;
            }
            let x = mesh.vertices[v];
            let c: Vector3<f64> = nb
                .iter()
                .map(|&u| mesh.vertices[u].coords)
                .sum::<Vector3<f64>>()
                / nb.len() as f64;
            let n = fd_gradient(f, &x, eps)
                .try_normalize(1e-300)
                .unwrap_or_else(Vector3::zeros);
            let mut d = c - x.coords;
            d -= n * n.dot(&d);
            next[v] = project(x + d);
        }
        std::mem::swap(&mut mesh.vertices, &mut next);
    }
}

/// Smallest angle (radians) of triangle `(a, b, c)`.
fn min_angle(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    crate::geometry::triangle_angles(a, b, c)
        .into_iter()
        .fold(f64::INFINITY, f64::min)
}

/// Flips interior edges whose flip raises the smaller minimum angle of the two triangles, when
/// the new edge does not exist yet (which keeps the mesh a 2-manifold) and the two new triangles
/// keep the orientation of the old ones (their normals agree with the old average normal).
fn improve_by_flips(mesh: &mut TriMesh, rounds: usize) {
    for _ in 0..rounds {
        let topo = Topology::new(mesh);
        let mut edge_set: std::collections::HashSet<(usize, usize)> =
            topo.edges().iter().map(|e| (e[0], e[1])).collect();
        let mut touched = vec![false; mesh.num_triangles()];
        let mut flips = 0;
        for e in 0..topo.num_edges() {
            let ts = topo.edge_triangles(e);
            if ts.len() != 2 || touched[ts[0]] || touched[ts[1]] {
                continue;
            }
            let [a, b] = topo.edges()[e];
            let (t0, t1) = (ts[0], ts[1]);
            // Orient so that t0 contains the directed edge (a, b).
            let tri0 = mesh.triangles[t0];
            let k0 = (0..3).find(|&k| tri0[k] == a && tri0[(k + 1) % 3] == b);
            let (a, b) = if k0.is_some() { (a, b) } else { (b, a) };
            let tri0 = mesh.triangles[t0];
            let tri1 = mesh.triangles[t1];
            let c = tri0.into_iter().find(|&v| v != a && v != b);
            let d = tri1.into_iter().find(|&v| v != a && v != b);
            let (Some(c), Some(d)) = (c, d) else { continue };
            if c == d || edge_set.contains(&(c.min(d), c.max(d))) {
                continue;
            }
            let p = &mesh.vertices;
            let old = min_angle(&p[a], &p[b], &p[c]).min(min_angle(&p[b], &p[a], &p[d]));
            let new = min_angle(&p[c], &p[d], &p[b]).min(min_angle(&p[d], &p[c], &p[a]));
            let n_old = (p[b] - p[a]).cross(&(p[c] - p[a])) + (p[a] - p[b]).cross(&(p[d] - p[b]));
            let n1 = (p[d] - p[c]).cross(&(p[b] - p[c]));
            let n2 = (p[c] - p[d]).cross(&(p[a] - p[d]));
            if new > old + 1e-3 && n1.dot(&n_old) > 0.0 && n2.dot(&n_old) > 0.0 {
                // (a, b, c) + (b, a, d) -> (c, d, b) + (d, c, a).
                mesh.triangles[t0] = [c, d, b];
                mesh.triangles[t1] = [d, c, a];
                edge_set.remove(&(a.min(b), a.max(b)));
                edge_set.insert((c.min(d), c.max(d)));
                touched[t0] = true;
                touched[t1] = true;
                flips += 1;
            }
        }
        if flips == 0 {
            break;
        }
    }
}

/// Helpers shared with the tests of other generators.
#[cfg(test)]
pub(crate) mod tests_support {
    use super::*;

    /// Central-difference gradient of `f` at `p`.
    pub(crate) fn gradient(
        f: &impl Fn(&Point3<f64>) -> f64,
        p: &Point3<f64>,
        eps: f64,
    ) -> Vector3<f64> {
        fd_gradient(f, p, eps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{enclosed_volume, min_angle_degrees};
    use crate::validate::validate_closed_manifold;

    #[test]
    fn sphere_sdf_gives_valid_sphere() {
        // The level set of |x| - r is the sphere: volume -> 4/3 pi r^3, all vertices at radius r.
        let r = 0.1;
        let bounds = Aabb {
            min: Point3::new(-r, -r, -r),
            max: Point3::new(r, r, r),
        };
        let m = implicit_surface(
            |p| p.coords.norm() - r,
            bounds,
            &ImplicitParams {
                cell_size: 0.02,
                ..Default::default()
            },
        )
        .unwrap();
        validate_closed_manifold(&m).unwrap();
        let v = enclosed_volume(&m);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((v / exact - 1.0).abs() < 0.03, "{v} vs {exact}");
        for p in &m.vertices {
            assert!((p.coords.norm() - r).abs() < 1e-6 * r);
        }
        let a = min_angle_degrees(&m).unwrap();
        assert!(a > 10.0, "min angle {a}");
    }

    #[test]
    fn torus_sdf_gives_genus_one() {
        // The level set of the torus distance has genus 1 and volume 2 pi^2 R r^2.
        let (big, small) = (0.1, 0.04);
        let f = |p: &Point3<f64>| {
            let q = (p.x * p.x + p.y * p.y).sqrt() - big;
            (q * q + p.z * p.z).sqrt() - small
        };
        let e = big + small;
        let bounds = Aabb {
            min: Point3::new(-e, -e, -small),
            max: Point3::new(e, e, small),
        };
        let m = implicit_surface(
            f,
            bounds,
            &ImplicitParams {
                cell_size: 0.01,
                ..Default::default()
            },
        )
        .unwrap();
        validate_closed_manifold(&m).unwrap();
        let topo = Topology::new(&m);
        assert_eq!(topo.genus(&m.triangles), Some(1));
        let exact = 2.0 * std::f64::consts::PI.powi(2) * big * small * small;
        let v = enclosed_volume(&m);
        assert!((v / exact - 1.0).abs() < 0.03, "{v} vs {exact}");
        assert!(min_angle_degrees(&m).unwrap() > 10.0);
    }

    #[test]
    fn raw_output_is_closed_and_bad_parameters_fail() {
        let bounds = Aabb {
            min: Point3::new(-1.0, -1.0, -1.0),
            max: Point3::new(1.0, 1.0, 1.0),
        };
        // A box-shaped field touching grid nodes exactly exercises the clamping.
        let f = |p: &Point3<f64>| p.x.abs().max(p.y.abs()).max(p.z.abs()) - 0.5;
        let m = implicit_surface(
            f,
            bounds,
            &ImplicitParams {
                cell_size: 0.25,
                relax_iterations: 0,
                ..Default::default()
            },
        )
        .unwrap();
        validate_closed_manifold(&m).unwrap();
        assert!(
            implicit_surface(
                f,
                bounds,
                &ImplicitParams {
                    cell_size: 0.0,
                    ..Default::default()
                }
            )
            .is_err()
        );
        assert!(implicit_surface(|_| 1.0, bounds, &ImplicitParams::default()).is_err());
        assert!(implicit_surface(|_| f64::NAN, bounds, &ImplicitParams::default()).is_err());
    }
}
