//! `balloon mesh info` end-to-end tests.

use crate::{last_json_line, run_balloon, shared_meshes_dir};

fn info_json(spec: &str) -> serde_json::Value {
    let out = run_balloon(&["mesh", "info", spec, "--json"]);
    assert!(
        out.status.success(),
        "{spec}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    last_json_line(&out)
}

#[test]
fn builtin_meshes_report_counts_and_topology() {
    // An icosphere of level 4 has 10 * 4^4 + 2 vertices, genus 0; the torus has genus 1.
    let j = info_json("builtin:icosphere");
    assert_eq!(j["vertices"], 2562);
    assert_eq!(j["triangles"], 5120);
    assert_eq!(j["edges"], 7680);
    assert_eq!(j["genus"], 0);
    assert_eq!(j["closed"], true);
    assert_eq!(j["outward"], true);
    assert_eq!(j["defects"], 0);
    let v = j["enclosed_volume"].as_f64().unwrap();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.1f64.powi(3);
    assert!((v / exact - 1.0).abs() < 5e-3, "{v}");
    let j = info_json("builtin:torus");
    assert_eq!(j["genus"], 1);
    assert_eq!(j["euler_characteristic"], 0);
    // The default (teddy) is closed, manifold, outward, genus 0, about 0.3 m tall.
    let j = info_json("builtin");
    assert_eq!(j["closed"], true);
    assert_eq!(j["manifold"], true);
    assert_eq!(j["consistently_oriented"], true);
    assert_eq!(j["genus"], 0);
    assert_eq!(j["components"], 1);
    let h = j["bbox_max"][1].as_f64().unwrap() - j["bbox_min"][1].as_f64().unwrap();
    assert!((h - 0.3).abs() < 0.01, "{h}");
    assert!(j["min_angle_degrees"].as_f64().unwrap() > 10.0);
}

#[test]
fn human_output_lists_every_field() {
    let out = run_balloon(&["mesh", "info", "builtin:box"]);
    assert!(out.status.success());
    let s = String::from_utf8_lossy(&out.stdout);
    for key in [
        "vertices:",
        "triangles:",
        "edges:",
        "components:",
        "closed:",
        "manifold:",
        "outward:",
        "genus:",
        "surface area:",
        "enclosed volume:",
        "bounding box:",
        "minimum angle:",
    ] {
        assert!(s.contains(key), "missing {key} in\n{s}");
    }
}

#[test]
fn errors_exit_non_zero_with_file_and_line() {
    let out = run_balloon(&["mesh", "info", "/nonexistent/teddy.obj"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/teddy.obj"));
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let out = run_balloon(&["mesh", "info", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.obj") && err.contains("line 4"), "{err}");
    let out = run_balloon(&["mesh", "info", "builtin:teapot"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("teapot"));
}

#[test]
fn shared_meshes_agree_with_readme() {
    let Some(dir) = shared_meshes_dir() else {
        eprintln!("skipping: shared meshes folder not found");
        return;
    };
    // V, F and genus from the table in the folder's README.md.
    for (name, v, f, genus) in [
        ("spot.obj", 11533, 23062, 0),
        ("armadillo_lowres.obj", 14587, 29170, 0),
        ("bunny_closed_libigl.off", 3485, 6966, 0),
        ("torus.obj", 2304, 4608, 1),
    ] {
        let j = info_json(dir.join(name).to_str().unwrap());
        assert_eq!(j["vertices"], v, "{name}");
        assert_eq!(j["triangles"], f, "{name}");
        assert_eq!(j["genus"], genus, "{name}");
        assert_eq!(j["closed"], true, "{name}");
        assert_eq!(j["outward"], true, "{name}");
    }
}
