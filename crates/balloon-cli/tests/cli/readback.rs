//! The written VTK files read back by readers that are not the project's own: `series.pvd` and
//! the `.vtp` frames with `roxmltree` (XML) and `base64` (the binary payloads), the volumetric
//! lattice (legacy VTK, ASCII) by a few lines of parsing here. What they hold is checked
//! against independent measurements: counts from `mesh info`, the volume the decoded surface
//! encloses against the summary's gas volume, and each lattice cell's volume against its rest
//! volume (volume conservation measured on the written geometry, not by the projection's own
//! error).

use super::{last_json_line, obj_points, run_balloon};
use base64::Engine as _;
use std::collections::HashMap;
use std::path::Path;

/// One decoded `DataArray`: its name (empty for the points), components and values as f64.
struct Array {
    name: String,
    components: usize,
    values: Vec<f64>,
}

/// Decodes a `format="binary"` array: base64 of a UInt64 byte count and the little-endian
/// 8-byte values; checks the count against the payload.
fn decode(node: roxmltree::Node<'_, '_>) -> Array {
    assert_eq!(node.attribute("format"), Some("binary"), "{node:?}");
    let text: String = node
        .text()
        .unwrap_or("")
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(text.as_bytes())
        .expect("valid base64");
    assert!(bytes.len() >= 8, "no header");
    let count = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    assert_eq!(bytes.len(), 8 + count, "header byte count != payload");
    assert_eq!(count % 8, 0, "payload is not 8-byte words");
    let words = bytes[8..].chunks_exact(8).map(|c| c.try_into().unwrap());
    let values = match node.attribute("type") {
        Some("Float64") => words.map(f64::from_le_bytes).collect(),
        Some("Int64") => words.map(|w| i64::from_le_bytes(w) as f64).collect(),
        t => panic!("unexpected DataArray type {t:?}"),
    };
    Array {
        name: node.attribute("Name").unwrap_or("").to_string(),
        components: node
            .attribute("NumberOfComponents")
            .map_or(1, |c| c.parse().unwrap()),
        values,
    }
}

/// A `.vtp` file: point and cell counts, points, triangles and the named point / cell arrays.
struct PolyData {
    points: Vec<f64>,
    triangles: Vec<[usize; 3]>,
    point_data: Vec<Array>,
    cell_data: Vec<Array>,
}

fn read_vtp(path: &Path) -> PolyData {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text)
        .unwrap_or_else(|e| panic!("{}: not XML: {e}", path.display()));
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "VTKFile");
    assert_eq!(root.attribute("type"), Some("PolyData"));
    assert_eq!(root.attribute("byte_order"), Some("LittleEndian"));
    assert_eq!(root.attribute("header_type"), Some("UInt64"));
    let piece = root
        .descendants()
        .find(|n| n.has_tag_name("Piece"))
        .expect("a Piece");
    let count = |a: &str| -> usize { piece.attribute(a).unwrap().parse().unwrap() };
    let (np, nc) = (count("NumberOfPoints"), count("NumberOfPolys"));
    let arrays_of = |section: &str| -> Vec<Array> {
        piece
            .children()
            .find(|n| n.has_tag_name(section))
            .map(|s| {
                s.children()
                    .filter(|n| n.has_tag_name("DataArray"))
                    .map(decode)
                    .collect()
            })
            .unwrap_or_default()
    };
    let points = arrays_of("Points").pop().expect("Points");
    assert_eq!(points.components, 3);
    assert_eq!(points.values.len(), 3 * np, "points");
    let polys = arrays_of("Polys");
    let by_name = |n: &str| {
        polys
            .iter()
            .find(|a| a.name == n)
            .unwrap_or_else(|| panic!("no {n}"))
    };
    let conn = &by_name("connectivity").values;
    let offsets = &by_name("offsets").values;
    assert_eq!(conn.len(), 3 * nc);
    assert_eq!(offsets.len(), nc);
    for (k, o) in offsets.iter().enumerate() {
        assert_eq!(*o as usize, 3 * (k + 1), "triangles only");
    }
    let triangles: Vec<[usize; 3]> = conn
        .chunks_exact(3)
        .map(|c| [c[0] as usize, c[1] as usize, c[2] as usize])
        .collect();
    assert!(
        triangles.iter().flatten().all(|&i| i < np),
        "index out of range"
    );
    let point_data = arrays_of("PointData");
    let cell_data = arrays_of("CellData");
    for a in &point_data {
        assert_eq!(a.values.len(), a.components * np, "point array {}", a.name);
    }
    for a in &cell_data {
        assert_eq!(a.values.len(), a.components * nc, "cell array {}", a.name);
    }
    PolyData {
        points: points.values,
        triangles,
        point_data,
        cell_data,
    }
}

/// The volume a closed surface encloses: the sum of signed tetrahedra to the origin.
fn enclosed_volume(x: &[f64], triangles: &[[usize; 3]]) -> f64 {
    let p = |i: usize| [x[3 * i], x[3 * i + 1], x[3 * i + 2]];
    triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0
        })
        .sum()
}

#[test]
fn vtp_frames_and_the_pvd_series_read_back_independently() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let info = last_json_line(&run_balloon(&[
        "mesh",
        "info",
        "builtin:icosphere",
        "--json",
    ]));
    let (nv, nt) = (
        info["vertices"].as_u64().unwrap() as usize,
        info["triangles"].as_u64().unwrap() as usize,
    );
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--steps",
        "4",
        "--frame-every",
        "2",
        "--format",
        "vtk",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = last_json_line(&out);
    // The series lists every frame with its time, in order.
    let pvd = std::fs::read_to_string(run.join("series.pvd")).unwrap();
    let doc = roxmltree::Document::parse(&pvd).expect("series.pvd is XML");
    assert_eq!(doc.root_element().attribute("type"), Some("Collection"));
    let sets: Vec<(f64, String)> = doc
        .descendants()
        .filter(|n| n.has_tag_name("DataSet"))
        .map(|n| {
            (
                n.attribute("timestep").unwrap().parse().unwrap(),
                n.attribute("file").unwrap().to_string(),
            )
        })
        .collect();
    let names: Vec<&str> = sets.iter().map(|s| s.1.as_str()).collect();
    assert_eq!(
        names,
        ["frame_00000.vtp", "frame_00002.vtp", "frame_00004.vtp"]
    );
    let dt = summary["sim_time_s"].as_f64().unwrap() / 4.0;
    for (k, (t, _)) in sets.iter().enumerate() {
        assert!(
            (t - 2.0 * k as f64 * dt).abs() <= 1e-12,
            "time {t} of frame {k}"
        );
    }
    let mut fields: HashMap<String, usize> = HashMap::new();
    for (_, file) in &sets {
        let f = read_vtp(&run.join(file));
        assert_eq!((f.points.len() / 3, f.triangles.len()), (nv, nt), "{file}");
        for a in f.point_data.iter().chain(&f.cell_data) {
            *fields.entry(a.name.clone()).or_default() += 1;
            assert!(a.values.iter().all(|v| v.is_finite()), "{file}: {}", a.name);
        }
    }
    for name in [
        "velocity",
        "speed",
        "pressure_force",
        "thickness",
        "stretch",
    ] {
        assert_eq!(fields.get(name), Some(&3), "field {name}");
    }
    // The final surface, decoded here, encloses the gas volume the summary reports.
    let last = read_vtp(&run.join("final.vtp"));
    let v = enclosed_volume(&last.points, &last.triangles);
    let reported = summary["final_gas_volume"].as_f64().unwrap();
    assert!((v / reported - 1.0).abs() < 1e-12, "{v} vs {reported}");
    assert!(reported > summary["initial_gas_volume"].as_f64().unwrap());
}

/// A legacy ASCII VTK unstructured grid: points, tetrahedra and the named cell scalars.
struct TetGrid {
    points: Vec<[f64; 3]>,
    tets: Vec<[usize; 4]>,
    cell_scalars: HashMap<String, Vec<f64>>,
}

fn read_legacy_vtk(path: &Path) -> TetGrid {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.starts_with("# vtk DataFile"), "{}", path.display());
    let mut tokens = text.split_whitespace();
    let mut grid = TetGrid {
        points: Vec::new(),
        tets: Vec::new(),
        cell_scalars: HashMap::new(),
    };
    let mut in_cells = false;
    while let Some(word) = tokens.next() {
        let mut next = || -> &str { tokens.next().expect("the file ended early") };
        match word {
            "POINTS" => {
                let n: usize = next().parse().unwrap();
                assert_eq!(next(), "double");
                for _ in 0..n {
                    let mut p = [0.0; 3];
                    for c in &mut p {
                        *c = next().parse().unwrap();
                    }
                    grid.points.push(p);
                }
            }
            "CELLS" => {
                let n: usize = next().parse().unwrap();
                let _size = next();
                for _ in 0..n {
                    assert_eq!(next(), "4", "tetrahedra only");
                    let mut t = [0; 4];
                    for i in &mut t {
                        *i = next().parse().unwrap();
                    }
                    grid.tets.push(t);
                }
            }
            "CELL_TYPES" => {
                let n: usize = next().parse().unwrap();
                for _ in 0..n {
                    assert_eq!(next(), "10", "VTK_TETRA");
                }
            }
            "CELL_DATA" | "POINT_DATA" => {
                in_cells = word == "CELL_DATA";
                let _count = next();
            }
            "SCALARS" => {
                let name = next().to_string();
                let _type = next();
                let _components = next();
                assert_eq!(next(), "LOOKUP_TABLE");
                let _table = next();
                let n = if in_cells {
                    grid.tets.len()
                } else {
                    grid.points.len()
                };
                let values = (0..n).map(|_| next().parse().unwrap()).collect();
                if in_cells {
                    grid.cell_scalars.insert(name, values);
                }
            }
            _ => {}
        }
    }
    grid
}

fn tet_volume(p: &[[f64; 3]], t: &[usize; 4]) -> f64 {
    let d = |i: usize| {
        [
            p[t[i]][0] - p[t[0]][0],
            p[t[i]][1] - p[t[0]][1],
            p[t[i]][2] - p[t[0]][2],
        ]
    };
    let (a, b, c) = (d(1), d(2), d(3));
    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]))
        / 6.0
}

#[test]
fn lattice_files_read_back_and_every_cell_keeps_its_volume() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let out = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "16",
        "--voxels-per-cell",
        "2",
        // The sphere reaches the body at about step 193 of the default scene (measured).
        "--steps",
        "200",
        "--frame-every",
        "100",
        "--lattice-frames",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = last_json_line(&out);
    let rest = read_legacy_vtk(&run.join("lattice.vtk"));
    assert_eq!(
        rest.tets.len() as u64,
        summary["tetrahedra"].as_u64().unwrap()
    );
    assert_eq!(
        rest.points.len() as u64,
        summary["particles"].as_u64().unwrap()
    );
    let cell_of = &rest.cell_scalars["cell"];
    let cells = summary["cells"].as_u64().unwrap() as usize;
    let cell_volumes = |g: &TetGrid| -> Vec<f64> {
        let mut v = vec![0.0; cells];
        for (t, tet) in g.tets.iter().enumerate() {
            v[cell_of[t] as usize] += tet_volume(&g.points, tet);
        }
        v
    };
    let v0 = cell_volumes(&rest);
    assert!(v0.iter().all(|&v| v > 0.0));
    let mut strained = 0.0f64;
    for step in [100, 200] {
        let g = read_legacy_vtk(&run.join(format!("lattice_{step:05}.vtk")));
        assert_eq!(g.tets, rest.tets, "the lattice keeps its connectivity");
        let v = cell_volumes(&g);
        let worst = v
            .iter()
            .zip(&v0)
            .map(|(a, b)| (a / b - 1.0).abs())
            .fold(0.0, f64::max);
        // The solver's tolerance is 1e-10 per cell; the files print shortest round-trip floats.
        assert!(worst <= 1e-9, "step {step}: cell volume error {worst:e}");
        // The largest relative change of a tetrahedron edge: the cells' shear under load.
        for tet in &g.tets {
            for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let len = |p: &[[f64; 3]]| {
                    let (a, b) = (p[tet[i]], p[tet[j]]);
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                };
                strained = strained.max((len(&g.points) / len(&rest.points) - 1.0).abs());
            }
        }
    }
    // The sphere hit the body (about step 193), so the volumes were kept under load: cells
    // sheared by percents (measured 4.0 % at step 200; at most 0.8 % at steps 40-160, resting
    // on the floor before the impact).
    assert!(
        strained > 0.02,
        "the cells barely deformed (edge strain {strained})"
    );
}

/// Vertex centroid and mean distance from it: the centre and radius of a sphere triangulated
/// with its vertices on it, measured on the file's points.
fn centre_and_radius(points: &[f64]) -> ([f64; 3], f64) {
    let n = (points.len() / 3) as f64;
    let c: [f64; 3] = std::array::from_fn(|k| points.iter().skip(k).step_by(3).sum::<f64>() / n);
    let r = points
        .chunks_exact(3)
        .map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    (c, r)
}

#[test]
fn the_drop_sphere_sphere_and_floor_are_written_where_the_simulation_has_them() {
    let dir = tempfile::tempdir().unwrap();
    let run = |format: &str| {
        let out = dir.path().join(format);
        let argv = [
            "builtin:icosphere",
            "--resolution",
            "12",
            "--voxels-per-cell",
            "2",
            "--steps",
            "200",
            "--frame-every",
            "100",
            "--format",
            format,
            "--pov",
            "--out",
            out.to_str().unwrap(),
        ];
        let args = super::volumetric_args(&argv);
        let start = balloon_cli::cmd_volumetric::build(&args, None).unwrap().sim;
        let end = balloon_cli::cmd_volumetric::execute(&args, None, true)
            .unwrap()
            .sim;
        (out, start, end)
    };
    let close = |a: [f64; 3], b: [f64; 3], tol: f64| (0..3).all(|k| (a[k] - b[k]).abs() <= tol);
    let (obj, start, end) = run("obj");
    let floor = end.planes()[0];
    for (step, sim) in [(0, &start), (200, &end)] {
        let s = sim.sphere().unwrap();
        let (c, r) = centre_and_radius(&obj_points(&obj.join(format!("sphere_{step:05}.obj"))));
        assert!(
            close(c, s.position.into(), 1e-12) && (r - s.radius).abs() <= 1e-12 * s.radius,
            "step {step}: file ({c:?}, {r}) vs simulation ({:?}, {})",
            s.position,
            s.radius
        );
    }
    // The sphere fell onto the body: the two frames differ by far more than the tolerance.
    let moved = start.sphere().unwrap().position - end.sphere().unwrap().position;
    assert!(moved.norm() > 0.1 * end.sphere().unwrap().radius, "{moved}");
    // The floor: one quad in the floor plane, reaching beyond the body on every side.
    let f = obj_points(&obj.join("floor.obj"));
    assert_eq!(f.len(), 12);
    assert!(f.chunks(3).all(|p| (p[2] - floor.point.z).abs() < 1e-12));
    let body = obj_points(&obj.join("frame_00200.obj"));
    for k in 0..2 {
        let (lo, hi) = body
            .iter()
            .skip(k)
            .step_by(3)
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let flo = f
            .iter()
            .skip(k)
            .step_by(3)
            .copied()
            .fold(f64::MAX, f64::min);
        let fhi = f
            .iter()
            .skip(k)
            .step_by(3)
            .copied()
            .fold(f64::MIN, f64::max);
        assert!(
            flo < lo && fhi > hi,
            "axis {k}: floor {flo}..{fhi}, body {lo}..{hi}"
        );
    }
    // POV-Ray: `sphere { <x, z, y>, r` (z up is POV's y) and `plane { <0, 1, 0>, height`.
    let pov = std::fs::read_to_string(obj.join("final.pov")).unwrap();
    let line = pov.lines().find(|l| l.starts_with("sphere {")).unwrap();
    let nums: Vec<f64> = line["sphere {".len()..]
        .split(['<', '>', ','])
        .filter_map(|t| t.split_whitespace().next()?.parse().ok())
        .collect();
    let s = end.sphere().unwrap();
    assert!(
        close([nums[0], nums[2], nums[1]], s.position.into(), 1e-12)
            && (nums[3] - s.radius).abs() <= 1e-12,
        "{line}"
    );
    let plane = pov.lines().find(|l| l.starts_with("plane {")).unwrap();
    let height: f64 = plane
        .strip_prefix("plane { <0, 1, 0>, ")
        .and_then(|r| r.split_whitespace().next())
        .and_then(|h| h.parse().ok())
        .unwrap_or_else(|| panic!("{plane}"));
    assert!((height - floor.point.z).abs() < 1e-12, "{plane}");

    // VTK: sphere and floor files as parts 1 and 2 of every time step of series.pvd.
    let (vtk, _, end) = run("vtk");
    let pvd = std::fs::read_to_string(vtk.join("series.pvd")).unwrap();
    let doc = roxmltree::Document::parse(&pvd).unwrap();
    let sets: Vec<(String, String)> = doc
        .descendants()
        .filter(|n| n.has_tag_name("DataSet"))
        .map(|n| {
            (
                n.attribute("part").unwrap().to_string(),
                n.attribute("file").unwrap().to_string(),
            )
        })
        .collect();
    let expect: Vec<(String, String)> = [0, 100, 200]
        .iter()
        .flat_map(|s| {
            [
                ("0".to_string(), format!("frame_{s:05}.vtp")),
                ("1".to_string(), format!("sphere_{s:05}.vtp")),
                ("2".to_string(), "floor.vtp".to_string()),
            ]
        })
        .collect();
    assert_eq!(sets, expect);
    let sphere = read_vtp(&vtk.join("sphere_00200.vtp"));
    let (c, r) = centre_and_radius(&sphere.points);
    let s = end.sphere().unwrap();
    assert!(close(c, s.position.into(), 1e-12) && (r - s.radius).abs() <= 1e-12 * s.radius);
    // A closed outward surface: it encloses the sphere's volume (up to the icosphere's facets).
    let v = enclosed_volume(&sphere.points, &sphere.triangles);
    let ball = 4.0 / 3.0 * std::f64::consts::PI * s.radius.powi(3);
    assert!(v > 0.97 * ball && v < ball, "{v} vs {ball}");
    assert_eq!(read_vtp(&vtk.join("floor.vtp")).triangles.len(), 2);
}

/// `stats.jsonl` of the drop-sphere scene carries the sphere after every step: its centre
/// matches the sphere files and the final simulation, its centre moves by its velocity times
/// the step, and its velocity changes by gravity plus the contact impulse the line reports
/// (the sphere touches only the body here, not the floor), which is non-zero exactly on the
/// lines that say `contact`.
#[test]
fn stats_lines_carry_the_sphere_consistent_with_its_files_and_motion() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let argv = [
        "builtin:icosphere",
        "--resolution",
        "12",
        "--voxels-per-cell",
        "2",
        "--steps",
        "300",
        "--frame-every",
        "100",
        "--out",
        out.to_str().unwrap(),
    ];
    let args = super::volumetric_args(&argv);
    let end = balloon_cli::cmd_volumetric::execute(&args, None, true)
        .unwrap()
        .sim;
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(out.join("stats.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 300);
    let vec3 = |v: &serde_json::Value| -> [f64; 3] {
        std::array::from_fn(|k| v[k].as_f64().unwrap_or_else(|| panic!("{v}")))
    };
    let sphere = end.sphere().unwrap();
    let g = end.body().params.gravity;
    let close = |a: [f64; 3], b: [f64; 3], tol: f64| (0..3).all(|k| (a[k] - b[k]).abs() <= tol);
    for step in [100, 200, 300] {
        let s = &lines[step - 1]["sphere"];
        let (c, _) = centre_and_radius(&obj_points(&out.join(format!("sphere_{step:05}.obj"))));
        assert!(close(c, vec3(&s["centre"]), 1e-12), "step {step}: {s}");
    }
    let last = &lines[299]["sphere"];
    // serde_json's default float parsing may be off by an ulp.
    let (centre, velocity) = (vec3(&last["centre"]), vec3(&last["velocity"]));
    assert!(close(centre, sphere.position.into(), 1e-15), "{last}");
    assert!(close(velocity, sphere.velocity.into(), 1e-14), "{last}");
    let (mut touched, mut impulse_up) = (0, 0.0);
    for pair in lines.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let h = b["time"].as_f64().unwrap() - a["time"].as_f64().unwrap();
        let (sa, sb) = (&a["sphere"], &b["sphere"]);
        let (ca, cb, vb) = (
            vec3(&sa["centre"]),
            vec3(&sb["centre"]),
            vec3(&sb["velocity"]),
        );
        let va = vec3(&sa["velocity"]);
        let j = vec3(&sb["contact_impulse"]);
        let scale = sphere.radius;
        // One position update `x += V h` per step (several with step halvings).
        assert!(
            b["halvings"] != 0
                || (0..3).all(|k| (cb[k] - ca[k] - vb[k] * h).abs() <= 1e-12 * scale),
            "step {}: the centre moved {:?}, velocity * dt {:?}",
            b["step"],
            [cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]],
            [vb[0] * h, vb[1] * h, vb[2] * h]
        );
        // M (V_b - V_a) = M g h + J.
        let m = sphere.mass;
        let residual: f64 = (0..3)
            .map(|k| (m * (vb[k] - va[k]) - m * g[k] * h - j[k]).abs())
            .fold(0.0, f64::max);
        assert!(
            residual <= 1e-12 * m * (1.0 + va[2].abs()),
            "step {}: momentum residual {residual:e} ({sb})",
            b["step"]
        );
        let contact = sb["contact"].as_bool().unwrap();
        assert_eq!(contact, sb["contacts"].as_u64().unwrap() > 0, "{sb}");
        assert_eq!(contact, j != [0.0; 3], "{sb}");
        if contact {
            touched += 1;
            impulse_up += j[2];
        }
    }
    // The sphere landed on the body, which pushed it up.
    assert!(
        touched > 0,
        "the sphere never touched the body in 300 steps"
    );
    assert!(
        impulse_up > 0.0,
        "net contact impulse {impulse_up} N s is not upward"
    );
    // The free scene has no sphere and writes none.
    let free = dir.path().join("free");
    let out = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "12",
        "--steps",
        "3",
        "--scene",
        "free",
        "--out",
        free.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stats = std::fs::read_to_string(free.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 3);
    assert!(!stats.contains("sphere"), "{stats}");
}
