//! `balloon connect` (issue 14, item 4): two neo-Hookean icospheres of 162 vertices pre-inflated
//! on opposite sides of the pressure maximum and joined with instant equalisation settle at the
//! analytic end state of the thin sphere (`ThinSphere::joined_pair`); the balloons as the
//! components of one file; the records (stats lines, summary, pictures, interruption) and the
//! refusals, each naming its flag.

use super::records::{check_interrupted, read_json, signal_and_wait, spawn, wait_for};
use super::{last_json_line, run_balloon};
use balloon::mesh::generate::icosphere;
use std::path::{Path, PathBuf};

/// The rubber of the experiment: neo-Hookean membrane, mu = 0.4 MPa, 1 mm wall, damped.
const RUBBER: &[&str] = &[
    "--material",
    "membrane-neo-hookean",
    "--mu",
    "4e5",
    "--thickness",
    "1e-3",
    "--mass-damping",
    "5",
];

/// Writes an icosphere of level 2 (162 vertices, radius 0.1 m) to `dir/ico2.obj`, and with
/// `two` a second one 0.5 m along x in the same file.
fn sphere_file(dir: &Path, two: bool) -> PathBuf {
    let mut mesh = icosphere(0.1, 2).unwrap();
    if two {
        let n = mesh.num_vertices();
        let other: Vec<_> = mesh
            .vertices
            .iter()
            .map(|p| p + nalgebra::Vector3::x() * 0.5)
            .collect();
        let tris: Vec<[usize; 3]> = mesh.triangles.iter().map(|t| t.map(|i| i + n)).collect();
        mesh.vertices.extend(other);
        mesh.triangles.extend(tris);
    }
    let path = dir.join(if two { "two.obj" } else { "ico2.obj" });
    balloon::mesh::io::write_obj(&path, &mesh).unwrap();
    path
}

fn connect(args: &[&str]) -> std::process::Output {
    let mut all = vec!["connect"];
    all.extend_from_slice(args);
    all.extend_from_slice(RUBBER);
    run_balloon(&all)
}

#[test]
fn two_icospheres_with_instant_equalisation_settle_at_the_analytic_end_state() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere_file(dir.path(), false);
    let run = dir.path().join("run");
    let out = connect(&[
        mesh.to_str().unwrap(),
        "--copies",
        "2",
        "--stretches",
        "1.35,1.6",
        "--conductance",
        "instant",
        "--until-settled",
        "--volume-tol",
        "1e-8",
        "--steps",
        "3000",
        "--frame-every",
        "100",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let s = read_json(&run.join("summary.json"));
    assert_eq!(last_json_line(&out), s);
    assert_eq!(
        (s["status"].as_str(), s["settled"].as_bool()),
        (Some("ok"), Some(true)),
        "{s}"
    );
    assert_eq!(s["balloons"], 2);
    assert_eq!(s["layout"], "copies");
    // The smaller balloon emptied into the larger one, at the analytic end state.
    let b = s["balloon_states"].as_array().unwrap();
    let l = |i: usize, k: &str| b[i][k].as_f64().unwrap();
    assert!((l(0, "start_stretch") - 1.35).abs() < 1e-6, "{s}");
    assert!((l(1, "start_stretch") - 1.6).abs() < 1e-6, "{s}");
    assert!(l(0, "stretch") < 1.3 && l(1, "stretch") > 1.65, "{s}");
    let a = &s["analytic"];
    let (ls, ll) = (
        a["small_stretch"].as_f64().unwrap(),
        a["large_stretch"].as_f64().unwrap(),
    );
    assert!((l(0, "stretch") / ls - 1.0).abs() < 1e-3, "{s}");
    assert!((l(1, "stretch") / ll - 1.0).abs() < 1e-3, "{s}");
    assert!(a["small_stretch_error"].as_f64().unwrap() < 1e-3, "{s}");
    assert!(a["large_stretch_error"].as_f64().unwrap() < 1e-3, "{s}");
    assert!(a["pressure_error"].as_f64().unwrap() < 3e-3, "{s}");
    // One pressure, and the gas conserved.
    assert!(
        (l(0, "gauge_pressure") / l(1, "gauge_pressure") - 1.0).abs() < 1e-3,
        "{s}"
    );
    let (t0, t1) = (
        s["total_amount_start"].as_f64().unwrap(),
        s["total_amount_end"].as_f64().unwrap(),
    );
    assert!((t1 / t0 - 1.0).abs() < 1e-12, "{s}");
    // One stats line per step, each with every balloon's state and the total amount.
    let steps = s["steps"].as_u64().unwrap() as usize;
    let rows: Vec<serde_json::Value> = std::fs::read_to_string(run.join("stats.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), steps);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r["step"], i + 1);
        for key in ["gauge_pressures", "volumes", "amounts", "stretches"] {
            assert_eq!(r[key].as_array().map(Vec::len), Some(2), "{key}: {r}");
        }
        let sum: f64 = r["amounts"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .sum();
        assert!((sum / r["total_amount"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    }
    let last = &rows[steps - 1];
    assert_eq!(last["stretches"][0].as_f64(), Some(l(0, "stretch")));
    // The frames hold both balloons; the pictures are written.
    let first = balloon::mesh::load(run.join("frame_00000.obj").to_str().unwrap()).unwrap();
    assert_eq!((first.num_vertices(), first.num_triangles()), (324, 640));
    for f in [
        "final.obj",
        "pair_start.png",
        "pair_end.png",
        "pressure_stretch.png",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    // The recorded scenario is a connect scenario with what ran.
    let rec = std::fs::read_to_string(run.join("scenario.toml")).unwrap();
    for line in [
        "kind = \"connect\"",
        "stretches = [1.35, 1.6]",
        "conductance = \"instant\"",
        "model = \"ideal\"",
        "until_settled = true",
    ] {
        assert!(rec.contains(line), "{line}: {rec}");
    }
}

#[test]
fn the_components_of_one_file_are_the_balloons_and_a_finite_tube_conserves_the_gas() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere_file(dir.path(), true);
    let out = connect(&[
        mesh.to_str().unwrap(),
        "--pressures",
        "3000,1000",
        "--conductance",
        "0.5",
        "--steps",
        "20",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert_eq!(
        (s["layout"].as_str(), s["balloons"].as_u64()),
        (Some("components"), Some(2))
    );
    assert_eq!(s["conductance"], "0.5");
    let b = s["balloon_states"].as_array().unwrap();
    // They start unstretched, at their own pressures; the tube moves gas from 0 to 1.
    let g = |i: usize, k: &str| b[i][k].as_f64().unwrap();
    assert!((g(0, "start_gauge_pressure") - 3000.0).abs() < 1e-6, "{s}");
    assert!((g(1, "start_gauge_pressure") - 1000.0).abs() < 1e-6, "{s}");
    let amount0 = (101325.0 + 3000.0) * g(0, "rest_gas_volume");
    assert!(g(0, "amount") < amount0, "{s}");
    let (t0, t1) = (
        s["total_amount_start"].as_f64().unwrap(),
        s["total_amount_end"].as_f64().unwrap(),
    );
    assert!((t1 / t0 - 1.0).abs() < 1e-12, "{s}");
    // Too little gas for one balloon on each side of the maximum: no analytic end state, and
    // the note says why.
    assert!(s["analytic"].is_null(), "{s}");
    let note = s["analytic_note"].as_str().unwrap();
    assert!(note.contains("no equal-pressure state"), "{note}");
}

#[test]
fn refusals_name_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere_file(dir.path(), false);
    let m = mesh.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &[m, "--copies", "2", "--stretches", "1.35"],
            "--stretches has 1 value(s) but there are 2 balloons",
        ),
        (
            &[m, "--copies", "3", "--pressures", "1,2"],
            "--pressures has 2 value(s) but there are 3",
        ),
        (
            &[
                m,
                "--copies",
                "2",
                "--stretches",
                "1.2,1.3",
                "--tubes",
                "0-2",
            ],
            "--tubes: 0-2",
        ),
        (
            &[
                m,
                "--copies",
                "2",
                "--stretches",
                "1.2,1.3",
                "--tubes",
                "1-1",
            ],
            "--tubes",
        ),
        (
            &[
                m,
                "--copies",
                "2",
                "--stretches",
                "1.2,1.3",
                "--gas",
                "constant",
            ],
            "--gas constant",
        ),
        (
            &[
                m,
                "--copies",
                "2",
                "--stretches",
                "1.2,1.3",
                "--conductance",
                "-1",
            ],
            "--conductance",
        ),
        (
            &[m, "--copies", "2", "--stretches", "1.2,1.3", "--static"],
            "--static",
        ),
        (&[m, "--copies", "2", "--stretches", "1.2,0"], "--stretches"),
        (
            &[m, "--copies", "2", "--stretches", "0.5,1.2"],
            "--stretches: balloon 0 has the stretch 0.5, below 1",
        ),
        (
            &[
                m,
                "--copies",
                "2",
                "--stretches",
                "1.2,1.3",
                "--pressures",
                "1,2",
            ],
            "--pressures",
        ),
        (&[m, "--copies", "2"], "--stretches"),
        (&[m, "--stretches", "1.2,1.3"], "--copies"),
        (&[m, "--copies", "0", "--stretches", "1.2"], "--copies"),
    ];
    for (args, what) in cases {
        let out = connect(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains(what), "{args:?}: {err}");
    }
}

#[test]
fn sigint_keeps_the_records_of_a_connect_run() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere_file(dir.path(), false);
    let run = dir.path().join("run");
    let mut all = vec![
        "connect",
        mesh.to_str().unwrap(),
        "--copies",
        "2",
        "--stretches",
        "1.35,1.6",
        "--conductance",
        "1",
        "--steps",
        "100000000",
        "--frame-every",
        "5",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ];
    all.extend_from_slice(RUBBER);
    let mut child = spawn(&all);
    wait_for(&mut child, &run.join("frame_00005.obj"));
    let out = signal_and_wait(&mut child, "INT");
    check_interrupted(&out, &run, 130, ".obj");
    let s = read_json(&run.join("summary.json"));
    assert_eq!(s["status"], "interrupted");
    assert_eq!(s["balloon_states"].as_array().map(Vec::len), Some(2));
}

#[test]
fn the_two_balloon_example_scenario_runs() {
    let example =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/two-balloons/scenario.toml");
    let out = run_balloon(&["run", example.to_str().unwrap(), "--steps", "3", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert_eq!(
        (s["status"].as_str(), s["steps"].as_u64()),
        (Some("ok"), Some(3)),
        "{s}"
    );
    assert_eq!(s["balloons"], 2);
    // The example is the experiment of the docs: equal spheres with an analytic end state.
    assert!(
        s["analytic"]["small_stretch"].as_f64().unwrap() < 1.35,
        "{s}"
    );
}

#[test]
fn a_connect_record_states_the_resolved_material_and_repeats_the_run() {
    // Without material flags the balloons are StVK shells with the default modulus and
    // Poisson ratio and the global volume projection: the record says so (as inflate's does),
    // instead of "(not set: ...)" comments, and running it again repeats the run bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let mesh = sphere_file(dir.path(), false);
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let out = run_balloon(&[
        "connect",
        mesh.to_str().unwrap(),
        "--copies",
        "2",
        "--stretches",
        "1.02,1.04",
        "--steps",
        "3",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec = std::fs::read_to_string(a.join("scenario.toml")).unwrap();
    for line in [
        "\nmaterial = \"stvk\"\n",
        &format!("\nyoung = {:?}\n", balloon::shell::DEFAULT_YOUNG),
        &format!("\npoisson = {:?}\n", balloon::shell::DEFAULT_POISSON),
        "\nvolume_projection = \"global\"\n",
    ] {
        assert!(rec.contains(line), "{line:?} missing in\n{rec}");
    }
    let out = run_balloon(&[
        "run",
        a.join("scenario.toml").to_str().unwrap(),
        "--out",
        b.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(a.join("final.obj")).unwrap(),
        std::fs::read(b.join("final.obj")).unwrap()
    );
    assert_eq!(
        rec,
        std::fs::read_to_string(b.join("scenario.toml")).unwrap()
    );
}
