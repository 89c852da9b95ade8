//! `balloon design`: the files it writes, its summary, and its errors.

use crate::run_balloon;

#[test]
fn design_writes_rest_shape_check_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("design");
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--pressure",
        "4000",
        "--thickness",
        "1e-3",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], true);
    assert_eq!(summary["check"]["converged"], true);
    assert!(
        summary["check"]["distance"]["max_relative"]
            .as_f64()
            .unwrap()
            < 1e-4
    );
    // The rest shape encloses less than the target (the gas stretched it).
    assert!(summary["rest_volume"].as_f64().unwrap() < summary["target_volume"].as_f64().unwrap());
    let rest = balloon_mesh::io::read_obj(&out.join("rest.obj")).unwrap();
    let inflated = balloon_mesh::io::read_obj(&out.join("inflated.obj")).unwrap();
    assert_eq!(rest.num_vertices(), 2562);
    assert_eq!(inflated.num_triangles(), rest.num_triangles());
    let csv = std::fs::read_to_string(out.join("distance.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2563);
}

#[test]
fn design_errors_name_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--pressure",
        "-5",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--pressure"));
    let o = run_balloon(&[
        "design",
        "no-such-file.obj",
        "--pressure",
        "100",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no-such-file.obj"));
}
