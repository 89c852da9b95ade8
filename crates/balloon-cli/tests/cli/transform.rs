//! `--transform` (`[mesh] transform`): the mesh moved by a 3x4 matrix after `--scale`.

use crate::{last_json_line, run_balloon};
use std::path::Path;

/// Runs `argv` with `--out dir/name --json`, returns the summary and the last frame
/// (`final.obj` of the shell, the last `frame_*.obj` of the volumetric body).
fn run(dir: &Path, name: &str, argv: &[&str]) -> (serde_json::Value, balloon_mesh::TriMesh) {
    let out = dir.join(name);
    let mut all = argv.to_vec();
    all.extend(["--out", out.to_str().unwrap(), "--json"]);
    let o = run_balloon(&all);
    assert!(
        o.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let last = if out.join("final.obj").is_file() {
        out.join("final.obj")
    } else {
        out.join("frame_00010.obj")
    };
    let mesh = balloon_mesh::io::read_obj(&last).unwrap();
    (last_json_line(&o), mesh)
}

const TRANSLATE: &str = "1,0,0,0.25,0,1,0,-0.5,0,0,1,2";

#[test]
fn a_translated_run_ends_where_the_untranslated_one_ends_translated() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("s.obj");
    balloon_mesh::io::write_obj(&mesh, &balloon_mesh::generate::icosphere(0.1, 2).unwrap())
        .unwrap();
    let shift = nalgebra::Vector3::new(0.25, -0.5, 2.0);
    let shell = ["inflate", mesh.to_str().unwrap(), "--steps", "4"];
    let volumetric = [
        "volumetric",
        mesh.to_str().unwrap(),
        "--resolution",
        "10",
        "--voxels-per-cell",
        "2",
        "--steps",
        "10",
        "--frame-every",
        "5",
        "--scene",
        "free",
    ];
    // The drop-sphere scene places its floor and sphere from the body's bounds, so it moves
    // along too, but its contacts and the loosely converged intermediate volume projections
    // (a stop at a tolerance, decided by rounding) amplify the rounding differences: measured
    // 1.0e-5 m after 10 steps, against 1e-12 m without contacts.
    let mut dropped = volumetric[..volumetric.len() - 2].to_vec();
    dropped.extend(["--scene", "drop-sphere"]);
    for (system, argv, tolerance) in [
        ("shell", &shell[..], 1e-9),
        ("volumetric", &volumetric[..], 1e-9),
        ("drop-sphere", &dropped[..], 1e-4),
    ] {
        let (_, plain) = run(dir.path(), &format!("{system}-plain"), argv);
        let mut moved_argv = argv.to_vec();
        moved_argv.extend(["--transform", TRANSLATE]);
        let (_, moved) = run(dir.path(), &format!("{system}-moved"), &moved_argv);
        assert_eq!(plain.triangles, moved.triangles);
        let worst = plain
            .vertices
            .iter()
            .zip(&moved.vertices)
            .map(|(a, b)| (b - (a + shift)).norm())
            .fold(0.0, f64::max);
        // OBJ coordinates are printed to about 1e-12 m and the dynamics round differently at
        // a distance of 2 m from the origin; the bodies are 0.2 m across.
        assert!(
            worst < tolerance,
            "{system}: moved by {shift:?} up to {worst:e} m off"
        );
    }
}

#[test]
fn a_rotation_about_z_keeps_the_inflated_volume() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("s.obj");
    balloon_mesh::io::write_obj(&mesh, &balloon_mesh::generate::icosphere(0.1, 2).unwrap())
        .unwrap();
    let q = 30f64.to_radians();
    let rotate = format!(
        "{:?},{:?},0,0,{:?},{:?},0,0,0,0,1,0",
        q.cos(),
        -q.sin(),
        q.sin(),
        q.cos()
    );
    let argv = ["inflate", mesh.to_str().unwrap(), "--steps", "4"];
    let (plain, plain_mesh) = run(dir.path(), "plain", &argv);
    let mut turned_argv = argv.to_vec();
    turned_argv.extend(["--transform", &rotate]);
    let (turned, turned_mesh) = run(dir.path(), "turned", &turned_argv);
    for key in ["initial_gas_volume", "final_gas_volume"] {
        let (a, b) = (plain[key].as_f64().unwrap(), turned[key].as_f64().unwrap());
        assert!((a - b).abs() < 1e-9 * a, "{key}: {a} vs {b} rotated");
    }
    assert!(
        turned["final_gas_volume"].as_f64().unwrap()
            > 1.01 * plain["initial_gas_volume"].as_f64().unwrap()
    );
    // And the inflated shape is the unrotated one turned by 30 degrees about z.
    let r = nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), q);
    let worst = plain_mesh
        .vertices
        .iter()
        .zip(&turned_mesh.vertices)
        .map(|(a, b)| (b - r * a).norm())
        .fold(0.0, f64::max);
    // Both runs converge to the Newton tolerance (1e-6 of the force scale), along paths whose
    // rounding differs (the single-precision factor of the CG preconditioner rounds the
    // rotated numbers differently): 1.4e-9 m measured on this 0.1 m sphere.
    assert!(worst < 1e-8, "turned shape off by {worst:e} m");
    let recorded = std::fs::read_to_string(dir.path().join("turned/scenario.toml")).unwrap();
    assert!(recorded.contains("transform = ["), "{recorded}");
}

#[test]
fn a_mirror_or_a_short_matrix_is_refused_by_name() {
    for (value, what) in [
        ("-1,0,0,0,0,1,0,0,0,0,1,0", "determinant"),
        ("1,0,0,0", "12 numbers"),
    ] {
        let o = run_balloon(&[
            "volumetric",
            "builtin:icosphere",
            "--resolution",
            "8",
            "--steps",
            "1",
            "--transform",
            value,
        ]);
        assert!(!o.status.success(), "{value}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("--transform") && err.contains(what),
            "{value}: {err}"
        );
    }
}

#[test]
fn a_scenario_transform_is_applied_and_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("v.toml");
    std::fs::write(
        &scenario,
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"builtin:icosphere\"\n\
         transform = [1, 0, 0, 0.25, 0, 1, 0, -0.5, 0, 0, 1, 2]\n\
         [lattice]\nresolution = 10\nvoxels_per_cell = 2\n[run]\nsteps = 2\n",
    )
    .unwrap();
    let out = dir.path().join("o");
    let o = run_balloon(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let recorded = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
    assert!(
        recorded.contains("transform = [1, 0, 0, 0.25, 0, 1, 0, -0.5, 0, 0, 1, 2]"),
        "{recorded}"
    );
    let soup = balloon_mesh::io::read_obj(&out.join("input_soup.obj")).unwrap();
    let z_min = soup
        .vertices
        .iter()
        .map(|p| p.z)
        .fold(f64::INFINITY, f64::min);
    assert!(
        (z_min - (2.0 - 0.1)).abs() < 1e-9,
        "lowest soup point {z_min}"
    );
}
