//! `balloon two-layer` end-to-end tests.

use super::{last_json_line, run_balloon};
use std::path::Path;

fn obj_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|v| v.parse().unwrap()).collect();
            [c[0], c[1], c[2]]
        })
        .collect()
}

#[test]
fn every_dimension_runs_and_reports_the_summary() {
    for (args, particles, springs) in [
        (vec!["--dim", "1"], 2u64, 1u64),
        (vec!["--dim", "2", "--particles", "10"], 20, 50),
        (vec!["--dim", "3", "--level", "1"], 36, 210),
        (
            vec![
                "--dim", "3", "--sphere", "uv", "--slices", "6", "--stacks", "4",
            ],
            40,
            0,
        ),
    ] {
        let mut a = vec!["two-layer", "--steps", "200", "--json"];
        a.extend(&args);
        let out = run_balloon(&a);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let j = last_json_line(&out);
        assert_eq!(j["particles"], particles, "{args:?}");
        if springs > 0 {
            assert_eq!(j["springs"], springs, "{args:?}");
        }
        assert_eq!(j["steps"], 200);
        assert_eq!(j["escaped_particles"], 0);
        for key in [
            "dt",
            "final_volume_outer",
            "final_volume_inner",
            "energy_initial",
            "energy_final",
            "min_height",
            "mean_step_ms",
        ] {
            assert!(j[key].is_number(), "{key} missing in {j}");
        }
        if args[1] != "1" {
            assert!(
                j["final_volume_outer"].as_f64().unwrap()
                    > j["final_volume_inner"].as_f64().unwrap()
            );
        }
    }
}

#[test]
fn every_integrator_runs() {
    for method in ["euler", "midpoint", "rk4", "symplectic"] {
        let out = run_balloon(&[
            "two-layer",
            "--level",
            "1",
            "--steps",
            "100",
            "--integrator",
            method,
            "--json",
        ]);
        assert!(out.status.success(), "{method}");
        let j = last_json_line(&out);
        assert_eq!(j["integrator"], method);
    }
    let out = run_balloon(&["two-layer", "--integrator", "verlet"]);
    assert!(!out.status.success());
}

#[test]
fn output_folder_has_frames_stats_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--steps",
        "60",
        "--frame-every",
        "20",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for k in [0, 20, 40, 60] {
        let f = dir.path().join(format!("frame_{k:05}.obj"));
        // Both layers of the level-1 octahedron sphere: 2 x 18 vertices.
        assert_eq!(obj_vertices(&f).len(), 36, "{}", f.display());
    }
    let stats = std::fs::read_to_string(dir.path().join("stats.jsonl")).unwrap();
    let rows: Vec<serde_json::Value> = stats
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 60);
    assert_eq!(rows[59]["step"], 60);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "ok");
    assert_eq!(summary["frames"], 4);
}

/// The drag spring pulls the body toward its target: with no gravity and no box the body's
/// centre moves along +x toward the target at (4, 0, 0).
#[test]
fn drag_pulls_the_body_toward_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--gravity",
        "0",
        "--no-box",
        "--steps",
        "800",
        "--dt",
        "1e-3",
        "--drag",
        "4,0,0@0:0.6",
        "--drag-stiffness",
        "5",
        "--frame-every",
        "0",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let centre = |k: usize| {
        let v = obj_vertices(&dir.path().join(format!("frame_{k:05}.obj")));
        v.iter().map(|p| p[0]).sum::<f64>() / v.len() as f64
    };
    assert!(
        centre(800) > centre(0) + 0.05,
        "{} -> {}",
        centre(0),
        centre(800)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert!(summary["work_done"].as_f64().unwrap() > 0.0);
}

#[test]
fn bad_parameters_fail_with_the_parameter_named() {
    for (args, needle) in [
        (vec!["--dt", "0"], "dt"),
        (vec!["--dt", "-1e-3"], "dt"),
        (vec!["--inner-mass", "0"], "--inner-mass"),
        (vec!["--outer-mass", "-1"], "--outer-mass"),
        (vec!["--inner-radius", "0"], "--inner-radius"),
        (vec!["--inner-radius", "1.5"], "below the outer radius"),
        (vec!["--k-radius", "0"], "radius stiffness"),
        (vec!["--restitution", "2"], "restitution"),
        (vec!["--box", "1"], "collision_box"),
        (vec!["--drag", "1,2"], "--drag"),
        (vec!["--dim", "4"], "dim"),
    ] {
        let mut a = vec!["two-layer", "--level", "1", "--steps", "5"];
        a.extend(&args);
        let out = run_balloon(&a);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(needle),
            "{args:?}: `{err}` should mention `{needle}`"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
}

/// Springs far too stiff for the explicit step: the run stops with an error naming the step,
/// integrator and dt, and what was written before stays readable.
#[test]
fn blow_up_is_reported_and_output_stays_readable() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--k-structural",
        "2e4",
        "--damping",
        "0",
        "--integrator",
        "euler",
        "--dt",
        "2e-3",
        "--steps",
        "3000",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("blew up at step") && err.contains("euler") && err.contains("smaller dt"),
        "{err}"
    );
    let stats = std::fs::read_to_string(dir.path().join("stats.jsonl")).unwrap();
    for line in stats.lines() {
        let row: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(row["total"].as_f64().unwrap().is_finite());
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "blew_up");
    assert!(summary["steps"].as_u64().unwrap() < 3000);
    assert!(obj_vertices(&dir.path().join("frame_00000.obj")).len() == 36);
}
