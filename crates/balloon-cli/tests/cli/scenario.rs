//! `balloon run SCENARIO.toml`: the example runs as written, flags override the file, errors
//! name the file, line and key, and a run repeats itself from its recorded `scenario.toml`.

use super::{last_json_line, obj_points, run_balloon};
use std::path::{Path, PathBuf};

/// A small closed sphere (162 vertices) written as OBJ into `dir`.
fn small_sphere(dir: &Path) -> PathBuf {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let path = dir.join("sphere.obj");
    balloon_mesh::io::write_obj(&path, &mesh).unwrap();
    path
}

fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_example_shell_scenario_runs_as_written() {
    let example = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/shell.toml");
    let out = run_balloon(&["run", example.to_str().unwrap(), "--json"]);
    ok(&out);
    let s = last_json_line(&out);
    assert_eq!(s["steps"], 20);
    assert_eq!(s["material"], "st-venant-kirchhoff");
    assert_eq!(s["final_gauge_pressure"], 1500.0);
    assert!(
        s["final_gas_volume"].as_f64().unwrap() > s["initial_gas_volume"].as_f64().unwrap(),
        "1500 Pa inflates the sphere: {s}"
    );
}

/// The example scenario `examples/NAME/scenario.toml` run as written, with `extra` flags after
/// it (fewer steps for the test); returns the summary and the output folder.
fn run_example(name: &str, extra: &[&str]) -> (serde_json::Value, tempfile::TempDir) {
    let example = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
        .join("scenario.toml");
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("run");
    let mut args = vec!["run", example.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", out_dir.to_str().unwrap(), "--json"]);
    let out = run_balloon(&args);
    ok(&out);
    (last_json_line(&out), dir)
}

/// Lowest and highest `z` of the points.
fn z_range(points: &[f64]) -> (f64, f64) {
    points
        .chunks_exact(3)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        })
}

#[test]
fn the_example_volumetric_and_two_layer_scenarios_run_as_written() {
    // The hanging teddy: its head is pinned, so the top of its surface stays where it was
    // while the rest sags under gravity; the cells keep their volumes.
    let (s, dir) = run_example("hanging-teddy", &["--steps", "400", "--frame-every", "400"]);
    assert_eq!(s["steps"], 400, "{s}");
    assert!(s["max_cell_volume_error"].as_f64().unwrap() < 1e-9, "{s}");
    let run = dir.path().join("run");
    let (lo0, hi0) = z_range(&obj_points(&run.join("frame_00000.obj")));
    let (lo1, hi1) = z_range(&obj_points(&run.join("frame_00400.obj")));
    assert!(
        (hi1 - hi0).abs() < 2e-3,
        "the pinned head moved: {hi0} -> {hi1}"
    );
    assert!(lo1 < lo0 - 1e-4, "the feet sag: {lo0} -> {lo1}");
    // The tethered two-layer ball hangs from springs at its top: it drops onto them.
    let (s, dir) = run_example(
        "tethered-two-layer",
        &["--steps", "400", "--frame-every", "400"],
    );
    assert_eq!(s["steps"], 400, "{s}");
    assert_eq!(s["escaped_particles"], 0, "{s}");
    let run = dir.path().join("run");
    let (lo0, hi0) = z_range(&obj_points(&run.join("frame_00000.obj")));
    let (lo1, hi1) = z_range(&obj_points(&run.join("frame_00400.obj")));
    assert!(lo1 < lo0 - 0.05, "the ball drops: {lo0} -> {lo1}");
    assert!(
        hi0 - hi1 < lo0 - lo1,
        "the anchored top moves less than the bottom"
    );
    // As written, without an output folder (nothing in them needs one).
    for name in ["hanging-teddy", "tethered-two-layer"] {
        let file = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples")
            .join(name)
            .join("scenario.toml");
        ok(&run_balloon(&[
            "run",
            file.to_str().unwrap(),
            "--steps",
            "5",
        ]));
    }
}

#[test]
fn a_mesh_path_is_relative_to_the_file_and_flags_override_it() {
    let dir = tempfile::tempdir().unwrap();
    small_sphere(dir.path());
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "[mesh]\npath = \"sphere.obj\"\n[gas]\nmodel = \"ideal\"\npressure = 800\n[run]\nsteps = 4\n",
    )
    .unwrap();
    // Run from another folder: the mesh is found beside the file.
    let out = run_balloon(&["run", scenario.to_str().unwrap(), "--steps", "2", "--json"]);
    ok(&out);
    let s = last_json_line(&out);
    assert_eq!(s["vertices"], 162);
    assert_eq!(s["steps"], 2, "--steps 2 overrides the file's 4");
}

#[test]
fn errors_name_the_file_the_line_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("bad.toml");
    for (text, expected) in [
        (
            "[run]\nsteps = 3\ndtt = 0.1\n",
            "bad.toml:3: `run.dtt`: unknown key",
        ),
        (
            "[gas]\npressure = \"high\"\n",
            "bad.toml:2: `gas.pressure`: expected a number",
        ),
        (
            "[run]\n\nsteps = 3\ncg_tol = 1.5\n",
            "bad.toml:4: `run.cg_tol`: invalid value '1.5'",
        ),
        (
            "[output]\nformat = \"jpeg\"\n",
            "bad.toml:2: `output.format`",
        ),
        ("[mesh]\npath = \"missing.obj\"\n", "missing.obj"),
    ] {
        std::fs::write(&scenario, text).unwrap();
        let out = run_balloon(&["run", scenario.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{text:?} ran");
        assert!(err.contains(expected), "{text:?}: {err}");
    }
    let out = run_balloon(&["run", dir.path().join("none.toml").to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read the scenario"));
}

/// The bytes of `dir/name`.
fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(name).display()))
}

#[test]
fn a_run_repeats_itself_from_its_recorded_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let scenario = dir.path().join("s.toml");
    std::fs::write(
        &scenario,
        "[mesh]\npath = \"sphere.obj\"\n[shell]\nthickness = 4e-4\n[run]\nsteps = 4\ndt = 0.005\n[output]\nframe_every = 2\n",
    )
    .unwrap();
    let (d1, d2) = (dir.path().join("d1"), dir.path().join("d2"));
    ok(&run_balloon(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        d1.to_str().unwrap(),
        "--pressure",
        "900",
    ]));
    let recorded = String::from_utf8(bytes(&d1, "scenario.toml")).unwrap();
    for line in [
        "thickness = 0.0004",
        "dt = 0.005",
        "pressure = 900",
        "steps = 4",
    ] {
        assert!(recorded.contains(line), "`{line}` missing:\n{recorded}");
    }
    let abs = std::path::absolute(&mesh).unwrap();
    assert!(
        recorded.contains(&format!("path = \"{}\"", abs.display())),
        "{recorded}"
    );
    ok(&run_balloon(&[
        "run",
        d1.join("scenario.toml").to_str().unwrap(),
        "--out",
        d2.to_str().unwrap(),
    ]));
    assert_eq!(
        bytes(&d1, "final.obj"),
        bytes(&d2, "final.obj"),
        "final frames differ"
    );
    assert_eq!(
        recorded.as_bytes(),
        bytes(&d2, "scenario.toml"),
        "the record of the repeat differs"
    );

    // `balloon inflate --out` records itself too, and its record repeats it.
    let (d3, d4) = (dir.path().join("d3"), dir.path().join("d4"));
    ok(&run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--steps",
        "3",
        "--gas",
        "ideal",
        "--young",
        "2e6",
        "--out",
        d3.to_str().unwrap(),
    ]));
    ok(&run_balloon(&[
        "run",
        d3.join("scenario.toml").to_str().unwrap(),
        "--out",
        d4.to_str().unwrap(),
    ]));
    assert_eq!(
        bytes(&d3, "final.obj"),
        bytes(&d4, "final.obj"),
        "final frames differ"
    );
    let s: serde_json::Value = serde_json::from_slice(&bytes(&d4, "summary.json")).unwrap();
    assert_eq!(s["steps"], 3);
}

/// Runs `args` with `--out d1`, then `balloon run d1/scenario.toml --out d2`, and checks that the
/// last frames (`last`) and the records are byte-identical.
fn repeats_itself(args: &[&str], kind: &str, last: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (d1, d2) = (dir.path().join("d1"), dir.path().join("d2"));
    let mut first: Vec<&str> = args.to_vec();
    first.extend(["--out", d1.to_str().unwrap()]);
    ok(&run_balloon(&first));
    let recorded = String::from_utf8(bytes(&d1, "scenario.toml")).unwrap();
    assert!(
        recorded.contains(&format!("kind = \"{kind}\"")),
        "{recorded}"
    );
    ok(&run_balloon(&[
        "run",
        d1.join("scenario.toml").to_str().unwrap(),
        "--out",
        d2.to_str().unwrap(),
    ]));
    assert_eq!(
        bytes(&d1, last),
        bytes(&d2, last),
        "{kind}: last frames differ"
    );
    assert_eq!(
        recorded.as_bytes(),
        bytes(&d2, "scenario.toml"),
        "{kind}: records differ"
    );
}

#[test]
fn volumetric_and_two_layer_runs_repeat_themselves_from_their_recorded_scenario() {
    repeats_itself(
        &[
            "volumetric",
            "builtin:icosphere",
            "--resolution",
            "10",
            "--voxels-per-cell",
            "2",
            "--steps",
            "6",
            "--frame-every",
            "3",
        ],
        "volumetric",
        "frame_00006.obj",
    );
    repeats_itself(
        &[
            "two-layer",
            "--level",
            "1",
            "--steps",
            "20",
            "--pressure",
            "3",
        ],
        "two-layer",
        "frame_00020.obj",
    );
}

#[test]
fn a_two_layer_scenario_file_selects_its_system() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("t.toml");
    std::fs::write(
        &scenario,
        "[system]\nkind = \"two-layer\"\n[body]\nlevel = 1\n[run]\nsteps = 7\nintegrator = \"midpoint\"\n",
    )
    .unwrap();
    let out = run_balloon(&["run", scenario.to_str().unwrap(), "--json"]);
    ok(&out);
    assert_eq!(last_json_line(&out)["steps"], 7);
    std::fs::write(
        &scenario,
        "[system]\nkind = \"two-layer\"\n[shell]\nthickness = 1e-3\n",
    )
    .unwrap();
    let out = run_balloon(&["run", scenario.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("t.toml:3: `shell`: unknown table"), "{err}");
}

#[test]
fn volumetric_anchors_and_loads_are_scenario_tables_and_repeat_themselves() {
    repeats_itself(
        &[
            "volumetric",
            "builtin:icosphere",
            "--resolution",
            "10",
            "--voxels-per-cell",
            "2",
            "--scene",
            "free",
            "--steps",
            "8",
            "--frame-every",
            "4",
            "--pin",
            "below:z:-0.06",
            "--pin",
            "above:z:0.06@2000",
            "--load",
            "force=0.1,0,0;on=above:x:0.03;per=total;end=0.002",
            "--load",
            "gravity=0,0,-3;start=0.001",
        ],
        "volumetric",
        "frame_00008.obj",
    );
    // The same from a hand-written scenario: `[[anchors]]` and `[[loads]]` tables.
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("v.toml");
    std::fs::write(
        &scenario,
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"builtin:icosphere\"\n\
         [lattice]\nresolution = 10\nvoxels_per_cell = 2\n[run]\nscene = \"free\"\nsteps = 3\n\
         [[anchors]]\nbelow = { axis = \"z\", value = -0.06 }\n\
         [[loads]]\nforce = [0.0, 0.0, 1.0]\nabove = { axis = \"z\", value = 0.06 }\n\
         [[loads]]\ngrab = [0.0, 0.0, 2.0]\nindices = [0]\nstiffness = 10.0\n",
    )
    .unwrap();
    let out_dir = dir.path().join("o");
    let out = run_balloon(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    ok(&out);
    let recorded = std::fs::read_to_string(out_dir.join("scenario.toml")).unwrap();
    for want in [
        "below:z:-0.06",
        "force=0.0,0.0,1.0;per=vertex;on=above:z:0.06",
        "grab=0.0,0.0,2.0;stiffness=10.0;on=indices:0",
    ] {
        assert!(recorded.contains(want), "{want} missing in\n{recorded}");
    }
    // An anchor that selects nothing names its selector and the file's table.
    std::fs::write(
        &scenario,
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"builtin:icosphere\"\n\
         [lattice]\nresolution = 10\nvoxels_per_cell = 2\n[[anchors]]\nbelow = { axis = \"z\", value = -9.0 }\n",
    )
    .unwrap();
    let out = run_balloon(&["run", scenario.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("`below:z:-9.0` selects no particle"), "{err}");
}

#[test]
fn two_layer_spring_anchors_and_loads_repeat_themselves() {
    repeats_itself(
        &[
            "two-layer",
            "--level",
            "1",
            "--steps",
            "20",
            "--pin",
            "below:z:-0.9@50",
            "--load",
            "grab=0,0,2;on=above:z:0.9;stiffness=5;end=0.004",
            "--load",
            "gravity=1,0,0;start=0.002",
        ],
        "two-layer",
        "frame_00020.obj",
    );
}

#[test]
fn a_json_scenario_runs_like_its_toml_twin_and_names_its_lines() {
    let dir = tempfile::tempdir().unwrap();
    let toml = dir.path().join("v.toml");
    let json = dir.path().join("v.json");
    std::fs::write(
        &toml,
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"builtin:icosphere\"\n\
         [lattice]\nresolution = 10\nvoxels_per_cell = 2\n[run]\nscene = \"free\"\nsteps = 4\n\
         [[anchors]]\nbelow = { axis = \"z\", value = -0.06 }\n\
         [[loads]]\nforce = [0.0, 0.0, 1.0]\nabove = { axis = \"z\", value = 0.06 }\n",
    )
    .unwrap();
    std::fs::write(
        &json,
        r#"{
  "system": {"kind": "volumetric"},
  "mesh": {"path": "builtin:icosphere"},
  "lattice": {"resolution": 10, "voxels_per_cell": 2},
  "run": {"scene": "free", "steps": 4},
  "anchors": [{"below": {"axis": "z", "value": -0.06}}],
  "loads": [{"force": [0.0, 0.0, 1.0], "above": {"axis": "z", "value": 0.06}}]
}
"#,
    )
    .unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (file, out) in [(&toml, &a), (&json, &b)] {
        ok(&run_balloon(&[
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]));
    }
    // The same run: the same record (TOML for both) and the same last frame.
    assert_eq!(bytes(&a, "scenario.toml"), bytes(&b, "scenario.toml"));
    assert_eq!(bytes(&a, "frame_00000.obj"), bytes(&b, "frame_00000.obj"));
    let last = |d: &std::path::Path| {
        let mut frames: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.starts_with("frame_"))
            .collect();
        frames.sort();
        frames.pop().unwrap()
    };
    assert_eq!(bytes(&a, &last(&a)), bytes(&b, &last(&b)));
    // Errors name the JSON file's line and the key.
    for (text, want) in [
        (
            "{\n  \"run\": {\n    \"steps\": -3\n  }\n}\n",
            "v.json:3: `run.steps`",
        ),
        (
            "{\n  \"run\": {\"stepz\": 3}\n}\n",
            "v.json:2: `run.stepz`: unknown key",
        ),
        (
            "{\n  \"run\": {\"steps\": 3,}\n}\n",
            "v.json:2: not valid JSON",
        ),
        (
            "{\"system\": {\"kind\": \"volumetric\"},\n \"anchors\": [\n  {\"below\": 3}\n ]\n}\n",
            "v.json:3: `anchors.below`",
        ),
    ] {
        std::fs::write(&json, text).unwrap();
        let out = run_balloon(&["run", json.to_str().unwrap()]);
        assert!(!out.status.success(), "{text}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(want), "{want} not in: {err}");
    }
}

#[test]
fn the_follower_term_is_on_by_default_off_in_the_papers_mode_and_either_on_request() {
    // `--follower-term` is a switch with a default of its own: left out, the converged solver
    // includes the follower term and the paper's mode (`--newton-tol 0`) does not; given, it
    // wins either way (`--follower-term`, `=true`, `=false`), and a scenario's
    // `follower_term = false` turns it off (not "leave it out"), recorded as such.
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let mesh = mesh.to_str().unwrap();
    let summary = |extra: &[&str]| {
        let mut args = vec!["inflate", mesh, "--steps", "2", "--json"];
        args.extend_from_slice(extra);
        let out = run_balloon(&args);
        ok(&out);
        last_json_line(&out)["follower_term"].clone()
    };
    assert_eq!(summary(&[]), true);
    assert_eq!(
        summary(&["--newton-tol", "0", "--newton-iters", "3"]),
        false
    );
    assert_eq!(summary(&["--follower-term"]), true);
    assert_eq!(summary(&["--follower-term=false"]), false);
    assert_eq!(
        summary(&[
            "--newton-tol",
            "0",
            "--newton-iters",
            "3",
            "--follower-term=true"
        ]),
        true
    );
    let scenario = dir.path().join("s.toml");
    let out_dir = dir.path().join("run");
    std::fs::write(
        &scenario,
        "[mesh]\npath = \"sphere.obj\"\n[run]\nsteps = 2\nfollower_term = false\n",
    )
    .unwrap();
    let out = run_balloon(&[
        "run",
        scenario.to_str().unwrap(),
        "--json",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    ok(&out);
    assert_eq!(last_json_line(&out)["follower_term"], false);
    let recorded = std::fs::read_to_string(out_dir.join("scenario.toml")).unwrap();
    assert!(recorded.contains("follower_term = false"), "{recorded}");
}
