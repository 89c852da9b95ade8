//! Tests of the lattice generator.

use super::*;
use crate::TriMesh;
use crate::generate::icosphere;
use nalgebra::{Point3, Vector3};

fn sphere_params(resolution: usize) -> LatticeParams {
    LatticeParams {
        resolution,
        ..LatticeParams::default()
    }
}

fn sphere_volume(r: f64) -> f64 {
    4.0 / 3.0 * std::f64::consts::PI * r * r * r
}

/// Every tetrahedron positive, every cell's five tetrahedra present, and each interior
/// triangular face shared by exactly two tetrahedra (a conforming mesh: the face diagonals of
/// neighbouring cells match).
fn assert_conforming(l: &Lattice) {
    use std::collections::HashMap;
    let mut faces: HashMap<[usize; 3], usize> = HashMap::new();
    for (t, tet) in l.tet_mesh.tets.iter().enumerate() {
        assert!(l.tet_mesh.tet_volume(t) > 0.0, "tet {t} not positive");
        for skip in 0..4 {
            let mut f: Vec<usize> = (0..4).filter(|&i| i != skip).map(|i| tet[i]).collect();
            f.sort_unstable();
            *faces.entry([f[0], f[1], f[2]]).or_default() += 1;
        }
    }
    assert!(faces.values().all(|&n| n <= 2), "a face shared by 3+ tets");
    // Boundary faces count: each boundary cell face is split into 2 triangles; an interior
    // quad face whose diagonals did not match would leave 4 unmatched triangles inside.
    let boundary = faces.values().filter(|&&n| n == 1).count();
    let cell_set: std::collections::HashSet<[usize; 3]> = l.cell_coords.iter().copied().collect();
    let mut open_quads = 0;
    for &[i, j, k] in &l.cell_coords {
        for (a, b, c) in [
            (i as i64 - 1, j as i64, k as i64),
            (i as i64 + 1, j as i64, k as i64),
            (i as i64, j as i64 - 1, k as i64),
            (i as i64, j as i64 + 1, k as i64),
            (i as i64, j as i64, k as i64 - 1),
            (i as i64, j as i64, k as i64 + 1),
        ] {
            if a < 0 || b < 0 || c < 0 || !cell_set.contains(&[a as usize, b as usize, c as usize])
            {
                open_quads += 1;
            }
        }
    }
    assert_eq!(boundary, 2 * open_quads, "non-conforming faces");
}

#[test]
fn icosphere_pseudo_volume_close_to_enclosed_volume() {
    // r = 1 icosphere (level 3, enclosed volume 4.13) at resolution 48, 4 voxels per cell
    // (12 cells across): the smoothed tetrahedral volume is within 3 % of the sphere volume (measured 1.1 %)
    // and the voxel pseudo volume within 3 % (measured 1.9 %).
    let soup = icosphere(1.0, 3).unwrap();
    let l = build_lattice(&soup, &sphere_params(48)).unwrap();
    let exact = sphere_volume(1.0);
    let tv = l.tet_mesh.total_volume();
    eprintln!(
        "cells {} tets {} tet volume {tv} pseudo {} exact {exact}",
        l.cells.len(),
        l.tet_mesh.tets.len(),
        l.info.pseudo_volume
    );
    assert!(
        (tv / exact - 1.0).abs() < 0.03,
        "tet volume {tv} vs {exact}"
    );
    assert!((l.info.pseudo_volume / exact - 1.0).abs() < 0.03);
    assert_eq!(l.tet_mesh.tets.len(), 5 * l.cells.len());
    assert_conforming(&l);
    // Smoothing preserved the volume.
    assert!((tv / l.info.volume_before_smoothing - 1.0).abs() < 1e-12);
    // Every soup vertex is embedded with weights summing to one, and interpolating the rest
    // lattice reproduces the soup exactly.
    let back = l.embedding.positions(&l.tet_mesh.vertices);
    for (p, q) in back.iter().zip(&soup.vertices) {
        assert!((p - q).norm() < 1e-9);
    }
}

#[test]
fn soup_with_hole_still_gives_a_body() {
    // Removing 10 of 1280 triangles opens the sphere; rays through the hole abstain and the
    // others still carve the ball: volume within 12 % of the closed sphere's.
    let mut soup = icosphere(1.0, 3).unwrap();
    soup.triangles.drain(100..110);
    let l = build_lattice(&soup, &sphere_params(32)).unwrap();
    let tv = l.tet_mesh.total_volume();
    assert!((tv / sphere_volume(1.0) - 1.0).abs() < 0.12, "{tv}");
    assert_conforming(&l);
}

#[test]
fn flipped_and_duplicated_triangles_give_the_same_lattice() {
    // The distance field is unsigned, so orientation and duplicates cannot matter.
    let soup = icosphere(1.0, 2).unwrap();
    let mut messy = soup.clone();
    for t in messy.triangles.iter_mut().step_by(3) {
        t.swap(1, 2);
    }
    let dup: Vec<_> = messy.triangles[..40].to_vec();
    messy.triangles.extend(dup);
    let p = sphere_params(24);
    let a = build_lattice(&soup, &p).unwrap();
    let b = build_lattice(&messy, &p).unwrap();
    assert_eq!(a.tet_mesh, b.tet_mesh);
    assert_eq!(a.cells, b.cells);
}

#[test]
fn mirror_symmetric_soup_gives_mirror_symmetric_lattice() {
    // A sphere is symmetric about x = 0: after axis-aligned smoothing the vertex set must be
    // too (Fig. 2: diagonal umbrellas would break this).
    let soup = icosphere(1.0, 3).unwrap();
    let l = build_lattice(&soup, &sphere_params(32)).unwrap();
    let c = l
        .tet_mesh
        .vertices
        .iter()
        .fold(Vector3::zeros(), |a, p| a + p.coords)
        / l.tet_mesh.vertices.len() as f64;
    let mut worst = 0.0f64;
    for p in &l.tet_mesh.vertices {
        let m = Point3::new(2.0 * c.x - p.x, p.y, p.z);
        let d = l
            .tet_mesh
            .vertices
            .iter()
            .map(|q| (q - m).norm())
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    assert!(worst < 1e-9, "mirror image off by {worst}");
}

#[cfg(feature = "parallel")]
#[test]
fn serial_and_parallel_generation_agree() {
    // The distance field, the rays and the embedding run on rayon; a one-thread pool must
    // give the identical lattice.
    let soup = icosphere(1.0, 2).unwrap();
    let p = sphere_params(24);
    let parallel = build_lattice(&soup, &p).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let serial = pool.install(|| build_lattice(&soup, &p).unwrap());
    assert_eq!(parallel, serial);
}

#[test]
fn two_components_both_filled() {
    let a = icosphere(0.5, 2).unwrap();
    let mut soup = a.clone();
    let off = soup.vertices.len();
    soup.vertices
        .extend(a.vertices.iter().map(|p| p + Vector3::new(2.0, 0.0, 0.0)));
    soup.triangles
        .extend(a.triangles.iter().map(|t| t.map(|i| i + off)));
    let l = build_lattice(&soup, &sphere_params(40)).unwrap();
    let left = l.tet_mesh.vertices.iter().filter(|p| p.x < 1.0).count();
    let right = l.tet_mesh.vertices.len() - left;
    assert!(left > 20 && left == right, "{left} {right}");
}

#[test]
fn bad_input_gives_named_errors() {
    let empty = TriMesh::default();
    assert!(matches!(
        build_lattice(&empty, &LatticeParams::default()),
        Err(LatticeError::EmptySoup { .. })
    ));
    let soup = icosphere(1.0, 1).unwrap();
    let e = build_lattice(
        &soup,
        &LatticeParams {
            p_subs: 0.95,
            ..LatticeParams::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("p_subs"), "{e}");
    let e = build_lattice(
        &soup,
        &LatticeParams {
            rays: 0,
            ..LatticeParams::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("rays"));
    // A single flat triangle encloses nothing.
    let flat = TriMesh::new(
        vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2]],
    );
    assert!(matches!(
        build_lattice(&flat, &LatticeParams::default()),
        Err(LatticeError::NoInterior { .. })
    ));
    let bad = TriMesh::new(soup.vertices.clone(), vec![[0, 1, 999]]);
    assert!(matches!(
        build_lattice(&bad, &LatticeParams::default()),
        Err(LatticeError::BadIndex { index: 999, .. })
    ));
}

#[test]
fn vertex_outside_lattice_uses_extrapolated_weights() {
    // A soup vertex far outside still reproduces its rest position exactly by extrapolation.
    let mut soup = icosphere(1.0, 2).unwrap();
    soup.vertices.push(Point3::new(3.0, 0.0, 0.0));
    let n = soup.vertices.len();
    soup.triangles.push([n - 1, 0, 1]);
    let l = build_lattice(&soup, &sphere_params(24)).unwrap();
    let back = l.embedding.positions(&l.tet_mesh.vertices);
    assert!((back[n - 1] - soup.vertices[n - 1]).norm() < 1e-9);
    assert!(l.embedding.vertices[n - 1].weights.iter().any(|&w| w < 0.0));
}
