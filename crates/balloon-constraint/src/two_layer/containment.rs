//! The inner layer kept inside the closed outer layer (Song 2009, Sec. 4.6.2) by a closest-point
//! test against the whole outer surface.
//!
//! The paper tests each inner particle against the tangent plane of its outer partner. That
//! plane is only a local approximation: on a bent outer layer an inner particle can be behind
//! the plane and still outside the surface (or the other way round). Here each inner particle
//! `p` is tested against the outer surface itself:
//!
//! 1. **Closest point.** `q` is the closest point of the outer triangles (segments in 2D) to
//!    `p`, found by a walk over the face adjacency: start from the face found last time and the
//!    faces around the partner, move to an adjacent face while that is closer (for a vertex
//!    feature, to any face around the vertex). On a smooth layer the walk ends at the global
//!    closest point; on a layer crumpled against the floor it can stop at a local minimum.
//! 2. **Inside test.** With `N` the angle-weighted pseudo-normal of the feature `q` lies on
//!    (the face normal inside a face, the sum of the two unit face normals on an edge, the
//!    angle-weighted sum of the unit normals of the faces around a vertex; Baerentzen and
//!    Aanaes 2005), `p` is outside when `(p - q) . N > 0`: exact for the global closest point
//!    of a closed surface that does not cross itself. Because neither is guaranteed, an
//!    "outside" (or "on the surface", within half the margin below) verdict is confirmed by the
//!    generalised winding number (`O(faces)`, only for these few particles); a particle the
//!    winding number finds inside gets the exact distance over all faces as its clearance.
//! 3. **Response.** An escaped particle (winding number below 1/2) is put just inside, at
//!    `q - m u` with `u` the unit outward direction from `q` and `m` the margin, `1e-3` of the
//!    longest edge of the closest face. Where the layer is folded and that point is still
//!    outside by winding number, it goes back to where it was at the end of the last call if
//!    that is inside now, else 10 or 100 margins deep. If it still moves outward relative to
//!    the surface point, `v_r = (v_p - sum_k w_k v_k) . u > 0` (`w_k` the barycentric weights
//!    of `q` on the face's vertices), the impulse `J = (1 + e) v_r / (1/m_p + sum_k w_k^2 /
//!    m_k)` along `u` is exchanged between the particle and the face's vertices: momentum is
//!    conserved, the relative normal velocity becomes `-e v_r`, and kinetic energy never grows
//!    for `e <= 1`. Fixed particles are neither moved nor pushed.
//!
//! **Cost.** A particle found inside at distance `d` keeps a clearance `d`; every call
//! subtracts how far it moved and the largest move of any outer vertex (a surface whose
//! vertices move by at most `delta` moves by at most `delta`), and the particle is tested
//! again only when its clearance is used up (a corrected particle is tested again at the next
//! call). Deep inner particles are therefore tested every few tens of steps, and the
//! containment costs `O(n)` per step while no inner particle is near the outer layer.
//! **Limitation:** the clearance of an inside verdict is the walk's distance, which on a
//! crumpled layer can exceed the true distance; the long bouncing test of
//! `tests/integration/two_layer.rs` checks every 10th step by an independent winding number.

use super::winding::{polygon_winding_number, winding_number};
use crate::ConstraintError;
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// Where on a face (segment in 2D) its closest point lies.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Feature {
    /// Inside the face (inside the segment).
    Face,
    /// On edge `k` of the face, from its local vertex `k` to `k + 1` (3D only).
    Edge(usize),
    /// On local vertex `k`.
    Vertex(usize),
}

/// The closest point of one face to a query point.
#[derive(Clone, Copy, Debug)]
struct Closest {
    face: usize,
    dist2: f64,
    point: Vector3<f64>,
    weights: [f64; 3],
    feature: Feature,
}

#[derive(Clone, Debug)]
enum Topology {
    /// Closed counter-clockwise polygon in the `xy` plane: segment `j` from `j` to `j + 1`.
    Polygon,
    /// Closed outward-oriented triangle surface.
    Surface {
        triangles: Vec<[usize; 3]>,
        /// Per face, per local edge `k` (vertex `k` to `k + 1`): the face across that edge.
        across: Vec<[usize; 3]>,
        /// Faces around each vertex (CSR: `vertex_faces[start[v]..start[v + 1]]`).
        start: Vec<usize>,
        vertex_faces: Vec<usize>,
    },
}

/// Keeps inner particles `inner_offset + j` inside the closed outer layer whose vertex `j` is
/// particle `outer_offset + j` (`j < count`); see the module documentation for the method. It
/// keeps per-particle hints and clearances from call to call: use one per body.
#[derive(Clone, Debug)]
pub struct LayerContainment {
    topology: Topology,
    inner_offset: usize,
    outer_offset: usize,
    count: usize,
    /// Per inner particle: the face its closest point was on last time.
    hint: Vec<usize>,
    /// Per inner particle: a distance it is known to be inside by (<= 0: test it).
    clearance: Vec<f64>,
    /// Positions of both layers at the end of the last call (empty before the first).
    previous: Vec<f64>,
}

/// Relative depth (of the longest edge of the closest face) at which escaped particles are put.
const MARGIN: f64 = 1e-3;
/// Most faces one walk visits before it stops (far more than a two-layer body needs).
const MAX_WALK: usize = 10_000;

fn point(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

/// Barycentric weights of the point of triangle `abc` closest to `p` (Ericson, "Real-Time
/// Collision Detection", Sec. 5.1.5): exact zeros outside the face's interior region.
fn triangle_weights(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    [1.0 - v - w, v, w]
}

fn feature_of(w: &[f64; 3]) -> Feature {
    match (w[0] == 0.0, w[1] == 0.0, w[2] == 0.0) {
        (false, false, false) => Feature::Face,
        (false, false, true) => Feature::Edge(0),
        (true, false, false) => Feature::Edge(1),
        (false, true, false) => Feature::Edge(2),
        (false, true, true) => Feature::Vertex(0),
        (true, false, true) => Feature::Vertex(1),
        _ => Feature::Vertex(2),
    }
}

fn unit_normal(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Vector3<f64> {
    (b - a)
        .cross(&(c - a))
        .try_normalize(0.0)
        .unwrap_or_default()
}

impl LayerContainment {
    /// Containment by a closed outward-oriented triangle surface (local vertex indices
    /// `0..count`). Errors unless every edge is shared by exactly two faces with opposite
    /// orientations.
    ///
    /// # Errors
    /// [`ConstraintError::InvalidLayerSurface`] naming the first edge, face or vertex at fault.
    pub fn surface(
        inner_offset: usize,
        outer_offset: usize,
        count: usize,
        triangles: &[[usize; 3]],
    ) -> Result<Self, ConstraintError> {
        let bad = |reason: String| ConstraintError::InvalidLayerSurface {
            triangles: triangles.len(),
            vertices: count,
            reason,
        };
        let mut directed: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
        for (f, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a >= count || b >= count {
                    return Err(bad(format!("face {f} refers to a vertex >= {count}")));
                }
                if directed.insert((a, b), (f, k)).is_some() {
                    return Err(bad(format!(
                        "edge {a}-{b} is used twice in the same direction (face {f}): not a closed oriented manifold"
                    )));
                }
            }
        }
        let mut across = vec![[usize::MAX; 3]; triangles.len()];
        for (&(a, b), &(f, k)) in &directed {
            match directed.get(&(b, a)) {
                Some(&(g, _)) => across[f][k] = g,
                None => {
                    return Err(bad(format!(
                        "edge {a}-{b} has a single face: the outer layer must be closed"
                    )));
                }
            }
        }
        let mut start = vec![0usize; count + 1];
        for t in triangles {
            for &v in t {
                start[v + 1] += 1;
            }
        }
        for v in 0..count {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut vertex_faces = vec![0; start[count]];
        for (f, t) in triangles.iter().enumerate() {
            for &v in t {
                vertex_faces[fill[v]] = f;
                fill[v] += 1;
            }
        }
        if let Some(v) = (0..count).find(|&v| start[v] == start[v + 1]) {
            return Err(bad(format!("vertex {v} belongs to no face")));
        }
        let hint = (0..count).map(|v| vertex_faces[start[v]]).collect();
        Ok(Self {
            topology: Topology::Surface {
                triangles: triangles.to_vec(),
                across,
                start,
                vertex_faces,
            },
            inner_offset,
            outer_offset,
            count,
            hint,
            clearance: vec![f64::NEG_INFINITY; count],
            previous: Vec::new(),
        })
    }

    /// Containment by the closed counter-clockwise polygon `0, 1, ..., count - 1` in the `xy`
    /// plane.
    pub fn polygon(inner_offset: usize, outer_offset: usize, count: usize) -> Self {
        Self {
            topology: Topology::Polygon,
            inner_offset,
            outer_offset,
            count,
            hint: (0..count).collect(),
            clearance: vec![f64::NEG_INFINITY; count],
            previous: Vec::new(),
        }
    }

    /// Vertex `k` (global particle index) of face `f`, and the number of its vertices.
    fn face_vertices(&self, f: usize) -> ([usize; 3], usize) {
        let o = self.outer_offset;
        match &self.topology {
            Topology::Polygon => ([o + f, o + (f + 1) % self.count, o], 2),
            Topology::Surface { triangles, .. } => {
                let t = triangles[f];
                ([o + t[0], o + t[1], o + t[2]], 3)
            }
        }
    }

    fn closest_on(&self, x: &[f64], p: &Vector3<f64>, f: usize) -> Closest {
        let (v, nv) = self.face_vertices(f);
        let (a, b) = (point(x, v[0]), point(x, v[1]));
        let (weights, feature) = if nv == 2 {
            let e = b - a;
            let len2 = e.norm_squared();
            let t = if len2 > 0.0 {
                ((p - a).dot(&e) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let feature = if t == 0.0 {
                Feature::Vertex(0)
            } else if t == 1.0 {
                Feature::Vertex(1)
            } else {
                Feature::Face
            };
            ([1.0 - t, t, 0.0], feature)
        } else {
            let c = point(x, v[2]);
            let w = triangle_weights(p, &a, &b, &c);
            (w, feature_of(&w))
        };
        let mut q = a * weights[0] + b * weights[1];
        if nv == 3 {
            q += point(x, v[2]) * weights[2];
        }
        let dist2 = (p - q).norm_squared();
        Closest {
            face: f,
            dist2: if dist2.is_finite() {
                dist2
            } else {
                f64::INFINITY
            },
            point: q,
            weights,
            feature,
        }
    }

    /// Faces next to `c` to try in the walk: those across its edges (its neighbouring
    /// segments in 2D), and all faces around its closest vertex.
    fn neighbours(&self, c: &Closest, out: &mut Vec<usize>) {
        out.clear();
        match &self.topology {
            Topology::Polygon => {
                let n = self.count;
                out.extend([(c.face + n - 1) % n, (c.face + 1) % n]);
            }
            Topology::Surface {
                triangles,
                across,
                start,
                vertex_faces,
            } => {
                out.extend_from_slice(&across[c.face]);
                if let Feature::Vertex(k) = c.feature {
                    let v = triangles[c.face][k];
                    out.extend_from_slice(&vertex_faces[start[v]..start[v + 1]]);
                }
            }
        }
    }

    /// The closest point of the outer layer to `p` by the walk of the module documentation,
    /// started from `hint` and the faces around outer vertex `partner`.
    fn closest(
        &self,
        x: &[f64],
        p: &Vector3<f64>,
        hint: usize,
        partner: usize,
        scratch: &mut Vec<usize>,
    ) -> Closest {
        let mut best = self.closest_on(x, p, hint);
        scratch.clear();
        match &self.topology {
            Topology::Polygon => {
                let n = self.count;
                scratch.extend([partner, (partner + n - 1) % n]);
            }
            Topology::Surface {
                start,
                vertex_faces,
                ..
            } => scratch.extend_from_slice(&vertex_faces[start[partner]..start[partner + 1]]),
        }
        for &f in scratch.iter() {
            let c = self.closest_on(x, p, f);
            if c.dist2 < best.dist2 {
                best = c;
            }
        }
        for _ in 0..MAX_WALK {
            self.neighbours(&best, scratch);
            let mut next = best;
            for &f in scratch.iter() {
                let c = self.closest_on(x, p, f);
                if c.dist2 < next.dist2 {
                    next = c;
                }
            }
            if next.face == best.face {
                break;
            }
            best = next;
        }
        best
    }

    /// The closest point of the outer layer to `p` over all its faces (`O(faces)`).
    fn closest_brute_force(&self, x: &[f64], p: &Vector3<f64>) -> Closest {
        let faces = match &self.topology {
            Topology::Polygon => self.count,
            Topology::Surface { triangles, .. } => triangles.len(),
        };
        let mut best = self.closest_on(x, p, 0);
        for f in 1..faces {
            let c = self.closest_on(x, p, f);
            if c.dist2 < best.dist2 {
                best = c;
            }
        }
        best
    }

    /// Outward pseudo-normal (not normalised) at the feature of `c`.
    fn pseudo_normal(&self, x: &[f64], c: &Closest) -> Vector3<f64> {
        let face_normal = |f: usize| {
            let (v, nv) = self.face_vertices(f);
            let (a, b) = (point(x, v[0]), point(x, v[1]));
            if nv == 2 {
                let e = b - a;
                Vector3::new(e.y, -e.x, 0.0)
                    .try_normalize(0.0)
                    .unwrap_or_default()
            } else {
                unit_normal(&a, &b, &point(x, v[2]))
            }
        };
        match (&self.topology, c.feature) {
            (_, Feature::Face) => face_normal(c.face),
            (Topology::Polygon, Feature::Vertex(k)) => {
                let n = self.count;
                let other = if k == 0 {
                    (c.face + n - 1) % n
                } else {
                    (c.face + 1) % n
                };
                face_normal(c.face) + face_normal(other)
            }
            (Topology::Surface { across, .. }, Feature::Edge(k)) => {
                face_normal(c.face) + face_normal(across[c.face][k])
            }
            (
                Topology::Surface {
                    triangles,
                    start,
                    vertex_faces,
                    ..
                },
                Feature::Vertex(k),
            ) => {
                let v = triangles[c.face][k];
                let o = self.outer_offset;
                let mut sum = Vector3::zeros();
                for &f in &vertex_faces[start[v]..start[v + 1]] {
                    let t = triangles[f];
                    let at = t.iter().position(|&u| u == v).unwrap_or(0);
                    let p0 = point(x, o + t[at]);
                    let e1 = point(x, o + t[(at + 1) % 3]) - p0;
                    let e2 = point(x, o + t[(at + 2) % 3]) - p0;
                    let angle = e1.cross(&e2).norm().atan2(e1.dot(&e2));
                    sum += face_normal(f) * angle;
                }
                sum
            }
            (Topology::Polygon, Feature::Edge(_)) => face_normal(c.face),
        }
    }

    /// Generalised winding number of `p` about the outer layer (`O(faces)`).
    fn winding_number(&self, x: &[f64], p: &Vector3<f64>) -> f64 {
        let p = Point3::from(*p);
        match &self.topology {
            Topology::Polygon => polygon_winding_number(&p, x, self.outer_offset, self.count),
            Topology::Surface { triangles, .. } => {
                winding_number(&p, x, self.outer_offset, triangles)
            }
        }
    }

    /// Longest edge of face `f` (m).
    fn face_size(&self, x: &[f64], f: usize) -> f64 {
        let (v, nv) = self.face_vertices(f);
        (0..nv)
            .map(|k| (point(x, v[k]) - point(x, v[(k + 1) % nv])).norm())
            .fold(0.0, f64::max)
    }

    /// Puts every escaped inner particle just inside the outer layer and removes its outward
    /// velocity relative to the surface (module documentation). `positions`, `velocities`:
    /// flat, all particles; `masses` and `fixed` per particle (fixed particles are neither
    /// moved nor pushed: infinite mass). Returns the number of particles corrected.
    pub fn contain(
        &mut self,
        positions: &mut [f64],
        velocities: &mut [f64],
        masses: &[f64],
        fixed: &[bool],
        restitution: f64,
    ) -> usize {
        let (io, oo, n) = (self.inner_offset, self.outer_offset, self.count);
        if self.previous.len() == positions.len() {
            // Conservative advancement: the clearance shrinks by the particle's move plus the
            // largest move of the surface.
            let surface_move = (oo..oo + n)
                .map(|i| (point(positions, i) - point(&self.previous, i)).norm_squared())
                .fold(0.0, f64::max)
                .sqrt();
            for j in 0..n {
                let moved = (point(positions, io + j) - point(&self.previous, io + j)).norm();
                self.clearance[j] -= moved + surface_move;
            }
        } else {
            self.clearance.fill(f64::NEG_INFINITY);
        }
        let mut corrected = 0;
        let mut scratch = Vec::new();
        for j in 0..n {
            if self.clearance[j] > 0.0 || fixed[io + j] {
                continue;
            }
            let i = io + j;
            let p = point(positions, i);
            let c = self.closest(positions, &p, self.hint[j], j, &mut scratch);
            self.hint[j] = c.face;
            let normal = self.pseudo_normal(positions, &c);
            let offset = p - c.point;
            let dist = c.dist2.sqrt();
            let margin = MARGIN * self.face_size(positions, c.face);
            if offset.dot(&normal) < 0.0 && dist >= 0.5 * margin {
                // Inside by the pseudo-normal, with room to spare.
                self.clearance[j] = dist;
                continue;
            }
            // Outside or on the surface by the pseudo-normal: confirm with the winding number
            // (where the outer layer folds over itself the closest feature's side can differ
            // from the enclosed region; the winding number decides).
            if self.winding_number(positions, &p) >= 0.5 {
                // Inside after all: the walk stopped at a local minimum of a crumpled layer.
                // Its clearance is the exact distance over all faces, so it is not tested
                // again (at this cost) until it or the layer has moved that far.
                let exact = self.closest_brute_force(positions, &p);
                self.hint[j] = exact.face;
                self.clearance[j] = exact.dist2.sqrt();
                continue;
            }
            // Unit outward direction at the closest point.
            let u = if dist > 0.0 {
                offset / dist
            } else {
                match normal.try_normalize(0.0) {
                    Some(u) => u,
                    None => continue,
                }
            };
            corrected += 1;
            // Just inside along the closest-point direction. Where the outer layer is folded
            // there (the winding number says the point is still out), back to where the
            // particle was at the end of the last call if that is inside now, else deeper.
            let mut target = c.point - u * margin;
            let mut inside = self.winding_number(positions, &target) >= 0.5;
            if !inside && self.previous.len() == positions.len() {
                let back = point(&self.previous, i);
                if self.winding_number(positions, &back) >= 0.5 {
                    target = back;
                    inside = true;
                }
            }
            for depth in [10.0, 100.0] {
                if inside {
                    break;
                }
                target = c.point - u * (depth * margin);
                inside = self.winding_number(positions, &target) >= 0.5;
            }
            for d in 0..3 {
                positions[3 * i + d] = target[d];
            }
            // Tested again at the next call: near a fold another sheet may be closer than the
            // margin.
            self.clearance[j] = 0.0;
            let (verts, nv) = self.face_vertices(c.face);
            let mut surface_velocity = Vector3::zeros();
            let mut weight = 1.0 / masses[i];
            let inverse_mass = |g: usize| if fixed[g] { 0.0 } else { 1.0 / masses[g] };
            for k in 0..nv {
                surface_velocity += point(velocities, verts[k]) * c.weights[k];
                weight += c.weights[k] * c.weights[k] * inverse_mass(verts[k]);
            }
            let vr = (point(velocities, i) - surface_velocity).dot(&u);
            if vr > 0.0 {
                let impulse = (1.0 + restitution) * vr / weight;
                for d in 0..3 {
                    velocities[3 * i + d] -= impulse / masses[i] * u[d];
                }
                for k in 0..nv {
                    let g = verts[k];
                    let s = impulse * c.weights[k] * inverse_mass(g);
                    for d in 0..3 {
                        velocities[3 * g + d] += s * u[d];
                    }
                }
            }
        }
        self.previous.clear();
        self.previous.extend_from_slice(positions);
        corrected
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_mesh::generate::octahedron_sphere;

    /// Closest points on a triangle: each Voronoi region gives its feature and the right point.
    #[test]
    fn triangle_closest_points_by_region() {
        let (a, b, c) = (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        );
        let cases = [
            (Vector3::new(0.2, 0.2, 1.0), Feature::Face, [0.6, 0.2, 0.2]),
            (
                Vector3::new(-1.0, -1.0, 0.3),
                Feature::Vertex(0),
                [1.0, 0.0, 0.0],
            ),
            (
                Vector3::new(2.0, -0.1, 0.0),
                Feature::Vertex(1),
                [0.0, 1.0, 0.0],
            ),
            (
                Vector3::new(0.5, -1.0, 0.0),
                Feature::Edge(0),
                [0.5, 0.5, 0.0],
            ),
            (
                Vector3::new(1.0, 1.0, 0.0),
                Feature::Edge(1),
                [0.0, 0.5, 0.5],
            ),
            (
                Vector3::new(-1.0, 0.25, 0.0),
                Feature::Edge(2),
                [0.75, 0.0, 0.25],
            ),
        ];
        for (p, feature, expected) in cases {
            let w = triangle_weights(&p, &a, &b, &c);
            assert_eq!(feature_of(&w), feature, "{p:?}");
            for k in 0..3 {
                assert!((w[k] - expected[k]).abs() < 1e-12, "{p:?}: {w:?}");
            }
        }
    }

    /// Two concentric octahedron spheres: particles pushed out through a face, an edge and a
    /// vertex of the outer layer are put back just inside, momentum is kept and kinetic
    /// energy does not grow; particles inside are left alone.
    #[test]
    fn escaped_particles_return_inside_without_energy_gain() {
        let inner = octahedron_sphere(0.6, 2).unwrap();
        let outer = octahedron_sphere(1.0, 2).unwrap();
        let n = inner.num_vertices();
        let mut x = inner.positions_flat();
        x.extend(outer.positions_flat());
        let mut v = vec![0.0; 6 * n];
        let masses: Vec<f64> = (0..2 * n).map(|i| if i < n { 0.5 } else { 2.0 }).collect();
        // Inner 0 out through its partner vertex; inner 7 beyond the centre of an outer face;
        // inner 9 beyond the midpoint of an outer edge.
        let t = outer.triangles[5];
        let face_centre = (0..3)
            .map(|k| outer.vertices[t[k]].coords)
            .sum::<Vector3<f64>>()
            / 3.0;
        let edge_mid = (outer.vertices[t[0]].coords + outer.vertices[t[1]].coords) / 2.0;
        let escape = [
            (0usize, outer.vertices[0].coords * 1.3),
            (7, face_centre * 1.2),
            (9, edge_mid * 1.1),
        ];
        for &(j, p) in &escape {
            for d in 0..3 {
                x[3 * j + d] = p[d];
                v[3 * j + d] = 3.0 * p[d];
            }
        }
        let momentum =
            |v: &[f64]| -> Vector3<f64> { (0..2 * n).map(|i| point(v, i) * masses[i]).sum() };
        let kinetic = |v: &[f64]| -> f64 {
            (0..2 * n)
                .map(|i| 0.5 * masses[i] * point(v, i).norm_squared())
                .sum()
        };
        let (p0, k0) = (momentum(&v), kinetic(&v));
        let mut c = LayerContainment::surface(0, n, n, &outer.triangles).unwrap();
        let fixed = c.contain(&mut x, &mut v, &masses, &[false; 2 * 66], 0.5);
        assert_eq!(fixed, 3);
        for &(j, p) in &escape {
            let r = point(&x, j);
            // Back on the outer surface (the radial ray meets it at the same face), just inside.
            assert!(r.norm() < p.norm() / 1.05, "particle {j} at {r:?}");
            // Its outward velocity relative to the surface is reversed with restitution.
            assert!(point(&v, j).dot(&r) < 3.0 * p.dot(&r));
        }
        assert!((momentum(&v) - p0).norm() < 1e-12);
        assert!(kinetic(&v) < k0);
        // A second call finds nothing to do.
        assert_eq!(c.contain(&mut x, &mut v, &masses, &[false; 2 * 66], 0.5), 0);
    }

    #[test]
    fn open_or_inconsistent_surfaces_are_rejected() {
        let m = octahedron_sphere(1.0, 1).unwrap();
        let n = m.num_vertices();
        let open = &m.triangles[1..];
        let e = LayerContainment::surface(0, n, n, open)
            .unwrap_err()
            .to_string();
        assert!(e.contains("closed"), "{e}");
        let mut flipped = m.triangles.clone();
        flipped[0].swap(1, 2);
        assert!(LayerContainment::surface(0, n, n, &flipped).is_err());
    }

    /// 2D: a particle pushed out of a square beyond a corner comes back inside.
    #[test]
    fn polygon_containment_handles_corners() {
        let outer = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0];
        let mut x = vec![0.0; 12];
        x.extend_from_slice(&outer);
        x[0] = 1.5;
        x[1] = 0.1;
        let mut v = vec![0.0; 24];
        v[0] = 1.0;
        let masses = vec![1.0; 8];
        let mut c = LayerContainment::polygon(0, 4, 4);
        assert_eq!(c.contain(&mut x, &mut v, &masses, &[false; 8], 0.0), 1);
        assert!(x[0] < 1.0 && x[0] > 0.99 && x[2] == 0.0, "{:?}", &x[..3]);
        // No relative velocity left along the outward direction from the corner (restitution
        // 0): the particle and the corner vertex (outer particle 4) share the momentum.
        let rel = 0.5 * (v[0] - v[12]) + 0.1 * (v[1] - v[13]);
        assert!(rel.abs() <= 1e-12, "{:?}", &v[..3]);
        assert!((v[0] + v[12] - 1.0).abs() < 1e-12);
    }
}
