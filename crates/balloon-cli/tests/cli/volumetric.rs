//! `balloon volumetric` end-to-end tests.

use crate::{last_json_line, run_balloon};

#[test]
fn json_summary_has_every_key_and_volume_is_conserved() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "16",
        "--voxels-per-cell",
        "2",
        "--steps",
        "20",
        "--dt",
        "5e-4",
        "--frame-every",
        "10",
        "--soft-diagonals",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = last_json_line(&o);
    for key in [
        "cells",
        "tetrahedra",
        "particles",
        "steps",
        "max_cell_volume_error",
        "total_volume_ratio",
        "momentum_drift",
        "angular_momentum_drift",
        "external_impulse",
        "momentum_balance",
        "resolution",
        "step_halvings",
        "mean_step_ms",
    ] {
        assert!(j.get(key).is_some(), "missing key {key} in {j}");
    }
    assert_eq!(j["steps"], 20);
    // Gravity and the floor act: no drift is claimed, the balance with their impulse is given.
    assert!(j["momentum_drift"].is_null(), "{j}");
    let weight_impulse = j["mass"].as_f64().unwrap() * 9.81 * 20.0 * 5e-4;
    assert!(
        j["momentum_balance"].as_f64().unwrap() < 1e-9 * weight_impulse,
        "{j}"
    );
    assert_eq!(
        j["tetrahedra"].as_u64().unwrap(),
        5 * j["cells"].as_u64().unwrap()
    );
    assert!(j["max_cell_volume_error"].as_f64().unwrap() <= 1e-10);
    assert!((j["total_volume_ratio"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    // Files: the lattice for ParaView, frames 0, 10, 20, one stats line per step, the summary.
    let vtk = std::fs::read_to_string(out.join("lattice.vtk")).unwrap();
    assert!(vtk.starts_with("# vtk DataFile Version 3.0"));
    assert!(vtk.contains(&format!("CELLS {} ", j["tetrahedra"])));
    for f in [
        "frame_00000.obj",
        "frame_00010.obj",
        "frame_00020.obj",
        "summary.json",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 20);
    for line in stats.lines() {
        let row: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(row["max_cell_volume_error"].as_f64().unwrap() <= 1e-10);
    }
}

#[test]
fn bad_parameter_is_named_in_the_error() {
    let o = run_balloon(&["volumetric", "builtin:icosphere", "--p-in", "1.5"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--p-in") && err.contains("1.5"), "{err}");
    let o = run_balloon(&["volumetric", "builtin:icosphere", "--dt", "0"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("dt"));
}

#[test]
fn missing_mesh_file_is_reported() {
    let o = run_balloon(&["volumetric", "/nonexistent/soup.obj"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/soup.obj"));
}

#[test]
fn inversion_stops_with_step_and_cell_and_keeps_written_output() {
    // Springs far too soft to hold the falling sphere: the body's tetrahedra invert even after
    // the bounded step halvings; the error names the step and cell, and every stats line written
    // before it parses.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fail");
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "12",
        "--voxels-per-cell",
        "2",
        "--edge-stiffness",
        "0.01",
        "--damping",
        "0",
        "--steps",
        "400",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("step") && err.contains("cell") && err.contains("halvings"),
        "{err}"
    );
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    assert!(stats.lines().count() > 10);
    for line in stats.lines() {
        serde_json::from_str::<serde_json::Value>(line).unwrap();
    }
    assert!(out.join("lattice.vtk").is_file());
}

#[test]
fn global_volume_solver_conserves_cells_in_few_iterations_on_a_real_soup() {
    // The bunny from ../shared/meshes (the built-in teddy when the folder is absent) under the
    // falling sphere, once with the paper's sweeps and once with the global solver.
    let mesh = crate::shared_meshes_dir()
        .map(|d| d.join("bunny_closed_libigl.off").display().to_string())
        .unwrap_or_else(|| "builtin".into());
    let run = |solver: &str| {
        let o = run_balloon(&[
            "volumetric",
            &mesh,
            "--resolution",
            "24",
            "--steps",
            "60",
            "--volume-solver",
            solver,
            "--json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        last_json_line(&o)
    };
    let (sweeps, global) = (run("gauss-seidel"), run("global"));
    assert_eq!(global["volume_solver"], "global");
    assert_eq!(global["cells"], sweeps["cells"]);
    for j in [&sweeps, &global] {
        assert!(j["max_cell_volume_error"].as_f64().unwrap() <= 1e-10, "{j}");
        assert!(
            (j["total_volume_ratio"].as_f64().unwrap() - 1.0).abs() < 1e-9,
            "{j}"
        );
    }
    let (gs, newton) = (
        sweeps["mean_sweeps"].as_f64().unwrap(),
        global["mean_sweeps"].as_f64().unwrap(),
    );
    assert!(
        newton <= 12.0 && newton < gs,
        "global {newton} vs Gauss-Seidel {gs} per step"
    );
    // The global solver only moves along the volume gradients: the scaling correction is
    // refused with the setting named.
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--volume-solver",
        "global",
        "--correction",
        "scaling",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("`correction`") && err.contains("gradient"),
        "{err}"
    );
}

/// The default lattice is sized for about 1000 cells (0.8 to 1.25 times), on the built-in teddy
/// and on real models at their natural size (the bunny is 0.15 m, the torus 2.5 m across); a
/// resolution that leaves nothing names one that works.
#[test]
fn default_lattice_is_sized_for_a_thousand_cells_on_any_model() {
    let mut models = vec!["builtin".to_string(), "builtin:torus".to_string()];
    if let Some(dir) = crate::shared_meshes_dir() {
        for f in ["torus.obj", "bunny_closed_libigl.off"] {
            models.push(dir.join(f).to_string_lossy().into_owned());
        }
    }
    for m in &models {
        let o = run_balloon(&["volumetric", m, "--steps", "0", "--json"]);
        assert!(
            o.status.success(),
            "{m}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let j = last_json_line(&o);
        let cells = j["cells"].as_u64().unwrap();
        assert!((800..=1250).contains(&cells), "{m}: {cells} cells");
        assert!(j["resolution"].as_u64().unwrap() > 24, "{m}: {j}");
    }
    // `--cells` overrides the target.
    let o = run_balloon(&[
        "volumetric",
        "builtin",
        "--cells",
        "300",
        "--steps",
        "0",
        "--json",
    ]);
    let cells = last_json_line(&o)["cells"].as_u64().unwrap();
    assert!((240..=375).contains(&cells), "{cells}");
    // A resolution too coarse for the model says which one would work.
    let o = run_balloon(&[
        "volumetric",
        "builtin:torus",
        "--resolution",
        "6",
        "--steps",
        "0",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("resolution 6 leaves no cell; --resolution ") && err.contains("cells"),
        "{err}"
    );
}
