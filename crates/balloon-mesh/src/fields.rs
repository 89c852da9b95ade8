//! Derived per-face and per-vertex fields of a triangle surface, for output and display.
//!
//! **For:** the quantities people colour a surface by: in-plane stretch (mean and largest
//! principal), vertex normals, vertex speeds, and the face -> vertex averaging used to show a
//! per-face field on a smooth surface.
//!
//! **Not for:** physics; nothing here is used by a solver (the pressure force people also colour
//! by is `balloon_gas::vertex_pressure_forces`). Every function is pure, works on flat position
//! arrays `x = [x0, y0, z0, x1, ...]` (3 numbers per vertex) and triangle index triples, and
//! checks its input: a length mismatch, an out-of-range index or a degenerate rest triangle is a
//! [`FieldError`] naming the argument and the index, never a panic.
//!
//! ```
//! use balloon_mesh::fields::{face_area_stretch, face_max_stretch};
//! let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
//! let x: Vec<f64> = rest.iter().map(|c| 2.0 * c).collect();
//! let tris = [[0, 1, 2]];
//! assert!((face_area_stretch(&rest, &x, &tris).unwrap()[0] - 2.0).abs() < 1e-12);
//! assert!((face_max_stretch(&rest, &x, &tris).unwrap()[0] - 2.0).abs() < 1e-12);
//! ```

use thiserror::Error;

/// Bad input to a field function.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FieldError {
    /// A flat array does not have the expected length.
    #[error("{name} has length {len}, expected {expected}")]
    LengthMismatch {
        /// Argument name.
        name: &'static str,
        /// Length given.
        len: usize,
        /// Length expected.
        expected: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {vertex}, but there are only {num_vertices} vertices"
    )]
    VertexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// Offending vertex index.
        vertex: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// A rest triangle has (numerically) zero area, so no deformation gradient exists.
    #[error("rest triangle {triangle} is degenerate (area {area:e}); stretch is undefined")]
    DegenerateRestTriangle {
        /// Triangle index.
        triangle: usize,
        /// Its rest area.
        area: f64,
    },
}

type V3 = [f64; 3];

#[inline]
fn p(x: &[f64], i: usize) -> V3 {
    [x[3 * i], x[3 * i + 1], x[3 * i + 2]]
}

#[inline]
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// Checks `x.len() % 3 == 0` and returns the vertex count.
fn vertex_count(name: &'static str, x: &[f64]) -> Result<usize, FieldError> {
    if !x.len().is_multiple_of(3) {
        return Err(FieldError::LengthMismatch {
            name,
            len: x.len(),
            expected: 3 * (x.len() / 3),
        });
    }
    Ok(x.len() / 3)
}

fn check_triangles(n: usize, tris: &[[usize; 3]]) -> Result<(), FieldError> {
    for (t, tri) in tris.iter().enumerate() {
        for &v in tri {
            if v >= n {
                return Err(FieldError::VertexOutOfRange {
                    triangle: t,
                    vertex: v,
                    num_vertices: n,
                });
            }
        }
    }
    Ok(())
}

/// Checks `rest` and `x` describe the same vertices and every triangle index is valid.
fn check_pair(rest: &[f64], x: &[f64], tris: &[[usize; 3]]) -> Result<usize, FieldError> {
    let n = vertex_count("rest", rest)?;
    if x.len() != rest.len() {
        return Err(FieldError::LengthMismatch {
            name: "x",
            len: x.len(),
            expected: rest.len(),
        });
    }
    check_triangles(n, tris)?;
    Ok(n)
}

/// Right Cauchy-Green tensor `C = F^T F` (2x2, as `[c11, c12, c22]`) of the in-plane
/// deformation gradient of triangle `t`, `F = D Dm^-1`, with `Dm` the rest edges written in an
/// orthonormal frame of the rest plane and `D` the deformed edges (3x2).
fn cauchy_green(
    rest: &[f64],
    x: &[f64],
    t: usize,
    tri: &[usize; 3],
) -> Result<[f64; 3], FieldError> {
    let [a, b, c] = *tri;
    let r1 = sub(p(rest, b), p(rest, a));
    let r2 = sub(p(rest, c), p(rest, a));
    let l1 = norm(r1);
    let area2 = norm(cross(r1, r2));
    // Relative degeneracy test: twice the area against the squared edge scale.
    let scale = dot(r1, r1).max(dot(r2, r2));
    if area2.is_nan() || area2 <= 1e-14 * scale || l1 == 0.0 {
        return Err(FieldError::DegenerateRestTriangle {
            triangle: t,
            area: 0.5 * area2,
        });
    }
    // Rest frame: e1 along r1, e2 in-plane perpendicular. Dm = [[l1, u], [0, w]].
    let u = dot(r2, r1) / l1;
    let w = area2 / l1;
    let d1 = sub(p(x, b), p(x, a));
    let d2 = sub(p(x, c), p(x, a));
    // Dm^-1 = [[1/l1, -u/(l1 w)], [0, 1/w]]; F columns: f1 = d1/l1, f2 = (d2 - u/l1 d1)/w.
    let f1 = [d1[0] / l1, d1[1] / l1, d1[2] / l1];
    let k = u / l1;
    let f2 = [
        (d2[0] - k * d1[0]) / w,
        (d2[1] - k * d1[1]) / w,
        (d2[2] - k * d1[2]) / w,
    ];
    Ok([dot(f1, f1), dot(f1, f2), dot(f2, f2)])
}

/// Mean in-plane stretch of each face, `sqrt(A / A0)` (deformed over rest area), one value per
/// triangle. For an equibiaxially stretched sphere it equals the stretch ratio `lambda` used by
/// the shell analytic solution (Wang et al. 2015, Sec. 7).
pub fn face_area_stretch(
    rest: &[f64],
    x: &[f64],
    tris: &[[usize; 3]],
) -> Result<Vec<f64>, FieldError> {
    check_pair(rest, x, tris)?;
    tris.iter()
        .enumerate()
        .map(|(t, tri)| {
            let [c11, c12, c22] = cauchy_green(rest, x, t, tri)?;
            // det C = (A/A0)^2.
            Ok((c11 * c22 - c12 * c12).max(0.0).sqrt().sqrt())
        })
        .collect()
}

/// Largest principal in-plane stretch of each face: the square root of the larger eigenvalue of
/// `C = F^T F`, with `F` the 3x2 in-plane deformation gradient (the same constant-strain
/// triangle kinematics as the membrane part of the three-prism element, Wang et al. 2015, Sec. 4).
pub fn face_max_stretch(
    rest: &[f64],
    x: &[f64],
    tris: &[[usize; 3]],
) -> Result<Vec<f64>, FieldError> {
    check_pair(rest, x, tris)?;
    tris.iter()
        .enumerate()
        .map(|(t, tri)| {
            let [c11, c12, c22] = cauchy_green(rest, x, t, tri)?;
            let mean = 0.5 * (c11 + c22);
            let half_diff = 0.5 * (c11 - c22);
            let radius = (half_diff * half_diff + c12 * c12).sqrt();
            Ok((mean + radius).max(0.0).sqrt())
        })
        .collect()
}

/// [`face_area_stretch`] that gives `NaN` ("undefined") for degenerate rest triangles instead
/// of failing: triangle soups (Diziol, Bender and Bayer 2011 takes any) may hold zero-area triangles, whose stretch
/// has no meaning while every other face's has. Other input errors still fail.
pub fn face_area_stretch_or_nan(
    rest: &[f64],
    x: &[f64],
    tris: &[[usize; 3]],
) -> Result<Vec<f64>, FieldError> {
    per_face_or_nan(rest, x, tris, face_area_stretch)
}

/// [`face_max_stretch`] with `NaN` for degenerate rest triangles (see
/// [`face_area_stretch_or_nan`]).
pub fn face_max_stretch_or_nan(
    rest: &[f64],
    x: &[f64],
    tris: &[[usize; 3]],
) -> Result<Vec<f64>, FieldError> {
    per_face_or_nan(rest, x, tris, face_max_stretch)
}

type FaceField = fn(&[f64], &[f64], &[[usize; 3]]) -> Result<Vec<f64>, FieldError>;

fn per_face_or_nan(
    rest: &[f64],
    x: &[f64],
    tris: &[[usize; 3]],
    f: FaceField,
) -> Result<Vec<f64>, FieldError> {
    match f(rest, x, tris) {
        Err(FieldError::DegenerateRestTriangle { .. }) => Ok(tris
            .iter()
            .map(|t| f(rest, x, std::slice::from_ref(t)).map_or(f64::NAN, |v| v[0]))
            .collect()),
        other => other,
    }
}

/// Areas of the triangles at positions `x` (m^2).
pub fn face_areas(x: &[f64], tris: &[[usize; 3]]) -> Result<Vec<f64>, FieldError> {
    let n = vertex_count("x", x)?;
    check_triangles(n, tris)?;
    Ok(tris
        .iter()
        .map(|&[a, b, c]| 0.5 * norm(cross(sub(p(x, b), p(x, a)), sub(p(x, c), p(x, a)))))
        .collect())
}

/// Per-vertex average of a per-face field, weighted by the face areas at positions `x`:
/// `value_i = sum_{f ∋ i} A_f value_f / sum_{f ∋ i} A_f`. The vertex count is `x.len() / 3`.
/// A vertex with no adjacent face (or only zero-area faces) gets the plain mean of its faces,
/// or `0` if it has none. Non-finite face values (e.g. the `NaN` of an undefined stretch) are
/// left out; a vertex whose faces all have one gets `NaN`.
pub fn face_to_vertex(
    x: &[f64],
    tris: &[[usize; 3]],
    face_values: &[f64],
) -> Result<Vec<f64>, FieldError> {
    if face_values.len() != tris.len() {
        return Err(FieldError::LengthMismatch {
            name: "face_values",
            len: face_values.len(),
            expected: tris.len(),
        });
    }
    let areas = face_areas(x, tris)?;
    let n = x.len() / 3;
    let mut sum = vec![0.0; n];
    let mut weight = vec![0.0; n];
    let mut plain = vec![0.0; n];
    let mut count = vec![0usize; n];
    let mut undefined = vec![false; n];
    for ((tri, &a), &v) in tris.iter().zip(&areas).zip(face_values) {
        if !v.is_finite() {
            tri.iter().for_each(|&i| undefined[i] = true);
            continue;
        }
        for &i in tri {
            sum[i] += a * v;
            weight[i] += a;
            plain[i] += v;
            count[i] += 1;
        }
    }
    Ok((0..n)
        .map(|i| {
            if weight[i] > 0.0 {
                sum[i] / weight[i]
            } else if count[i] > 0 {
                plain[i] / count[i] as f64
            } else if undefined[i] {
                f64::NAN
            } else {
                0.0
            }
        })
        .collect())
}

/// Unit vertex normals (flat, 3 per vertex): the normalised sum of the area-weighted normals
/// `A n = (1/2) e12 x e13` of the adjacent faces (outward for an outward-oriented mesh). A vertex
/// whose sum vanishes (isolated, or cancelling faces) gets the zero vector. The checked form of
/// [`crate::geometry::vertex_normals_flat`].
pub fn vertex_normals(x: &[f64], tris: &[[usize; 3]]) -> Result<Vec<f64>, FieldError> {
    let n = vertex_count("x", x)?;
    check_triangles(n, tris)?;
    Ok(crate::geometry::vertex_normals_flat(x, tris))
}

/// `sum_{f ∋ i} e12 x e13` per vertex (flat, m^2): twice the area-weighted normal sum
/// `2 sum_{f ∋ i} A_f n_f`. The checked form of
/// [`crate::geometry::vertex_area_normal_sums_flat`]; a pressure `p` puts the force
/// `p / 6` times this on each vertex (Wang et al. 2015, Eq. 15).
pub fn vertex_area_normal_sums(x: &[f64], tris: &[[usize; 3]]) -> Result<Vec<f64>, FieldError> {
    let n = vertex_count("x", x)?;
    check_triangles(n, tris)?;
    Ok(crate::geometry::vertex_area_normal_sums_flat(x, tris))
}

/// Speed `|v_i|` of each vertex (m/s) from flat velocities `v` (3 per vertex).
pub fn vertex_speeds(v: &[f64]) -> Result<Vec<f64>, FieldError> {
    vertex_count("v", v)?;
    Ok(v.chunks_exact(3)
        .map(|c| norm([c[0], c[1], c[2]]))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TriMesh;

    fn sphere() -> TriMesh {
        crate::generate::icosphere(1.0, 2).unwrap()
    }

    fn flat(mesh: &TriMesh) -> Vec<f64> {
        mesh.positions_flat()
    }

    #[test]
    fn uniformly_scaled_mesh_has_the_scale_as_stretch() {
        let mesh = sphere();
        let rest = flat(&mesh);
        let tris = mesh.triangles.clone();
        for s in [0.5, 1.0, 1.7] {
            // Also rotate and translate: stretch must not see rigid motion.
            let (c, sn) = (0.3f64.cos(), 0.3f64.sin());
            let x: Vec<f64> = rest
                .chunks_exact(3)
                .flat_map(|v| {
                    [
                        s * (c * v[0] - sn * v[1]) + 1.0,
                        s * (sn * v[0] + c * v[1]) - 2.0,
                        s * v[2] + 0.5,
                    ]
                })
                .collect();
            for val in face_area_stretch(&rest, &x, &tris).unwrap() {
                assert!((val - s).abs() < 1e-12, "area stretch {val} vs {s}");
            }
            for val in face_max_stretch(&rest, &x, &tris).unwrap() {
                assert!((val - s).abs() < 1e-12, "max stretch {val} vs {s}");
            }
        }
    }

    #[test]
    fn sheared_triangle_principal_stretch_matches_hand_value() {
        // Simple shear x' = x + g y of the unit right triangle in the xy plane: F = [[1, g], [0, 1]],
        // C = [[1, g], [g, 1 + g^2]], largest eigenvalue (2 + g^2 + g sqrt(4 + g^2)) / 2.
        let g = 0.5;
        let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, g, 1.0, 0.0];
        let tris = [[0, 1, 2]];
        let lmax = ((2.0 + g * g + g * (4.0f64 + g * g).sqrt()) / 2.0).sqrt();
        // For g = 0.5 this is (1 + sqrt(17)) / 4.
        assert!((lmax - 1.280_776_406_404_415).abs() < 1e-12);
        let got = face_max_stretch(&rest, &x, &tris).unwrap()[0];
        assert!((got - lmax).abs() < 1e-12, "{got} vs {lmax}");
        // Shear preserves area.
        let area = face_area_stretch(&rest, &x, &tris).unwrap()[0];
        assert!((area - 1.0).abs() < 1e-12);
        // Edge 0-1 rotated out of plane, edge 0-2 stretched by 3: max stretch 3, area stretch sqrt 3.
        let x = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 3.0, 0.0];
        assert!((face_max_stretch(&rest, &x, &tris).unwrap()[0] - 3.0).abs() < 1e-12);
        assert!((face_area_stretch(&rest, &x, &tris).unwrap()[0] - 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn checked_normals_match_the_mesh_normals_and_twice_area_sums() {
        let mesh = sphere();
        let x = flat(&mesh);
        let n = vertex_normals(&x, &mesh.triangles).unwrap();
        for (a, b) in n
            .chunks_exact(3)
            .zip(crate::geometry::vertex_normals(&mesh))
        {
            assert_eq!([a[0], a[1], a[2]], [b.x, b.y, b.z]);
        }
        let sums = vertex_area_normal_sums(&x, &mesh.triangles).unwrap();
        let total: f64 = sums
            .chunks_exact(3)
            .map(|s| (s[0].powi(2) + s[1].powi(2) + s[2].powi(2)).sqrt())
            .sum();
        // Each face contributes |e12 x e13| = 2 A to three vertices; on a sphere the per-vertex
        // sums are nearly aligned, so their lengths add up to just under 6 times the area.
        let area = crate::geometry::surface_area(&mesh);
        assert!(
            total <= 6.0 * area * (1.0 + 1e-12) && total > 5.9 * area,
            "{total} vs {area}"
        );
        assert!(matches!(
            vertex_area_normal_sums(&x, &[[0, 1, x.len()]]),
            Err(FieldError::VertexOutOfRange { .. })
        ));
    }

    #[test]
    fn vertex_normals_of_a_sphere_are_radial_and_unit() {
        let mesh = sphere();
        let x = flat(&mesh);
        let n = vertex_normals(&x, &mesh.triangles).unwrap();
        for (ni, xi) in n.chunks_exact(3).zip(x.chunks_exact(3)) {
            let l = (ni[0] * ni[0] + ni[1] * ni[1] + ni[2] * ni[2]).sqrt();
            assert!((l - 1.0).abs() < 1e-12);
            let r = (xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]).sqrt();
            let cos = (ni[0] * xi[0] + ni[1] * xi[1] + ni[2] * xi[2]) / r;
            assert!(cos > 0.99, "normal not radial: cos {cos}");
        }
    }

    #[test]
    fn face_to_vertex_is_area_weighted() {
        // Two triangles sharing edge 1-2, areas 0.5 and 1.0.
        let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 2.0, 0.0];
        let tris = [[0, 1, 2], [1, 3, 2]];
        let areas = face_areas(&x, &tris).unwrap();
        assert!((areas[0] - 0.5).abs() < 1e-15);
        let a1 = areas[1];
        let v = face_to_vertex(&x, &tris, &[1.0, 4.0]).unwrap();
        assert_eq!(v[0], 1.0);
        assert_eq!(v[3], 4.0);
        let expect = (0.5 * 1.0 + a1 * 4.0) / (0.5 + a1);
        assert!((v[1] - expect).abs() < 1e-14 && (v[2] - expect).abs() < 1e-14);
        // A constant field stays constant.
        let c = face_to_vertex(&x, &tris, &[2.5, 2.5]).unwrap();
        assert!(c.iter().all(|&s| (s - 2.5).abs() < 1e-15));
    }

    #[test]
    fn speeds_and_bad_input() {
        assert_eq!(
            vertex_speeds(&[3.0, 4.0, 0.0, 0.0, 0.0, -2.0]).unwrap(),
            vec![5.0, 2.0]
        );
        assert!(matches!(
            vertex_speeds(&[1.0, 2.0]),
            Err(FieldError::LengthMismatch { name: "v", .. })
        ));
        let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0];
        let err = face_max_stretch(&rest, &rest, &[[0, 1, 2]]).unwrap_err();
        assert!(matches!(
            err,
            FieldError::DegenerateRestTriangle { triangle: 0, .. }
        ));
        let err = face_area_stretch(&rest, &rest, &[[0, 1, 5]]).unwrap_err();
        assert!(err.to_string().contains("vertex 5"), "{err}");
        let err = face_area_stretch(&rest, &rest[..6], &[[0, 1, 2]]).unwrap_err();
        assert!(matches!(err, FieldError::LengthMismatch { name: "x", .. }));
        let err = face_to_vertex(&rest, &[[0, 1, 2]], &[]).unwrap_err();
        assert!(err.to_string().contains("face_values"));
    }

    #[test]
    fn degenerate_soup_triangles_get_nan_and_the_rest_is_kept() {
        // Triangle 0 is a unit right triangle stretched by 2 along x; triangle 1 is a
        // zero-area sliver (collinear points) as triangle soups may hold.
        let rest = [
            0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, // triangle 0
            0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 2.0, 0.0, 1.0, // collinear
        ];
        let mut x = rest;
        x[3] = 2.0;
        let tris = [[0, 1, 2], [3, 4, 5]];
        assert!(face_area_stretch(&rest, &x, &tris).is_err());
        let area = face_area_stretch_or_nan(&rest, &x, &tris).unwrap();
        assert!(
            (area[0] - 2f64.sqrt()).abs() < 1e-14 && area[1].is_nan(),
            "{area:?}"
        );
        let max = face_max_stretch_or_nan(&rest, &x, &tris).unwrap();
        assert!((max[0] - 2.0).abs() < 1e-14 && max[1].is_nan(), "{max:?}");
        // Averaged to vertices: the good triangle's vertices keep its value, the sliver's
        // vertices (no defined face) are NaN; nothing else is polluted.
        let v = face_to_vertex(&x, &tris, &area).unwrap();
        assert!(
            v[..3].iter().all(|s| (s - 2f64.sqrt()).abs() < 1e-14),
            "{v:?}"
        );
        assert!(v[3..].iter().all(|s| s.is_nan()), "{v:?}");
        // Other input errors still fail.
        assert!(face_area_stretch_or_nan(&rest, &x[..9], &tris).is_err());
    }
}
