//! `balloon inflate` end to end: JSON summary, output folder, bad input, divergence.

use super::{last_json_line, run_balloon};
use std::path::{Path, PathBuf};

/// A small closed sphere (162 vertices) written as OBJ into `dir`.
fn small_sphere(dir: &Path) -> PathBuf {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let path = dir.join("sphere.obj");
    balloon_mesh::io::write_obj(&path, &mesh).unwrap();
    path
}

const SUMMARY_KEYS: &[&str] = &[
    "vertices",
    "triangles",
    "steps",
    "converged",
    "sim_time_s",
    "initial_gas_volume",
    "final_gas_volume",
    "final_gauge_pressure",
    "shell_volume_ratio_final",
    "shell_volume_ratio_max_deviation",
    "mean_step_ms",
    "newton_iterations_total",
    "newton_tolerance",
    "newton_residual_max",
    "line_search_cuts_total",
    "min_dt_used",
    "linear_iterations_total",
];

#[test]
fn every_step_and_the_summary_say_where_the_time_went() {
    // stats.jsonl's `times` per step and the summary's `phase_times_ms`: the phases are timed
    // apart, so per step they sum to at most the step's wall time, the run's totals are the
    // sum of the steps', the default (factorising) solver spends time factorising and the
    // global projection runs every step.
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let out_dir = dir.path().join("run");
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--steps",
        "4",
        "--json",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    let phases = [
        "forces_ms",
        "energy_ms",
        "assembly_ms",
        "factorization_ms",
        "solve_ms",
        "projection_ms",
    ];
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    let mut sum = [0.0; 6];
    let mut lines = 0;
    for line in stats.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let t = &v["times"];
        let mut total = 0.0;
        for (k, name) in phases.iter().enumerate() {
            let x = t[name]
                .as_f64()
                .unwrap_or_else(|| panic!("no `{name}` in {line}"));
            assert!(x >= 0.0, "{name} {x}");
            sum[k] += x;
            total += x;
        }
        let step_ms = v["step_ms"].as_f64().unwrap();
        assert!(
            total <= step_ms + 1e-9,
            "phases {total} ms in a {step_ms} ms step"
        );
        assert!(t["forces_ms"].as_f64().unwrap() > 0.0, "{line}");
        assert!(t["projection_ms"].as_f64().unwrap() > 0.0, "{line}");
        lines += 1;
    }
    assert_eq!(lines, 4, "{stats}");
    let run = &s["phase_times_ms"];
    for (k, name) in phases.iter().enumerate() {
        let x = run[name].as_f64().unwrap();
        assert!(
            (x - sum[k]).abs() <= 1e-9 * (1.0 + x),
            "{name}: {x} vs {}",
            sum[k]
        );
    }
    assert!(run["factorization_ms"].as_f64().unwrap() > 0.0, "{run}");
    let mean = s["mean_step_ms"].as_f64().unwrap();
    assert!(
        sum.iter().sum::<f64>() <= 4.0 * mean + 1e-9,
        "{run} vs {mean} ms/step"
    );
}

#[test]
fn json_summary_has_the_documented_keys_and_sane_values() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let out = run_balloon(&["inflate", mesh.to_str().unwrap(), "--steps", "5", "--json"]);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    for k in SUMMARY_KEYS {
        assert!(s.get(k).is_some(), "summary lacks `{k}`: {s}");
    }
    assert_eq!(s["vertices"], 162);
    assert_eq!(s["triangles"], 320);
    assert_eq!(s["steps"], 5);
    assert!(
        s["final_gas_volume"].as_f64().unwrap() > s["initial_gas_volume"].as_f64().unwrap(),
        "the pump inflates"
    );
    assert!(s["shell_volume_ratio_max_deviation"].as_f64().unwrap() < 1e-9);
    // The default is the converged mode: every step's Newton residual met the tolerance.
    assert_eq!(s["newton_tolerance"], 1e-6);
    let worst = s["newton_residual_max"].as_f64().unwrap();
    assert!(
        worst > 0.0 && worst <= 1e-6,
        "largest relative residual {worst}"
    );
    assert!(s["newton_iterations_total"].as_u64().unwrap() >= 5);
    // The paper's mode is exactly 3 full Newton steps per step, no convergence test.
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--steps",
        "5",
        "--json",
        "--newton-iters",
        "3",
        "--newton-tol",
        "0",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert_eq!(
        s["newton_iterations_total"], 15,
        "3 per step in the paper's mode"
    );
    assert_eq!(s["line_search_cuts_total"], 0);
}

/// `--inexact-forcing 0` solves every Newton system to `--cg-tol` instead of a fraction of
/// the Newton tolerance: the same converged steps (Newton stops on the nonlinear residual) for
/// more CG iterations; a static solve takes the flag too. Checked by mutation: ignoring the
/// flag gives equal CG counts.
#[test]
fn inexact_forcing_changes_the_cg_work_not_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let run = |extra: &[&str]| {
        let mut argv = vec![
            "inflate",
            mesh.to_str().unwrap(),
            "--steps",
            "4",
            "--json",
            "--gas",
            "ideal",
            "--ambient",
            "0",
            "--cg-tol",
            "1e-10",
        ];
        argv.extend_from_slice(extra);
        let out = run_balloon(&argv);
        assert!(
            out.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        last_json_line(&out)
    };
    let (inexact, exact) = (run(&[]), run(&["--inexact-forcing", "0"]));
    let (vi, ve) = (
        inexact["final_gas_volume"].as_f64().unwrap(),
        exact["final_gas_volume"].as_f64().unwrap(),
    );
    assert!((vi - ve).abs() <= 1e-6 * ve, "{vi} vs {ve}");
    assert!(vi > 1.01 * inexact["initial_gas_volume"].as_f64().unwrap());
    let cg = |s: &serde_json::Value| s["linear_iterations_total"].as_u64().unwrap();
    assert!(
        cg(&inexact) < cg(&exact),
        "CG iterations: {} with forcing, {} without",
        cg(&inexact),
        cg(&exact)
    );
    let statics: Vec<serde_json::Value> = ["0.1", "0"]
        .into_iter()
        .map(|forcing| {
            let out = run_balloon(&[
                "inflate",
                mesh.to_str().unwrap(),
                "--static",
                "--json",
                "--gas",
                "constant",
                "--pressure",
                "500",
                "--inexact-forcing",
                forcing,
            ]);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            last_json_line(&out)
        })
        .collect();
    for s in &statics {
        assert_eq!(s["converged"], true, "{s}");
    }
    let volume = |s: &serde_json::Value| s["final_gas_volume"].as_f64().unwrap();
    assert!((volume(&statics[0]) - volume(&statics[1])).abs() <= 1e-6 * volume(&statics[1]));
}

#[test]
fn newton_flags_out_of_range_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    for (flag, value) in [
        ("--newton-iters", "0"),
        ("--newton-iters", "4294967296"),
        ("--newton-tol", "-1"),
        ("--newton-tol", "nan"),
        ("--newton-tol", "inf"),
        ("--inexact-forcing", "-0.1"),
        ("--inexact-forcing", "1.5"),
        ("--inexact-forcing", "nan"),
    ] {
        let arg = format!("{flag}={value}");
        let out = run_balloon(&["inflate", mesh.to_str().unwrap(), &arg]);
        assert!(!out.status.success(), "{flag} {value} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(flag) && err.contains(value),
            "{flag} {value}: {err}"
        );
    }
}

#[test]
fn out_folder_gets_frames_stats_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let out_dir = dir.path().join("run");
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--steps",
        "4",
        "--frame-every",
        "2",
        "--linear-solver",
        "cholesky",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "frame_00000.obj",
        "frame_00002.obj",
        "frame_00004.obj",
        "final.obj",
        "summary.json",
        "stats.jsonl",
    ] {
        assert!(out_dir.join(f).is_file(), "missing {f}");
    }
    let final_mesh = balloon_mesh::io::read_mesh(&out_dir.join("final.obj")).unwrap();
    assert_eq!(final_mesh.num_vertices(), 162);
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    let rows: Vec<serde_json::Value> = stats
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 4);
    // Each step converged (relative residual within the default 1e-6) in at least one iteration.
    assert!(
        rows.iter()
            .all(|r| r["newton_iterations"].as_u64().unwrap() >= 1
                && r["newton_residual"].as_f64().unwrap() <= 1e-6)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["steps"], 4);
    assert!(summary["error"].is_null());
}

#[test]
fn open_mesh_is_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("open.obj");
    std::fs::write(
        &path,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n",
    )
    .unwrap();
    let out = run_balloon(&["inflate", path.to_str().unwrap(), "--steps", "1"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("open.obj"), "{err}");
    assert!(err.contains("boundary") || err.contains("open"), "{err}");
}

#[test]
fn out_of_range_parameters_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let m = mesh.to_str().unwrap();
    for (flag, value, word) in [
        ("--poisson", "0.5", "poisson"),
        ("--young", "-1", "young"),
        ("--thickness", "0", "thickness"),
        ("--density", "-3", "density"),
        ("--dt", "0", "dt"),
        ("--scale", "0", "scale"),
    ] {
        let out = run_balloon(&["inflate", m, flag, value, "--steps", "1"]);
        assert!(!out.status.success(), "{flag} {value} should fail");
        let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
        assert!(err.contains(word), "{flag} {value}: {err}");
    }
}

#[test]
fn diverging_run_fails_naming_the_step_and_keeps_its_output() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let out_dir = dir.path().join("run");
    // Neo-Hookean under a constant pressure far above its limit point: no equilibrium.
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--material",
        "neo-hookean",
        "--gas",
        "constant",
        "--pressure",
        "20000",
        "--dt",
        "0.05",
        "--steps",
        "500",
        "--linear-solver",
        "cholesky",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("step "), "{err}");
    let summary = std::fs::read_to_string(out_dir.join("summary.json"))
        .unwrap_or_else(|e| panic!("no summary.json ({e}); stderr: {err}"));
    let summary: serde_json::Value = serde_json::from_str(&summary).unwrap();
    assert!(summary["error"].as_str().unwrap().contains("step"));
    let steps = summary["steps"].as_u64().unwrap() as usize;
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    assert_eq!(
        stats.lines().count(),
        steps,
        "one complete stats line per completed step"
    );
    for l in stats.lines() {
        serde_json::from_str::<serde_json::Value>(l).unwrap();
    }
    balloon_mesh::io::read_mesh(&out_dir.join("final.obj")).unwrap();
}

#[test]
fn a_newton_cap_too_low_for_the_tolerance_is_a_warning_in_the_summary() {
    // With the residual test on, `--newton-iters 1` cannot converge a step: the steps are
    // split into sub-steps, which the summary says, pointing at the paper's mode.
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--newton-iters",
        "1",
        "--steps",
        "3",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert!(s["split_steps"].as_u64().unwrap() > 0, "{s}");
    let warnings = s["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{s}");
    let w = warnings[0].as_str().unwrap();
    assert!(
        w.contains("newton_iters") && w.contains("= 1") && w.contains("newton_tol` = 0"),
        "{w}"
    );
    // The paper's mode (no residual test) and the default cap give no warning.
    for args in [
        &["--newton-iters", "1", "--newton-tol", "0"][..],
        &["--newton-iters", "50"][..],
    ] {
        let mut all = vec!["inflate", "builtin:icosphere", "--steps", "3", "--json"];
        all.extend_from_slice(args);
        let out = run_balloon(&all);
        assert!(out.status.success());
        let s = last_json_line(&out);
        assert_eq!(s["warnings"], serde_json::json!([]), "{args:?}: {s}");
    }
}

/// The warnings of a `balloon inflate` run with `args` (its JSON summary), and its Newton
/// iterations per step.
fn inflate_warnings(args: &[&str]) -> (Vec<String>, f64) {
    let mut all = vec!["inflate"];
    all.extend_from_slice(args);
    all.push("--json");
    let out = run_balloon(&all);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    let per_step = s["newton_iterations_total"].as_f64().unwrap() / s["steps"].as_f64().unwrap();
    let warnings = s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect();
    (warnings, per_step)
}

#[test]
fn a_floppy_wall_is_a_warning_that_says_whether_bending_would_hold_it() {
    // The default pump on the built-in teddy (0.3 m, 4.5 mm edges): the paper's wall is
    // floppy, and a plate bending stiffness holds mesh-scale wrinkles within a 10 ms step
    // (`D dt^2 / (rho h l^4)` about 2.4), so the warning suggests `bending`.
    let (warnings, per_step) = inflate_warnings(&["builtin:teddy", "--steps", "3"]);
    assert!(per_step > 10.0, "{per_step}");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert!(
        w.contains("Newton iterations on average")
            && w.contains("`bending` = 1")
            && w.contains("holds such wrinkles within a step"),
        "{w}"
    );
    // With the bending term the same steps are whole and cheap: no warning.
    let (warnings, per_step) =
        inflate_warnings(&["builtin:teddy", "--steps", "3", "--bending", "1"]);
    assert!(
        per_step <= 10.0 && warnings.is_empty(),
        "{per_step}: {warnings:?}"
    );
    // The paper's pressurised gas stretches the wall from the start: no warning.
    let (warnings, per_step) = inflate_warnings(&[
        "builtin:teddy",
        "--steps",
        "3",
        "--gas",
        "ideal",
        "--ambient",
        "0",
    ]);
    assert!(
        per_step <= 10.0 && warnings.is_empty(),
        "{per_step}: {warnings:?}"
    );
    // At 1 m (30 mm edges, ratio about 1e-3) bending would not hold the wrinkles within a
    // step, and the warning does not suggest it. A run of 10 steps or more says so after its
    // fifth step already (on stderr, with the human output), and again in its summary.
    let Some(dir) = crate::shared_meshes_dir() else {
        return;
    };
    let bunny = dir.join("bunny_closed_libigl.off").display().to_string();
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("bunny");
    let out = run_balloon(&[
        "inflate",
        &bunny,
        "--scale",
        "6.418666509195382",
        "--steps",
        "10",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let early = stderr
        .lines()
        .find(|l| l.starts_with("warning: the first 5 of 10 steps took"))
        .unwrap_or_else(|| panic!("no early warning: {stderr}"));
    assert!(
        early.contains("does not hold them within a step") && early.contains("Ctrl-C"),
        "{early}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    let per_step = summary["newton_iterations_total"].as_f64().unwrap() / 10.0;
    assert!(per_step > 10.0, "{per_step}");
    let warnings = summary["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{summary}");
    let w = warnings[0].as_str().unwrap();
    assert!(
        w.starts_with("the steps took")
            && w.contains("does not hold them within a step")
            && !w.contains("holds such wrinkles within a step"),
        "{w}"
    );
    // The human output repeats the summary's warning after the run, on stdout.
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(&format!("warning: {w}")), "{stdout}");
    // The warning's time for the wall's elastic wave to cross an element, against the
    // bunny's own: its mean edge length at 1 m from its file, and the default wall (1 MPa,
    // Poisson's ratio 0.45, 950 kg/m^3) with the plane-stress modulus Y / (1 - nu^2).
    let crossing = number_after(w, "`l / sqrt(E / rho)` = ");
    let mesh = balloon_mesh::io::read_mesh(std::path::Path::new(&bunny)).unwrap();
    let (mut sum, mut edges) = (0.0, 0.0);
    for t in &mesh.triangles {
        for k in 0..3 {
            sum += (mesh.vertices[t[k]] - mesh.vertices[t[(k + 1) % 3]]).norm();
            edges += 1.0;
        }
    }
    let l = 6.418666509195382 * sum / edges;
    let expected = l * (950.0 * (1.0 - 0.45f64 * 0.45) / 1e6).sqrt();
    assert!(
        (crossing / expected - 1.0).abs() < 1e-2,
        "{crossing} against {expected}: {w}"
    );
    // What it says a floppy step takes holds for this run's steps.
    let fewest = number_after(w, "with the membrane modulus E: ");
    let most = number_after(w, &format!("with the membrane modulus E: {fewest} to "));
    assert!(
        fewest <= per_step && per_step <= most,
        "{per_step} Newton iterations per step, outside {fewest} to {most}: {w}"
    );
}

/// The number that follows `prefix` in `text` (up to the next space or `)`).
fn number_after(text: &str, prefix: &str) -> f64 {
    let rest = &text[text
        .find(prefix)
        .unwrap_or_else(|| panic!("no {prefix:?} in {text}"))
        + prefix.len()..];
    let end = rest.find([' ', ')']).unwrap_or(rest.len());
    rest[..end]
        .parse()
        .unwrap_or_else(|e| panic!("{:?} after {prefix:?}: {e}", &rest[..end]))
}

/// A 162-vertex sphere of `radius` (m) flattened to 1 : 0.5 : 0.3, written to `dir/flat.obj`
/// (a shell that bends as it inflates).
fn flattened_sphere(dir: &std::path::Path, radius: f64) -> std::path::PathBuf {
    let mut mesh = balloon_mesh::generate::icosphere(radius, 2).unwrap();
    for v in &mut mesh.vertices {
        v.y *= 0.5;
        v.z *= 0.3;
    }
    let path = dir.join("flat.obj");
    balloon_mesh::io::write_obj(&path, &mesh).unwrap();
    path
}

/// `--bending F` gives the wall the bending stiffness of a plate times `F`: the run records it
/// (`[shell] bending`), `balloon run` of that record repeats the run byte for byte, and on a
/// flattened sphere (whose inflation changes its curvature) the bending wall ends elsewhere
/// than the paper's wall, which has none.
#[test]
fn the_wall_bending_flag_is_recorded_repeated_and_changes_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let path = flattened_sphere(dir.path(), 0.1);
    let run = |name: &str, bending: &str| {
        let out_dir = dir.path().join(name);
        let out = run_balloon(&[
            "inflate",
            path.to_str().unwrap(),
            "--steps",
            "3",
            "--bending",
            bending,
            "--json",
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        (last_json_line(&out), out_dir)
    };
    let (plain, plain_dir) = run("plain", "0");
    let (bent, bent_dir) = run("bent", "1000");
    assert_eq!(plain["scenario"]["shell"]["bending"], 0.0);
    assert_eq!(bent["scenario"]["shell"]["bending"], 1000.0);
    let a = super::obj_points(&plain_dir.join("final.obj"));
    let b = super::obj_points(&bent_dir.join("final.obj"));
    let gap = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    assert!(gap > 1e-6, "the bending wall moves differently: {gap:e} m");
    let record = bent_dir.join("scenario.toml");
    let text = std::fs::read_to_string(&record).unwrap();
    assert!(text.contains("bending = 1000"), "{text}");
    let again = dir.path().join("again");
    let out = run_balloon(&[
        "run",
        record.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read(again.join("final.obj")).unwrap(),
        std::fs::read(bent_dir.join("final.obj")).unwrap()
    );
}

/// On a model whose bending term is weak against stretching (a flattened sphere of 1 m), the
/// default solver factorises a split matrix (the hinges' opposite-corner couplings bounded by
/// diagonal blocks, the difference applied by CG) and reaches the states of the exact direct
/// solver.
#[test]
fn a_split_bending_stiffness_reaches_the_states_of_the_direct_solver() {
    let dir = tempfile::tempdir().unwrap();
    let path = flattened_sphere(dir.path(), 1.0);
    let run = |name: &str, solver: &str| {
        let out_dir = dir.path().join(name);
        let out = run_balloon(&[
            "inflate",
            path.to_str().unwrap(),
            "--steps",
            "4",
            "--bending",
            "1",
            "--linear-solver",
            solver,
            "--newton-tol",
            "1e-9",
            "--json",
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        super::obj_points(&out_dir.join("final.obj"))
    };
    let split = run("split", "factorized-pcg");
    let direct = run("direct", "cholesky");
    let moved = split
        .iter()
        .zip(super::obj_points(&path))
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    let gap = split
        .iter()
        .zip(&direct)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-4, "the shell moved: {moved:e} m");
    assert!(gap <= 1e-7, "split {gap:e} m from the direct solver's");
}
