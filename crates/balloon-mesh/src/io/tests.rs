//! Tests of the readers and writers: round trips, format quirks, malformed inputs (errors that
//! name the file and line/byte, never a panic) and the shared real meshes.

use super::*;
use crate::generate::{icosphere, torus};
use crate::topology::Topology;
use crate::validate::validate_closed_manifold;
use nalgebra::Point3;
use proptest::prelude::*;
use std::path::PathBuf;

fn p() -> PathBuf {
    PathBuf::from("mesh_under_test.xyz")
}

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

/// Asserts that `r` is a parse error naming the file and a line or byte location.
fn assert_located(r: Result<TriMesh, MeshError>, what: &str) -> String {
    let e = r.expect_err(what);
    let msg = e.to_string();
    assert!(matches!(e, MeshError::Parse { .. }), "{what}: {msg}");
    assert!(msg.contains("mesh_under_test.xyz"), "{what}: {msg}");
    assert!(
        msg.contains(":line ") || msg.contains(":byte ") || msg.contains(":header"),
        "{what}: {msg}"
    );
    msg
}

#[test]
fn round_trips_through_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = icosphere(0.1, 2).unwrap();
    m.vertices[3].x = 1.0 / 3.0; // a value that needs all 17 digits
    for ext in ["obj", "off", "ply", "OBJ", "stl"] {
        let path = dir.path().join(format!("m.{ext}"));
        write_mesh(&path, &m).unwrap();
        let r = read_mesh(&path).unwrap();
        if ext == "stl" {
            // STL stores a soup of f32 corners; welding restores the indexed mesh.
            assert_eq!(r.num_vertices(), m.num_vertices());
            assert_eq!(r.num_triangles(), m.num_triangles());
            validate_closed_manifold(&r).unwrap();
            let err = (crate::geometry::enclosed_volume(&r) / crate::geometry::enclosed_volume(&m)
                - 1.0)
                .abs();
            assert!(err < 1e-6, "{err}");
        } else {
            assert_eq!(r, m, "{ext} round trip");
        }
    }
    let err = write_mesh(&dir.path().join("m.xyz"), &m)
        .unwrap_err()
        .to_string();
    assert!(err.contains("m.xyz") && err.contains(".obj"), "{err}");
    let err = read_mesh(&dir.path().join("m.vtk"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("unsupported"), "{err}");
    let err = read_mesh(&dir.path().join("missing.obj")).unwrap_err();
    assert!(matches!(err, MeshError::Io { .. }) && err.to_string().contains("missing.obj"));
}

#[test]
fn obj_quirks() {
    let text = "# comment\nmtllib a.mtl\no thing\nv 0 0 0 1.0\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nv 0 1 0\r\n\
                vt 0 0\nvn 0 0 1\ng group\ns off\nusemtl red\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -2//1 -1//1\nl 1 2\n";
    let m = parse_obj(text.as_bytes(), &p()).unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    let m = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2 2/3 3/4\n", &p()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
}

#[test]
fn off_quirks() {
    // Princeton benchmark style: comments, blank lines, counts on the next line.
    let a = "OFF\n# made by hand\n\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    let m = parse_off(a.as_bytes(), &p()).unwrap();
    assert_eq!(m, tetra());
    // Counts on the header line, and glued to it (ModelNet).
    let b = a.replace("OFF\n# made by hand\n\n4 4 6\n", "OFF 4 4 6\n");
    assert_eq!(parse_off(b.as_bytes(), &p()).unwrap(), tetra());
    let c = a.replace("OFF\n# made by hand\n\n4 4 6\n", "OFF4 4 6\n");
    assert_eq!(parse_off(c.as_bytes(), &p()).unwrap(), tetra());
    // COFF with per-vertex and per-face colours; a quad is fan-triangulated.
    let d = "COFF\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n1 1 0 1 2 3 4\n0 1 0 0 0 0 0\n4 0 1 2 3 0.5 0.5 0.5\n";
    let m = parse_off(d.as_bytes(), &p()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    let e = "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n";
    assert_eq!(parse_off(e.as_bytes(), &p()).unwrap().num_triangles(), 1);
}

fn ply_header(format: &str, vertex_props: &str, face_prop: &str, nv: usize, nf: usize) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment test\nobj_info x\nelement extra 2\nproperty float a\nproperty list uchar int l\n\
         element vertex {nv}\n{vertex_props}element face {nf}\n{face_prop}property uchar red\nelement edge 1\nproperty int v1\nproperty int v2\nend_header\n"
    )
}

#[test]
fn ply_ascii_and_binary_with_unknown_elements() {
    let t = tetra();
    // ASCII: an unknown element before the vertices (with a list), extra vertex and face
    // properties, `vertex_index` spelling, an unknown element after the faces.
    let mut a = ply_header(
        "ascii",
        "property float nx\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n",
        "property list uint ushort vertex_index\n",
        4,
        4,
    );
    a.push_str("1.5 2 7 8\n2.5 0\n");
    for v in &t.vertices {
        a.push_str(&format!("9 {} {} {} 200\n", v.x, v.y, v.z));
    }
    for f in &t.triangles {
        a.push_str(&format!("3 {} {} {} 12\n", f[0], f[1], f[2]));
    }
    a.push_str("0 1\n");
    assert_eq!(parse_ply(a.as_bytes(), &p()).unwrap(), t);
    // Binary, both endiannesses, mixed scalar types (int16 x, float y, double z).
    for (fmt, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
        let mut b = ply_header(
            fmt,
            "property short x\nproperty float y\nproperty double z\n",
            "property list uchar int vertex_indices\n",
            4,
            4,
        )
        .into_bytes();
        let put = |b: &mut Vec<u8>, bytes: &[u8]| {
            if big {
                b.extend(bytes.iter().rev());
            } else {
                b.extend_from_slice(bytes);
            }
        };
        for a in [1.5f32, 2.5] {
            put(&mut b, &a.to_le_bytes());
            b.push(if a < 2.0 { 2 } else { 0 });
            if a < 2.0 {
                put(&mut b, &7i32.to_le_bytes());
                put(&mut b, &8i32.to_le_bytes());
            }
        }
        for v in &t.vertices {
            put(&mut b, &(v.x as i16).to_le_bytes());
            put(&mut b, &(v.y as f32).to_le_bytes());
            put(&mut b, &v.z.to_le_bytes());
        }
        for f in &t.triangles {
            b.push(3);
            for &i in f {
                put(&mut b, &(i as i32).to_le_bytes());
            }
            b.push(12);
        }
        put(&mut b, &0i32.to_le_bytes());
        put(&mut b, &1i32.to_le_bytes());
        assert_eq!(parse_ply(&b, &p()).unwrap(), t, "{fmt}");
        // Truncating the binary body names a byte offset.
        let msg = assert_located(parse_ply(&b[..b.len() - 10], &p()), fmt);
        assert!(msg.contains("byte"), "{msg}");
    }
}

#[test]
fn ply_thickness_property_of_vertices_or_faces_with_polygons_fanned() {
    // A square (one quad, two triangles) with a per-face thickness after the index list.
    let face = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                property float z\nelement face 2\nproperty list uchar int vertex_indices\n\
                property double thickness\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n\
                4 0 1 2 3 0.002\n3 0 2 3 0.001\n";
    let (mesh, prop) = parse_ply_with_property(face.as_bytes(), &p(), "thickness").unwrap();
    assert_eq!(mesh.triangles.len(), 3);
    assert_eq!(prop, PlyProperty::PerFace(vec![0.002, 0.002, 0.001]));
    // Absent, and the plain reader is unchanged.
    let (_, none) = parse_ply_with_property(face.as_bytes(), &p(), "density").unwrap();
    assert_eq!(none, PlyProperty::Absent);
    assert_eq!(parse_ply(face.as_bytes(), &p()).unwrap(), mesh);
    // Per vertex (a vertex property wins over a face property of the same name).
    let vert = face
        .replace(
            "property float z\n",
            "property float z\nproperty float thickness\n",
        )
        .replace(
            "0 0 0\n1 0 0\n1 1 0\n0 1 0\n",
            "0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n",
        );
    let (_, prop) = parse_ply_with_property(vert.as_bytes(), &p(), "thickness").unwrap();
    assert_eq!(prop, PlyProperty::PerVertex(vec![1.0, 2.0, 3.0, 4.0]));
}

#[test]
fn stl_ascii_binary_solid_header_and_welding() {
    let t = tetra();
    let mut ascii = String::from("solid tetra\n");
    for f in &t.triangles {
        ascii.push_str("  facet normal 0 0 0\n    outer loop\n");
        for &i in f {
            let v = t.vertices[i];
            ascii.push_str(&format!("      vertex {} {} {}\n", v.x, v.y, v.z));
        }
        ascii.push_str("    endloop\n  endfacet\n");
    }
    ascii.push_str("endsolid tetra\n");
    let m = parse_stl(ascii.as_bytes(), &p(), 0.0).unwrap();
    assert_eq!(m.num_vertices(), 4);
    validate_closed_manifold(&m).unwrap();
    // A binary file whose header starts with "solid" is still read as binary.
    let mut bin = Vec::new();
    stl::write_stl_to(&mut bin, &t).unwrap();
    bin[..5].copy_from_slice(b"solid");
    let m = parse_stl(&bin, &p(), 0.0).unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.num_triangles(), 4);
    // Welding with a tolerance merges nearly coincident corners; exact welding does not.
    let mut jitter = t.clone();
    let soup = TriMesh::new(
        jitter
            .triangles
            .iter()
            .enumerate()
            .flat_map(|(k, f)| {
                f.map(|i| jitter.vertices[i] + nalgebra::Vector3::x() * 1e-7 * k as f64)
            })
            .collect(),
        (0..4).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect(),
    );
    jitter = soup;
    let mut bin = Vec::new();
    stl::write_stl_to(&mut bin, &jitter).unwrap();
    assert!(parse_stl(&bin, &p(), 0.0).unwrap().num_vertices() > 4);
    assert_eq!(parse_stl(&bin, &p(), 1e-5).unwrap().num_vertices(), 4);
}

#[test]
fn malformed_inputs_name_file_and_location() {
    let obj_cases: &[(&str, &str)] = &[
        ("", "empty"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "index out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "index zero"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 2 3\n",
            "relative index out of range",
        ),
        ("v 0 0 abc\n", "bad number"),
        ("v 0 0\n", "too few coordinates"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "two-corner face"),
        ("v 0 0 nan\n", "non-finite"),
        ("v 0 0 0\nf x y z\n", "non-integer index"),
    ];
    for (text, what) in obj_cases {
        assert_located(parse_obj(text.as_bytes(), &p()), what);
    }
    let good = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    let off_cases: Vec<(String, &str)> = vec![
        (String::new(), "empty"),
        ("PLY\n".into(), "wrong header"),
        (good[..good.len() - 20].into(), "truncated"),
        (good.replace("4 4 0", "5 4 0"), "wrong vertex count"),
        (good.replace("4 4 0", "4 9 0"), "wrong face count"),
        (good.replace("1 0 0\n", "1 zero 0\n"), "bad number"),
        (good.replace("3 1 2 3", "3 1 2 4"), "index out of range"),
        (good.replace("3 1 2 3", "2 1 2"), "two-corner face"),
        (good.replace("3 1 2 3", "4 1 2 3"), "short face"),
        ("OFF\n".into(), "no counts"),
        ("OFF\n4\n".into(), "one count"),
    ];
    for (text, what) in &off_cases {
        assert_located(parse_off(text.as_bytes(), &p()), what);
    }
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert_eq!(parse_ply(ply.as_bytes(), &p()).unwrap().num_triangles(), 1);
    // A property-less element occupies no bytes however large its count (no long loop).
    let empty = ply.replace(
        "element face 1",
        "element empty 18446744073709551615\nelement face 1",
    );
    assert_eq!(
        parse_ply(empty.as_bytes(), &p()).unwrap().num_triangles(),
        1
    );
    let ply_cases: Vec<(String, &str)> = vec![
        (String::new(), "empty"),
        ("ply\n".into(), "no end_header"),
        (ply.replace("format ascii", "format weird"), "bad format"),
        (
            ply.replace("property float y", "property quad y"),
            "bad type",
        ),
        (ply.replace("3 0 1 2", "3 0 1 3"), "index out of range"),
        (ply.replace("3 0 1 2", "3 0 1"), "truncated"),
        (ply.replace("1 0 0", "1 x 0"), "bad number"),
        (
            ply.replace("element vertex 3", "element vertex 4"),
            "wrong count",
        ),
        (ply.replace("property float z\n", ""), "missing z"),
        (ply.replace("3 0 1 2", "2 0 1"), "two-corner face"),
        ("solid\n".into(), "not ply"),
    ];
    for (text, what) in &ply_cases {
        assert_located(parse_ply(text.as_bytes(), &p()), what);
    }
    let stl = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n";
    assert_eq!(
        parse_stl(stl.as_bytes(), &p(), 0.0)
            .unwrap()
            .num_triangles(),
        1
    );
    let mut short_bin = vec![0u8; 84 + 50];
    short_bin[80] = 2; // announces 2 triangles, holds 1
    let stl_cases: Vec<(Vec<u8>, &str)> = vec![
        (Vec::new(), "empty"),
        (b"hello".to_vec(), "garbage"),
        (
            stl.replace("vertex 1 0 0", "vertex 1 q 0").into_bytes(),
            "bad number",
        ),
        (stl.as_bytes()[..60].to_vec(), "truncated ascii"),
        (
            stl.replace("vertex 0 1 0\n", "").into_bytes(),
            "two-vertex facet",
        ),
        (short_bin, "binary size mismatch"),
        (vec![0u8; 84], "binary without triangles"),
    ];
    for (bytes, what) in &stl_cases {
        assert_located(parse_stl(bytes, &p(), 0.0), what);
    }
}

fn valid_samples() -> Vec<(&'static str, Vec<u8>)> {
    let m = torus(1.0, 0.3, 6, 4).unwrap();
    let mut obj = Vec::new();
    for v in &m.vertices {
        obj.extend(format!("v {} {} {}\n", v.x, v.y, v.z).bytes());
    }
    for t in &m.triangles {
        obj.extend(format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1).bytes());
    }
    let mut off = Vec::new();
    off::write_off_to(&mut off, &m).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.ply");
    write_ply_binary(&path, &m).unwrap();
    let ply = std::fs::read(&path).unwrap();
    let mut stl = Vec::new();
    stl::write_stl_to(&mut stl, &m).unwrap();
    vec![("obj", obj), ("off", off), ("ply", ply), ("stl", stl)]
}

fn parse_any(kind: &str, bytes: &[u8]) -> Result<TriMesh, MeshError> {
    match kind {
        "obj" => parse_obj(bytes, &p()),
        "off" => parse_off(bytes, &p()),
        "ply" => parse_ply(bytes, &p()),
        _ => parse_stl(bytes, &p(), 0.0),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random bytes never make a reader panic; any mesh returned has in-range indices.
    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        for kind in ["obj", "off", "ply", "stl"] {
            if let Ok(m) = parse_any(kind, &bytes) {
                prop_assert!(m.triangles.iter().flatten().all(|&i| i < m.num_vertices()));
            }
        }
    }

    /// Mutating, truncating or inserting bytes in valid files never makes a reader panic, and
    /// every error names the file and a location.
    #[test]
    fn mutated_files_never_panic(
        which in 0usize..4,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..6),
        cut in any::<prop::sample::Index>(),
    ) {
        let samples = valid_samples();
        let (kind, mut bytes) = samples[which].clone();
        for (at, byte, op) in edits {
            let i = at.index(bytes.len());
            match op {
                0 => bytes[i] = byte,
                1 => bytes.insert(i, byte),
                _ => { bytes.remove(i); }
            }
        }
        if cut.index(4) == 0 {
            let n = cut.index(bytes.len());
            bytes.truncate(n);
        }
        match parse_any(kind, &bytes) {
            Ok(m) => prop_assert!(m.triangles.iter().flatten().all(|&i| i < m.num_vertices())),
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(msg.contains("mesh_under_test.xyz"), "{}", msg);
            }
        }
    }
}

fn shared(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/meshes")
        .join(name);
    if p.is_file() {
        Some(p)
    } else {
        // In CI the real meshes must be there: a skipped check would pass silently.
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but {} is missing",
            p.display()
        );
        eprintln!("skipping: {} not found", p.display());
        None
    }
}

#[test]
fn shared_meshes_match_their_readme() {
    // Counts and genus from /work/shared/meshes/README.md; all are closed outward 2-manifolds.
    for (name, v, f, genus) in [
        ("spot.obj", 11533, 23062, 0),
        ("armadillo_lowres.obj", 14587, 29170, 0),
        ("bunny_closed_libigl.off", 3485, 6966, 0),
        ("torus.obj", 2304, 4608, 1),
    ] {
        let Some(path) = shared(name) else { continue };
        let m = read_mesh(&path).unwrap();
        assert_eq!((m.num_vertices(), m.num_triangles()), (v, f), "{name}");
        let topo = Topology::new(&m);
        assert_eq!(topo.genus(&m.triangles), Some(genus), "{name}");
        let rep = crate::validate::validate(&m, &Default::default());
        assert!(rep.is_valid(), "{name}: {:?}", rep.defects.first());
        if name.starts_with("bunny") {
            // README: "smallest angle 2.7 degrees".
            let a = crate::geometry::min_angle_degrees(&m).unwrap();
            assert!((a - 2.7).abs() < 0.05, "{a}");
        }
        assert!(
            rep.closed && rep.manifold && rep.consistently_oriented && rep.outward,
            "{name}: {:?}",
            rep.defects.first()
        );
    }
}

#[test]
fn off_face_size_that_overflows_is_an_error_not_a_panic() {
    let src = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n18446744073709551615 0 1 2\n";
    let msg = assert_located(parse_off(src, &p()), "huge face size");
    assert!(msg.contains("announces"), "{msg}");
}

#[test]
fn a_byte_order_mark_is_skipped_in_every_text_format() {
    let bom = |s: &str| [&b"\xEF\xBB\xBF"[..], s.as_bytes()].concat();
    // OBJ: the first line is a vertex; before the fix it was silently dropped.
    let obj = bom("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    let m = parse_obj(&obj, &p()).unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m, tetra());
    let off = bom("OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    assert_eq!(parse_off(&off, &p()).unwrap(), tetra());
    let ply = bom(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n",
    );
    assert_eq!(parse_ply(&ply, &p()).unwrap(), tetra());
    let mut stl = String::from("solid t\n");
    let t = tetra();
    for tri in &t.triangles {
        stl.push_str("facet normal 0 0 0\nouter loop\n");
        for &i in tri {
            let v = t.vertices[i];
            stl.push_str(&format!("vertex {} {} {}\n", v.x, v.y, v.z));
        }
        stl.push_str("endloop\nendfacet\n");
    }
    stl.push_str("endsolid t\n");
    let m = parse_stl(&bom(&stl), &p(), 0.0).unwrap();
    assert_eq!((m.num_vertices(), m.num_triangles()), (4, 4));
}

#[test]
fn inputs_with_only_degenerate_faces_are_refused() {
    // STL whose facets all collapse to a point or a repeated corner.
    let stl = "solid d\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0 0 0\nvertex 1 0 0\n\
               endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 2 2 2\nvertex 2 2 2\n\
               vertex 2 2 2\nendloop\nendfacet\nendsolid d\n";
    let msg = assert_located(parse_stl(stl.as_bytes(), &p(), 0.0), "degenerate STL");
    assert!(msg.contains("degenerate"), "{msg}");
    // OBJ and OFF with collinear corners only.
    let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n";
    let msg = assert_located(parse_obj(obj.as_bytes(), &p()), "collinear OBJ");
    assert!(msg.contains("zero area"), "{msg}");
    let off = "OFF\n3 1 0\n0 0 0\n1 1 1\n2 2 2\n3 0 1 2\n";
    let msg = assert_located(parse_off(off.as_bytes(), &p()), "collinear OFF");
    assert!(msg.contains("zero area"), "{msg}");
    // One real face among degenerate ones is a mesh (validation reports the rest).
    let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n";
    assert_eq!(parse_obj(obj.as_bytes(), &p()).unwrap().num_triangles(), 2);
}

#[test]
fn messages_escape_control_characters_and_cut_long_tokens() {
    let long = "9".repeat(5_000_000) + "x";
    let src = format!("v 0 0 \x1b[31mred\x07\nv {long} 0 0\n");
    let msg = assert_located(parse_obj(src.as_bytes(), &p()), "escape");
    assert!(!msg.contains('\x1b') && !msg.contains('\x07'), "{msg:?}");
    assert!(msg.contains("\\u{1b}"), "{msg}");
    let src = format!("v 0 0 0\nv {long} 0 0\n");
    let msg = assert_located(parse_obj(src.as_bytes(), &p()), "long token");
    assert!(msg.len() < 600, "{} bytes: {}", msg.len(), &msg[..200]);
    assert!(msg.contains("more bytes"), "{msg}");
    // Ordinary messages are unchanged.
    let msg = assert_located(parse_obj(b"v 0 0\n", &p()), "short");
    assert!(
        msg.ends_with("vertex needs 3 coordinates, found 2"),
        "{msg}"
    );
}

#[cfg(unix)]
#[test]
fn devices_directories_fifos_and_huge_files_are_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    // A symlink named like a mesh that points at an endless device.
    let link = dir.path().join("zero.obj");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let e = read_mesh(&link).unwrap_err();
    assert!(matches!(e, MeshError::NotAFile { .. }), "{e}");
    assert!(e.to_string().contains("character device"), "{e}");
    // A directory with a mesh extension.
    let sub = dir.path().join("folder.off");
    std::fs::create_dir(&sub).unwrap();
    let e = read_mesh(&sub).unwrap_err();
    assert!(e.to_string().contains("directory"), "{e}");
    // A FIFO (reading it would block forever).
    let fifo = dir.path().join("pipe.stl");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        let e = read_mesh(&fifo).unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
    }
    // A sparse file past the size limit: refused by its size, nothing allocated.
    let big = dir.path().join("big.ply");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(MAX_MESH_FILE_BYTES + 1).unwrap();
    let e = read_mesh(&big).unwrap_err();
    assert!(matches!(e, MeshError::FileTooLarge { .. }), "{e}");
    assert!(e.to_string().contains("big.ply"), "{e}");
}

/// A face property written by `write_ply_binary_with_face_property` reads back as the same
/// values, face by face, and the mesh as the same mesh; a property of the wrong length is
/// refused and names it.
#[test]
fn a_face_property_written_to_ply_reads_back() {
    let m = crate::generate::icosphere(0.1, 1).unwrap();
    let values: Vec<f64> = (0..m.num_triangles())
        .map(|i| 1e-3 + i as f64 * 1e-6)
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.ply");
    write_ply_binary_with_face_property(&path, &m, Some(("thickness", &values))).unwrap();
    let (back, property) = read_ply_with_property(&path, "thickness").unwrap();
    assert_eq!(back.triangles, m.triangles);
    assert_eq!(back.vertices, m.vertices);
    assert_eq!(property, PlyProperty::PerFace(values.clone()));
    let err = write_ply_binary_with_face_property(&path, &m, Some(("thickness", &values[1..])))
        .unwrap_err();
    assert!(err.to_string().contains("thickness"), "{err}");
}
