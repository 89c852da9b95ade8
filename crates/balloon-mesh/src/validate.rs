//! Mesh validation and repair: what the shell simulator requires before any work (a closed,
//! 2-manifold, consistently outward-oriented surface without degenerate triangles) and helpers
//! that repair common defects (duplicate vertices, degenerate triangles, flipped orientation).

use crate::topology::Topology;
use crate::{MeshError, TriMesh};
use nalgebra::Point3;
use std::collections::HashMap;
use std::fmt;

/// One problem found in a mesh, naming the element(s) involved.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Defect {
    /// A vertex coordinate is NaN or infinite.
    NonFiniteVertex {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The bad index.
        index: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// A triangle uses the same vertex twice.
    RepeatedIndex {
        /// The triangle.
        triangle: usize,
    },
    /// A triangle has (near-)zero area: `2 A / l_max^2` below the tolerance.
    DegenerateTriangle {
        /// The triangle.
        triangle: usize,
        /// Its area, m^2.
        area: f64,
    },
    /// An edge shared by more than two triangles.
    NonManifoldEdge {
        /// The edge's vertices.
        edge: [usize; 2],
        /// Number of triangles on it.
        triangles: usize,
    },
    /// A vertex whose incident triangles form several fans (surfaces touching at a point).
    NonManifoldVertex {
        /// The vertex.
        vertex: usize,
        /// Number of fans.
        fans: usize,
    },
    /// An edge with a single triangle: the mesh has a hole.
    BoundaryEdge {
        /// The edge's vertices.
        edge: [usize; 2],
    },
    /// Two triangles traverse their shared edge in the same direction (one of them is flipped).
    InconsistentOrientation {
        /// The edge's vertices.
        edge: [usize; 2],
        /// The two triangles.
        triangles: [usize; 2],
    },
    /// A closed, consistently oriented component encloses a negative volume: its normals point
    /// inward.
    InwardOrientation {
        /// The component (numbered as in [`Topology::triangle_components`]).
        component: usize,
        /// A triangle of that component.
        triangle: usize,
        /// Its signed enclosed volume, m^3.
        volume: f64,
    },
    /// Two vertices at the same position (within the weld tolerance).
    DuplicateVertex {
        /// The later vertex.
        vertex: usize,
        /// The earlier vertex it coincides with.
        duplicate_of: usize,
    },
    /// A vertex used by no triangle.
    UnreferencedVertex {
        /// The vertex.
        vertex: usize,
    },
}

impl fmt::Display for Defect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Defect::NonFiniteVertex { vertex } => {
                write!(f, "vertex {vertex} has a non-finite coordinate")
            }
            Defect::IndexOutOfRange {
                triangle,
                index,
                num_vertices,
            } => write!(
                f,
                "triangle {triangle} refers to vertex {index} but there are only {num_vertices} vertices"
            ),
            Defect::RepeatedIndex { triangle } => {
                write!(f, "triangle {triangle} uses a vertex twice")
            }
            Defect::DegenerateTriangle { triangle, area } => {
                write!(f, "triangle {triangle} is degenerate (area {area:e} m^2)")
            }
            Defect::NonManifoldEdge { edge, triangles } => write!(
                f,
                "edge ({}, {}) is shared by {triangles} triangles (non-manifold)",
                edge[0], edge[1]
            ),
            Defect::NonManifoldVertex { vertex, fans } => write!(
                f,
                "vertex {vertex} joins {fans} separate fans of triangles (non-manifold)"
            ),
            Defect::BoundaryEdge { edge } => write!(
                f,
                "edge ({}, {}) has a single triangle (the mesh is open)",
                edge[0], edge[1]
            ),
            Defect::InconsistentOrientation { edge, triangles } => write!(
                f,
                "triangles {} and {} traverse edge ({}, {}) in the same direction (inconsistent orientation)",
                triangles[0], triangles[1], edge[0], edge[1]
            ),
            Defect::InwardOrientation {
                component,
                triangle,
                volume,
            } => write!(
                f,
                "component {component} (triangle {triangle}) is oriented inward (enclosed volume {volume:e} m^3)"
            ),
            Defect::DuplicateVertex {
                vertex,
                duplicate_of,
            } => write!(f, "vertex {vertex} duplicates vertex {duplicate_of}"),
            Defect::UnreferencedVertex { vertex } => {
                write!(f, "vertex {vertex} is used by no triangle")
            }
        }
    }
}

/// Tolerances of [`validate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidationOptions {
    /// A triangle is degenerate when `2 A / l_max^2 <` this (its height relative to its longest
    /// edge). Default `1e-10`.
    pub degenerate_tolerance: f64,
    /// Vertices closer than this (m) are duplicates. Default `0.0` (exactly equal positions).
    pub duplicate_tolerance: f64,
    /// Report unreferenced vertices. Default `true`.
    pub report_unreferenced: bool,
}

impl Default for ValidationOptions {
    fn default() -> Self {
        Self {
            degenerate_tolerance: 1e-10,
            duplicate_tolerance: 0.0,
            report_unreferenced: true,
        }
    }
}

/// Result of [`validate`]: every defect found, with summary flags.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ValidationReport {
    /// All defects, grouped by kind in the order of the [`Defect`] variants.
    pub defects: Vec<Defect>,
    /// Every edge has exactly two triangles.
    pub closed: bool,
    /// No non-manifold edge or vertex.
    pub manifold: bool,
    /// Every manifold interior edge is traversed in opposite directions by its two triangles.
    pub consistently_oriented: bool,
    /// Every closed, consistently oriented component encloses a positive volume.
    pub outward: bool,
    /// Connected components (0 when topology could not be built).
    pub components: usize,
    /// Genus when the mesh is a closed orientable manifold.
    pub genus: Option<usize>,
}

impl ValidationReport {
    /// `true` when no defect was found.
    pub fn is_valid(&self) -> bool {
        self.defects.is_empty()
    }
}

fn is_degenerate(p: [&Point3<f64>; 3], tol: f64) -> Option<f64> {
    let cr = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
    let l2 = (p[1] - p[0])
        .norm_squared()
        .max((p[2] - p[1]).norm_squared())
        .max((p[0] - p[2]).norm_squared());
    (cr.is_nan() || cr <= tol * l2).then_some(0.5 * cr)
}

/// Duplicate vertices: for each vertex, the first earlier vertex within `tol` (or itself).
fn duplicate_map(vertices: &[Point3<f64>], tol: f64) -> Vec<usize> {
    let mut map = Vec::with_capacity(vertices.len());
    if tol <= 0.0 {
        let mut seen: HashMap<[u64; 3], usize> = HashMap::with_capacity(vertices.len());
        for (i, p) in vertices.iter().enumerate() {
            // +0.0 and -0.0 are the same position.
            let key = [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits);
            map.push(*seen.entry(key).or_insert(i));
        }
        return map;
    }
    let cell = |p: &Point3<f64>| [p.x, p.y, p.z].map(|c| (c / tol).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in vertices.iter().enumerate() {
        let c = cell(p);
        let mut found = i;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &j in list {
                            if map[j] == j && (vertices[j] - p).norm() <= tol {
                                found = found.min(j);
                                if found < i {
                                    break 'search;
                                }
                            }
                        }
                    }
                }
            }
        }
        map.push(found);
        if found == i {
            grid.entry(c).or_default().push(i);
        }
    }
    map
}

/// Checks `mesh` for every [`Defect`]. Never panics, whatever the indices.
pub fn validate(mesh: &TriMesh, opts: &ValidationOptions) -> ValidationReport {
    let nv = mesh.num_vertices();
    let mut d = Vec::new();
    for (i, p) in mesh.vertices.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            d.push(Defect::NonFiniteVertex { vertex: i });
        }
    }
    let mut in_range = true;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &i in tri {
            if i >= nv {
                in_range = false;
                d.push(Defect::IndexOutOfRange {
                    triangle: t,
                    index: i,
                    num_vertices: nv,
                });
                break;
            }
        }
    }
    let mut report = ValidationReport::default();
    if !in_range {
        report.defects = d;
        return report;
    }
    for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
        if a == b || b == c || c == a {
            d.push(Defect::RepeatedIndex { triangle: t });
        } else if let Some(area) = is_degenerate(
            [&mesh.vertices[a], &mesh.vertices[b], &mesh.vertices[c]],
            opts.degenerate_tolerance,
        ) {
            d.push(Defect::DegenerateTriangle { triangle: t, area });
        }
    }
    let topo = Topology::new(mesh);
    let mut manifold = true;
    for e in topo.non_manifold_edges() {
        manifold = false;
        d.push(Defect::NonManifoldEdge {
            edge: topo.edges()[e],
            triangles: topo.edge_triangles(e).len(),
        });
    }
    for v in 0..nv {
        let fans = topo.vertex_fan_count(v, &mesh.triangles);
        if fans > 1 {
            manifold = false;
            d.push(Defect::NonManifoldVertex { vertex: v, fans });
        }
    }
    let boundary = topo.boundary_edges();
    for &e in &boundary {
        d.push(Defect::BoundaryEdge {
            edge: topo.edges()[e],
        });
    }
    let (label, ncomp) = topo.triangle_components();
    let mut comp_consistent = vec![true; ncomp];
    let mut comp_closed = vec![true; ncomp];
    let mut consistent = true;
    for e in 0..topo.num_edges() {
        let tris = topo.edge_triangles(e);
        if tris.len() != 2 {
            for &t in tris {
                comp_closed[label[t]] = false;
            }
            continue;
        }
        let [a, b] = topo.edges()[e];
        let dir = |t: usize| {
            let tri = mesh.triangles[t];
            (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b)
        };
        if a != b && dir(tris[0]) == dir(tris[1]) {
            consistent = false;
            comp_consistent[label[tris[0]]] = false;
            d.push(Defect::InconsistentOrientation {
                edge: [a, b],
                triangles: [tris[0], tris[1]],
            });
        }
    }
    let mut vol = vec![0.0; ncomp];
    let mut first = vec![usize::MAX; ncomp];
    for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
        let v = &mesh.vertices;
        vol[label[t]] += v[a].coords.dot(&v[b].coords.cross(&v[c].coords)) / 6.0;
        first[label[t]] = first[label[t]].min(t);
    }
    let mut outward = true;
    for c in 0..ncomp {
        if comp_closed[c] && comp_consistent[c] && vol[c] < 0.0 {
            outward = false;
            d.push(Defect::InwardOrientation {
                component: c,
                triangle: first[c],
                volume: vol[c],
            });
        }
    }
    for (i, &j) in duplicate_map(&mesh.vertices, opts.duplicate_tolerance)
        .iter()
        .enumerate()
    {
        if j != i {
            d.push(Defect::DuplicateVertex {
                vertex: i,
                duplicate_of: j,
            });
        }
    }
    if opts.report_unreferenced {
        for v in 0..nv {
            if topo.vertex_triangles(v).is_empty() {
                d.push(Defect::UnreferencedVertex { vertex: v });
            }
        }
    }
    report.closed = boundary.is_empty() && topo.non_manifold_edges().is_empty();
    report.manifold = manifold;
    report.consistently_oriented = consistent;
    report.outward = outward;
    report.components = ncomp;
    report.genus = if consistent {
        topo.genus(&mesh.triangles)
    } else {
        None
    };
    report.defects = d;
    report
}

/// Checks that `mesh` is what the shell simulator needs: a closed, 2-manifold, consistently
/// outward-oriented surface with finite coordinates, in-range indices, no degenerate triangles,
/// no duplicate or unreferenced vertices (default [`ValidationOptions`]).
///
/// # Errors
/// [`MeshError::InvalidMesh`] naming the first defect and the count of the others.
pub fn validate_closed_manifold(mesh: &TriMesh) -> Result<(), MeshError> {
    let rep = validate(mesh, &ValidationOptions::default());
    let mut defects = rep.defects.into_iter();
    match defects.next() {
        None => Ok(()),
        Some(first) => Err(MeshError::InvalidMesh {
            first,
            others: defects.len(),
        }),
    }
}

/// Merges vertices closer than `tol` (m; `0.0` merges exactly equal positions) into the first of
/// them, drops triangles that become degenerate (a repeated index) and unreferenced vertices.
///
/// Returns the welded mesh and, for every input vertex, its index in the output (`usize::MAX`
/// for a dropped vertex).
///
/// # Panics
/// If a triangle index is out of range.
pub fn weld_vertices(mesh: &TriMesh, tol: f64) -> (TriMesh, Vec<usize>) {
    let rep = duplicate_map(&mesh.vertices, tol);
    let triangles: Vec<[usize; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| rep[i]))
        .filter(|&[a, b, c]| a != b && b != c && c != a)
        .collect();
    let mut used = vec![false; mesh.num_vertices()];
    for t in &triangles {
        for &i in t {
            used[i] = true;
        }
    }
    let mut new_index = vec![usize::MAX; mesh.num_vertices()];
    let mut vertices = Vec::new();
    for (i, p) in mesh.vertices.iter().enumerate() {
        if used[i] {
            new_index[i] = vertices.len();
            vertices.push(*p);
        }
    }
    let map: Vec<usize> = rep.iter().map(|&r| new_index[r]).collect();
    let triangles = triangles
        .into_iter()
        .map(|t| t.map(|i| new_index[i]))
        .collect();
    (TriMesh::new(vertices, triangles), map)
}

/// Drops vertices used by no triangle. Returns the compacted mesh and, for every input vertex,
/// its index in the output (`usize::MAX` for a dropped vertex).
///
/// # Panics
/// If a triangle index is out of range.
pub fn remove_unreferenced_vertices(mesh: &TriMesh) -> (TriMesh, Vec<usize>) {
    let mut map = vec![usize::MAX; mesh.num_vertices()];
    let mut vertices = Vec::new();
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                if map[i] == usize::MAX {
                    map[i] = vertices.len();
                    vertices.push(mesh.vertices[i]);
                }
                map[i]
            })
        })
        .collect();
    (TriMesh::new(vertices, triangles), map)
}

/// Removes triangles with a repeated index or `2 A / l_max^2 < tol` (see
/// [`ValidationOptions::degenerate_tolerance`]); vertices are kept.
///
/// # Panics
/// If a triangle index is out of range.
pub fn remove_degenerate_triangles(mesh: &TriMesh, tol: f64) -> TriMesh {
    let v = &mesh.vertices;
    let triangles = mesh
        .triangles
        .iter()
        .copied()
        .filter(|&[a, b, c]| {
            a != b && b != c && c != a && is_degenerate([&v[a], &v[b], &v[c]], tol).is_none()
        })
        .collect();
    TriMesh::new(mesh.vertices.clone(), triangles)
}

/// Makes the orientation consistent (breadth-first over each edge-connected component, flipping
/// triangles to match their neighbours), then flips every component whose enclosed volume
/// (divergence theorem, Wang et al. 2015, Eq. 13) is negative so that normals point outward.
///
/// # Errors
/// [`MeshError::InvalidMesh`] when an index is out of range, an edge is non-manifold, or a
/// component is not orientable (a Moebius-like loop).
pub fn orient_outward(mesh: &TriMesh) -> Result<TriMesh, MeshError> {
    let nv = mesh.num_vertices();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i >= nv) {
            return Err(MeshError::InvalidMesh {
                first: Defect::IndexOutOfRange {
                    triangle: t,
                    index: i,
                    num_vertices: nv,
                },
                others: 0,
            });
        }
    }
    let topo = Topology::new(mesh);
    let bad = topo.non_manifold_edges();
    if let Some(&e) = bad.first() {
        return Err(MeshError::InvalidMesh {
            first: Defect::NonManifoldEdge {
                edge: topo.edges()[e],
                triangles: topo.edge_triangles(e).len(),
            },
            others: bad.len() - 1,
        });
    }
    let mut tris = mesh.triangles.clone();
    let nf = tris.len();
    let mut visited = vec![false; nf];
    let mut comp = vec![usize::MAX; nf];
    let mut ncomp = 0;
    let mut queue = std::collections::VecDeque::new();
    let has_dir =
        |tri: &[usize; 3], a: usize, b: usize| (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b);
    for seed in 0..nf {
        if visited[seed] {
            continue;
        }
        visited[seed] = true;
        comp[seed] = ncomp;
        queue.push_back(seed);
        while let Some(t) = queue.pop_front() {
            for k in 0..3 {
                // Edge indices follow the input vertex order; read the direction from the
                // current (possibly flipped) triangle.
                let e = topo.triangle_edges()[t][k];
                let [x, y] = topo.edges()[e];
                if x == y {
                    continue;
                }
                let (a, b) = if has_dir(&tris[t], x, y) {
                    (x, y)
                } else {
                    (y, x)
                };
                for &u in topo.edge_triangles(e) {
                    if u == t {
                        continue;
                    }
                    if !visited[u] {
                        visited[u] = true;
                        comp[u] = ncomp;
                        if has_dir(&tris[u], a, b) {
                            tris[u].swap(1, 2);
                        }
                        queue.push_back(u);
                    } else if has_dir(&tris[u], a, b) {
                        return Err(MeshError::InvalidMesh {
                            first: Defect::InconsistentOrientation {
                                edge: [a.min(b), a.max(b)],
                                triangles: [t.min(u), t.max(u)],
                            },
                            others: 0,
                        });
                    }
                }
            }
        }
        ncomp += 1;
    }
    let v = &mesh.vertices;
    let mut vol = vec![0.0; ncomp];
    for (t, &[a, b, c]) in tris.iter().enumerate() {
        vol[comp[t]] += v[a].coords.dot(&v[b].coords.cross(&v[c].coords));
    }
    for (t, tri) in tris.iter_mut().enumerate() {
        if vol[comp[t]] < 0.0 {
            tri.swap(1, 2);
        }
    }
    Ok(TriMesh::new(mesh.vertices.clone(), tris))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::icosphere;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    fn kinds(m: &TriMesh) -> Vec<Defect> {
        validate(m, &ValidationOptions::default()).defects
    }

    #[test]
    fn valid_meshes_pass() {
        assert!(validate_closed_manifold(&tetra()).is_ok());
        let s = icosphere(0.1, 3).unwrap();
        let rep = validate(&s, &ValidationOptions::default());
        assert!(rep.is_valid(), "{:?}", rep.defects.first());
        assert!(rep.closed && rep.manifold && rep.consistently_oriented && rep.outward);
        assert_eq!(rep.genus, Some(0));
    }

    #[test]
    fn each_defect_is_caught() {
        let mut m = tetra();
        m.triangles[3] = [1, 2, 7];
        assert!(matches!(
            kinds(&m)[0],
            Defect::IndexOutOfRange {
                triangle: 3,
                index: 7,
                ..
            }
        ));
        let err = validate_closed_manifold(&m).unwrap_err().to_string();
        assert!(
            err.contains("triangle 3") && err.contains("vertex 7"),
            "{err}"
        );

        let mut m = tetra();
        m.triangles[1] = [0, 1, 1];
        assert!(kinds(&m).contains(&Defect::RepeatedIndex { triangle: 1 }));

        let mut m = tetra();
        m.vertices[3] = Point3::new(0.5, 0.0, 0.0); // on edge (0, 1): triangle 1 collapses
        assert!(
            kinds(&m)
                .iter()
                .any(|d| matches!(d, Defect::DegenerateTriangle { triangle: 1, .. }))
        );

        let mut m = tetra();
        m.triangles.pop();
        let k = kinds(&m);
        assert_eq!(
            k.iter()
                .filter(|d| matches!(d, Defect::BoundaryEdge { .. }))
                .count(),
            3
        );
        let err = validate_closed_manifold(&m).unwrap_err().to_string();
        assert!(err.contains("2 more"), "{err}");

        let mut m = tetra();
        m.triangles[3] = [1, 3, 2];
        assert!(
            kinds(&m)
                .iter()
                .any(|d| matches!(d, Defect::InconsistentOrientation { .. }))
        );

        let mut m = tetra();
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
        let k = kinds(&m);
        assert!(
            matches!(k[0], Defect::InwardOrientation { component: 0, .. }),
            "{k:?}"
        );
        assert!(!validate(&m, &ValidationOptions::default()).outward);

        let mut m = tetra();
        m.vertices.push(m.vertices[0]);
        let k = kinds(&m);
        assert!(k.contains(&Defect::DuplicateVertex {
            vertex: 4,
            duplicate_of: 0
        }));
        assert!(k.contains(&Defect::UnreferencedVertex { vertex: 4 }));

        // Two tetrahedra glued at one vertex: that vertex has two fans.
        let a = tetra();
        let mut m = a.clone();
        m.vertices
            .extend(a.vertices[1..].iter().map(|p| Point3::from(-p.coords)));
        m.triangles.extend(
            a.triangles
                .iter()
                .map(|t| t.map(|i| if i == 0 { 0 } else { i + 3 })),
        );
        assert!(kinds(&m).contains(&Defect::NonManifoldVertex { vertex: 0, fans: 2 }));

        // A fin: a third triangle on edge (0, 1).
        let mut m = tetra();
        m.vertices.push(Point3::new(0.5, -1.0, -1.0));
        m.triangles.push([0, 1, 4]);
        assert!(kinds(&m).iter().any(|d| matches!(
            d,
            Defect::NonManifoldEdge {
                edge: [0, 1],
                triangles: 3
            }
        )));
        assert!(orient_outward(&m).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 64, failure_persistence: None, ..Default::default() })]

        /// Validation and repair never panic, whatever the indices and coordinates; a mesh that
        /// passes validation keeps passing after `orient_outward` (it is already outward).
        #[test]
        fn validation_never_panics(
            coords in proptest::collection::vec(-2i8..3, 0..24),
            tris in proptest::collection::vec([0usize..10, 0usize..10, 0usize..10], 0..12),
        ) {
            let vertices: Vec<Point3<f64>> = coords
                .chunks_exact(3)
                .map(|c| Point3::new(c[0] as f64, c[1] as f64, c[2] as f64))
                .collect();
            let m = TriMesh::new(vertices, tris);
            let rep = validate(&m, &ValidationOptions::default());
            let ok = validate_closed_manifold(&m).is_ok();
            proptest::prop_assert_eq!(ok, rep.is_valid());
            if let Ok(o) = orient_outward(&m) {
                proptest::prop_assert_eq!(o.num_triangles(), m.num_triangles());
                if ok {
                    proptest::prop_assert!(validate_closed_manifold(&o).is_ok());
                }
            }
        }
    }

    #[test]
    fn repairs_restore_validity() {
        // Scrambled orientation: orient_outward recovers a valid mesh with the same volume sign.
        let mut m = icosphere(0.1, 2).unwrap();
        for (i, t) in m.triangles.iter_mut().enumerate() {
            if i % 3 == 0 || i == 1 {
                t.swap(0, 1);
            }
        }
        assert!(validate_closed_manifold(&m).is_err());
        let o = orient_outward(&m).unwrap();
        validate_closed_manifold(&o).unwrap();
        assert!(crate::geometry::enclosed_volume(&o) > 0.0);

        // A triangle soup (every triangle with its own vertices) welds back to the sphere.
        let s = icosphere(1.0, 1).unwrap();
        let soup = TriMesh::new(
            s.triangles
                .iter()
                .flat_map(|t| t.map(|i| s.vertices[i]))
                .collect(),
            (0..s.num_triangles())
                .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect(),
        );
        let (w, map) = weld_vertices(&soup, 0.0);
        assert_eq!(w.num_vertices(), s.num_vertices());
        assert_eq!(map.len(), soup.num_vertices());
        validate_closed_manifold(&w).unwrap();
        // With a tolerance, slightly perturbed copies weld too.
        let mut noisy = soup.clone();
        for (i, p) in noisy.vertices.iter_mut().enumerate() {
            p.x += 1e-9 * (i % 7) as f64;
        }
        let (w, _) = weld_vertices(&noisy, 1e-6);
        assert_eq!(w.num_vertices(), s.num_vertices());

        let mut d = tetra();
        d.triangles.push([0, 1, 1]);
        assert_eq!(remove_degenerate_triangles(&d, 1e-10).num_triangles(), 4);

        // An unused vertex is dropped and the others keep their geometry.
        let mut u = tetra();
        u.vertices.insert(0, Point3::new(9.0, 9.0, 9.0));
        for t in &mut u.triangles {
            *t = t.map(|i| i + 1);
        }
        assert!(validate_closed_manifold(&u).is_err());
        let (c, map) = remove_unreferenced_vertices(&u);
        assert_eq!(map[0], usize::MAX);
        validate_closed_manifold(&c).unwrap();
        assert!((crate::geometry::enclosed_volume(&c) - 1.0 / 6.0).abs() < 1e-15);
    }
}
