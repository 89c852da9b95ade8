//! Anchors (`--pin`), thickness maps (`--thickness-file`, `--thickness-rule`, a PLY property)
//! and loads (`--load`) of `balloon inflate`, and the example scenario with a pinned neck.

use super::{last_json_line, run_balloon};
use balloon_mesh::TriMesh;
use std::path::{Path, PathBuf};

/// A 0.1 m icosphere (162 vertices, 320 faces).
fn sphere() -> TriMesh {
    balloon_mesh::generate::icosphere(0.1, 2).unwrap()
}

fn write_sphere(dir: &Path) -> PathBuf {
    let path = dir.join("sphere.obj");
    balloon_mesh::io::write_obj(&path, &sphere()).unwrap();
    path
}

fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn run_ok(args: &[&str]) -> serde_json::Value {
    let mut all = args.to_vec();
    all.push("--json");
    let out = run_balloon(&all);
    ok(&out);
    last_json_line(&out)
}

fn final_mesh(dir: &Path) -> TriMesh {
    balloon_mesh::io::read_obj(&dir.join("final.obj")).unwrap()
}

/// The neck of the example: the vertices below z = -0.085 m (the bottom cap of the sphere).
fn neck_vertices(mesh: &TriMesh) -> Vec<usize> {
    (0..mesh.num_vertices())
        .filter(|&v| mesh.vertices[v].z < -0.085)
        .collect()
}

#[test]
fn a_hard_pinned_neck_stays_exactly_where_it_is_while_the_rest_inflates() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = write_sphere(dir.path());
    let input = balloon_mesh::io::read_obj(&mesh_path).unwrap();
    let out = dir.path().join("out");
    let s = run_ok(&[
        "inflate",
        mesh_path.to_str().unwrap(),
        "--gas",
        "constant",
        "--pressure",
        "3000",
        "--steps",
        "10",
        "--pin",
        "below:z:-0.085",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        s["final_gas_volume"].as_f64().unwrap() > 1.05 * s["initial_gas_volume"].as_f64().unwrap()
    );
    let end = final_mesh(&out);
    let neck = neck_vertices(&input);
    assert!(neck.len() >= 3, "{neck:?}");
    for &v in &neck {
        assert_eq!(
            end.vertices[v], input.vertices[v],
            "pinned vertex {v} moved"
        );
    }
    let top = (0..input.num_vertices())
        .max_by(|&a, &b| input.vertices[a].z.total_cmp(&input.vertices[b].z))
        .unwrap();
    assert!(end.vertices[top].z > input.vertices[top].z + 1e-3);
    // The recorded scenario repeats the pins.
    let rec = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
    assert!(
        rec.contains("[[anchors]]\nspec = \"below:z:-0.085\""),
        "{rec}"
    );
}

#[test]
fn a_ply_vertex_group_pins_the_neck_from_the_command_line_and_a_scenario() {
    // The mesh as a PLY whose vertex property `neck` marks the bottom cap: `--pin
    // ply:FILE:neck` (and `vertex_group` in a scenario) holds exactly those vertices.
    let dir = tempfile::tempdir().unwrap();
    let input = sphere();
    let neck = neck_vertices(&input);
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nproperty uchar neck\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        input.num_vertices(),
        input.num_triangles()
    );
    for (v, p) in input.vertices.iter().enumerate() {
        let mark = u8::from(neck.contains(&v));
        ply.push_str(&format!("{:?} {:?} {:?} {mark}\n", p.x, p.y, p.z));
    }
    for t in &input.triangles {
        ply.push_str(&format!("3 {} {} {}\n", t[0], t[1], t[2]));
    }
    let path = dir.path().join("balloon.ply");
    std::fs::write(&path, ply).unwrap();
    let spec = format!("ply:{}:neck", path.display());
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "[mesh]\npath = \"balloon.ply\"\n[gas]\nmodel = \"constant\"\npressure = 3000\n\
         [run]\nsteps = 8\n[[anchors]]\nvertex_group = { file = \"balloon.ply\", property = \"neck\" }\n",
    )
    .unwrap();
    for (k, args) in [
        vec![
            "inflate",
            path.to_str().unwrap(),
            "--gas",
            "constant",
            "--pressure",
            "3000",
            "--steps",
            "8",
            "--pin",
            spec.as_str(),
        ],
        vec!["run", scenario.to_str().unwrap()],
    ]
    .into_iter()
    .enumerate()
    {
        let out = dir.path().join(format!("out{k}"));
        let mut args = args;
        args.extend(["--out", out.to_str().unwrap()]);
        let s = run_ok(&args);
        assert!(
            s["final_gas_volume"].as_f64().unwrap()
                > 1.05 * s["initial_gas_volume"].as_f64().unwrap()
        );
        let end = final_mesh(&out);
        for v in 0..input.num_vertices() {
            let still = end.vertices[v] == input.vertices[v];
            assert_eq!(
                still,
                neck.contains(&v),
                "run {k}: vertex {v} pinned {}",
                !still
            );
        }
        let rec = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
        assert!(
            rec.contains(&format!("ply:{}:neck", path.display())),
            "{rec}"
        );
    }
}

#[test]
fn spring_anchors_under_a_force_move_by_f_over_k() {
    // Every vertex on a spring of k = 10 N/m to its rest position and pushed by F = 0.01 N:
    // the whole (unpressurised) shell shifts rigidly by F / k = 1 mm.
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = write_sphere(dir.path());
    let input = balloon_mesh::io::read_obj(&mesh_path).unwrap();
    let out = dir.path().join("out");
    run_ok(&[
        "inflate",
        mesh_path.to_str().unwrap(),
        "--gas",
        "constant",
        "--pressure",
        "0",
        "--steps",
        "60",
        "--pin",
        "box:-1,-1,-1,1,1,1",
        "--pin-stiffness",
        "10",
        "--load",
        "force=0,0,0.01;on=box:-1,-1,-1,1,1,1",
        "--out",
        out.to_str().unwrap(),
    ]);
    let end = final_mesh(&out);
    let n = input.num_vertices() as f64;
    let dz: f64 = (0..input.num_vertices())
        .map(|v| end.vertices[v].z - input.vertices[v].z)
        .sum::<f64>()
        / n;
    assert!((dz - 1e-3).abs() < 2e-5, "mean shift {dz} m, F/k = 1e-3 m");
}

/// Per-vertex thickness: `thin` below z = 0, `thick` above.
fn halves(mesh: &TriMesh, thin: f64, thick: f64) -> String {
    let mut s = String::from("# rest thickness per vertex (m): the upper half twice as thick\n");
    for p in &mesh.vertices {
        s.push_str(&format!("{:e}\n", if p.z > 0.0 { thick } else { thin }));
    }
    s
}

/// Mean distance from the origin of the vertices above (`upper`) or below the equator band.
fn mean_radius(mesh: &TriMesh, upper: bool) -> f64 {
    let r: Vec<f64> = mesh
        .vertices
        .iter()
        .filter(|p| if upper { p.z > 0.05 } else { p.z < -0.05 })
        .map(|p| p.coords.norm())
        .collect();
    r.iter().sum::<f64>() / r.len() as f64
}

#[test]
fn a_balloon_with_one_half_twice_as_thick_inflates_asymmetrically() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = write_sphere(dir.path());
    let wall = dir.path().join("wall.txt");
    std::fs::write(&wall, halves(&sphere(), 3e-4, 6e-4)).unwrap();
    let out = dir.path().join("out");
    let common = [
        "--gas",
        "constant",
        "--pressure",
        "1500",
        "--steps",
        "30",
        "--format",
        "vtk",
    ];
    let mut args = vec![
        "inflate",
        mesh_path.to_str().unwrap(),
        "--thickness-file",
        wall.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(common);
    let s = run_ok(&args);
    let (tmin, tmax) = (
        s["final_thickness_min"].as_f64().unwrap(),
        s["final_thickness_max"].as_f64().unwrap(),
    );
    assert!(tmax > 1.6 * tmin, "{tmin} .. {tmax}");
    // The thickness field is in the VTK frames.
    let vtp = std::fs::read_to_string(out.join("final.vtp")).unwrap();
    assert!(vtp.contains("Name=\"thickness\""), "no thickness field");
    // Again with an OBJ final frame to measure: the thin lower half bulges further.
    let obj = dir.path().join("obj");
    let mut args = vec![
        "inflate",
        mesh_path.to_str().unwrap(),
        "--thickness-file",
        wall.to_str().unwrap(),
        "--out",
        obj.to_str().unwrap(),
    ];
    args.extend(&common[..6]);
    run_ok(&args);
    let end = final_mesh(&obj);
    let (upper, lower) = (mean_radius(&end, true), mean_radius(&end, false));
    assert!(
        lower > upper * 1.01,
        "thin half radius {lower} m, thick half {upper} m"
    );
    // The same wall as a linear rule thickens toward +z as well.
    let rule = dir.path().join("rule");
    run_ok(&[
        "inflate",
        mesh_path.to_str().unwrap(),
        "--thickness-rule",
        "z:3e-4:6e-4",
        "--out",
        rule.to_str().unwrap(),
        "--gas",
        "constant",
        "--pressure",
        "1500",
        "--steps",
        "30",
    ]);
    let end = final_mesh(&rule);
    assert!(mean_radius(&end, false) > mean_radius(&end, true) * 1.005);
}

#[test]
fn a_ply_thickness_property_is_the_rest_thickness_and_bad_maps_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nproperty double thickness\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.num_vertices(),
        mesh.num_triangles()
    );
    for p in &mesh.vertices {
        ply.push_str(&format!("{} {} {} 4e-4\n", p.x, p.y, p.z));
    }
    for t in &mesh.triangles {
        ply.push_str(&format!("3 {} {} {}\n", t[0], t[1], t[2]));
    }
    let path = dir.path().join("thick.ply");
    std::fs::write(&path, ply).unwrap();
    let s = run_ok(&["inflate", path.to_str().unwrap(), "--steps", "1"]);
    let t = s["final_thickness_mean"].as_f64().unwrap();
    assert!((t - 4e-4).abs() < 2e-5, "{t} (the default is 3e-4)");

    let obj = write_sphere(dir.path());
    let wall = dir.path().join("wall.txt");
    for (text, what) in [
        ("3e-4\n".repeat(7), "7 values".to_owned()),
        ("3e-4\n# c\nthick\n".to_owned(), "wall.txt:3:".to_owned()),
        ("3e-4\n0\n".to_owned(), "wall.txt:2:".to_owned()),
    ] {
        std::fs::write(&wall, text).unwrap();
        let out = run_balloon(&[
            "inflate",
            obj.to_str().unwrap(),
            "--thickness-file",
            wall.to_str().unwrap(),
            "--steps",
            "1",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(&what), "{err}");
    }
    for (pin, what) in [
        ("below:z:-5", "selects no vertex"),
        ("indices:1,9999", "vertex 9999"),
        ("sideways:1", "not a selector"),
    ] {
        let out = run_balloon(&["inflate", obj.to_str().unwrap(), "--pin", pin]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(what), "{pin}: {err}");
    }
}

#[test]
fn gravity_and_a_scheduled_grab_move_the_shell() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = write_sphere(dir.path());
    let input = balloon_mesh::io::read_obj(&mesh_path).unwrap();
    let bottom = neck_vertices(&input);
    // Hung from its top (pinned), unpressurised: gravity pulls the bottom down, and so does a
    // grab toward a point below it active for the first 0.1 s (without a load nothing moves).
    let shift = |load: &str, name: &str| {
        let out = dir.path().join(name);
        run_ok(&[
            "inflate",
            mesh_path.to_str().unwrap(),
            "--gas",
            "constant",
            "--pressure",
            "0",
            "--steps",
            "10",
            "--pin",
            "above:z:0.085",
            "--load",
            load,
            "--out",
            out.to_str().unwrap(),
        ]);
        let end = final_mesh(&out);
        let dz: f64 = bottom
            .iter()
            .map(|&v| end.vertices[v].z - input.vertices[v].z)
            .sum();
        (dz / bottom.len() as f64, out)
    };
    let (fall, _) = shift("gravity=0,0,-9.81", "gravity");
    assert!(fall < -1e-5, "gravity moved the bottom by {fall} m");
    let (pull, out) = shift(
        "grab=0,0,-0.3;on=below:z:-0.085;stiffness=0.1;end=0.1",
        "grab",
    );
    assert!(pull < -1e-5, "the grab moved the bottom by {pull} m");
    let rec = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
    assert!(
        rec.contains(
            "[[loads]]\nspec = \"grab=0.0,0.0,-0.3;stiffness=0.1;on=below:z:-0.085;end=0.1\""
        ),
        "{rec}"
    );
}

/// The example's folder.
fn example_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/pinned-neck")
}

/// The example's data files, generated: the sphere, its neck and its wall.
fn example_files() -> Vec<(&'static str, String)> {
    let mesh = sphere();
    let mut obj = String::new();
    for p in &mesh.vertices {
        obj.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    for t in &mesh.triangles {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    let mut neck = String::from("# the neck: vertex indices (0-based) below z = -0.085 m\n");
    for v in neck_vertices(&mesh) {
        neck.push_str(&format!("{v}\n"));
    }
    vec![
        ("sphere.obj", obj),
        ("neck.txt", neck),
        ("wall.txt", halves(&mesh, 3e-4, 6e-4)),
    ]
}

#[test]
fn the_pinned_neck_example_runs_as_written() {
    let dir = example_dir();
    // The data files are generated; BALLOON_REGENERATE_EXAMPLES=1 rewrites them.
    for (name, text) in example_files() {
        let path = dir.join(name);
        if std::env::var_os("BALLOON_REGENERATE_EXAMPLES").is_some() {
            std::fs::write(&path, &text).unwrap();
        }
        let on_disk = std::fs::read_to_string(&path).unwrap();
        assert!(
            on_disk == text,
            "{} differs from its generator",
            path.display()
        );
    }
    let scenario = dir.join("pinned-neck.toml");
    let out = tempfile::tempdir().unwrap();
    let s = run_ok(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
    ]);
    assert_eq!(s["vertices"], 162);
    let input = sphere();
    let end = final_mesh(out.path());
    for &v in &neck_vertices(&input) {
        let (a, b) = (end.vertices[v], input.vertices[v]);
        assert!(
            (a - b).norm() < 1e-12,
            "neck vertex {v} moved from {b} to {a}"
        );
    }
    assert!(
        s["final_gas_volume"].as_f64().unwrap() > 1.05 * s["initial_gas_volume"].as_f64().unwrap()
    );
}

#[test]
fn the_two_layer_body_takes_hard_pins_from_flags_and_scenario_files() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "[system]\nkind = \"two-layer\"\n[body]\ndim = 3\n[run]\nsteps = 20\n\
         [[anchors]]\nabove = { axis = \"z\", value = 0.0 }\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    run_ok(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let rec = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
    assert!(rec.contains("[[anchors]]\nspec = \"above:z:0.0\""), "{rec}");
    // Spring anchors (`@K`) are taken too (crate::loads tests what they do).
    let springs = run_balloon(&[
        "two-layer",
        "--dim",
        "3",
        "--level",
        "1",
        "--steps",
        "5",
        "--pin",
        "above:z:0@10",
    ]);
    assert!(
        springs.status.success(),
        "{}",
        String::from_utf8_lossy(&springs.stderr)
    );
}

#[test]
fn a_run_with_anchors_loads_and_a_thickness_map_repeats_byte_identically_from_its_record() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let scenario = example_dir().join("pinned-neck.toml");
    // A `file:` path on the command line is relative to the working directory.
    let pin = format!("file:{}@300", example_dir().join("neck.txt").display());
    run_ok(&[
        "run",
        scenario.to_str().unwrap(),
        "--steps",
        "8",
        "--pin",
        &pin,
        "--load",
        "force=0,0.01,0;on=above:z:0.09;start=0.02;end=0.06",
        "--out",
        a.to_str().unwrap(),
    ]);
    let rec = std::fs::read_to_string(a.join("scenario.toml")).unwrap();
    assert!(rec.contains("thickness_file = \""), "{rec}");
    run_ok(&[
        "run",
        a.join("scenario.toml").to_str().unwrap(),
        "--out",
        b.to_str().unwrap(),
    ]);
    let (fa, fb) = (
        std::fs::read(a.join("final.obj")).unwrap(),
        std::fs::read(b.join("final.obj")).unwrap(),
    );
    assert!(fa == fb, "the repeated run differs");
}

#[test]
fn a_static_solve_keeps_a_hard_pinned_neck_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = write_sphere(dir.path());
    let input = balloon_mesh::io::read_obj(&mesh_path).unwrap();
    let out = dir.path().join("out");
    run_ok(&[
        "inflate",
        mesh_path.to_str().unwrap(),
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "2000",
        "--pin",
        "below:z:-0.085",
        "--out",
        out.to_str().unwrap(),
    ]);
    let end = final_mesh(&out);
    for &v in &neck_vertices(&input) {
        assert_eq!(
            end.vertices[v], input.vertices[v],
            "pinned vertex {v} moved"
        );
    }
}
