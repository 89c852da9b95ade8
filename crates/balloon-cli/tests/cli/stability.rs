//! `--stability` (issue 30, item 6): the smallest eigenvalue of each static equilibrium's
//! stiffness in `stats.jsonl`, refused without `--static`.

use crate::run_balloon;

/// A neo-Hookean membrane sphere traced under volume control across its pressure maximum
/// (`l = 7^(1/6)`, V/V0 = 2.65) stays stable (the volume is held; neo-Hookean has no
/// aspherical bifurcation): every point reports a positive smallest eigenvalue, checked on
/// the operator, and the summary lists no unstable point and no warning.
#[test]
fn stability_reports_the_smallest_eigenvalue_of_each_point() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("st");
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--thickness",
        "1e-3",
        "--static",
        "--gas",
        "volume",
        "--volume-ratios",
        "1.5:3.5:1",
        "--stability",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        summary["unstable_points"],
        serde_json::json!([]),
        "{summary}"
    );
    assert!(summary.get("warnings").is_none(), "{summary}");
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 3);
    for line in stats.lines() {
        let p: serde_json::Value = serde_json::from_str(line).unwrap();
        let s = &p["stability"];
        let lambda = s["smallest_eigenvalue"].as_f64().unwrap();
        assert!(lambda > 0.0, "{p}");
        assert!(s["residual"].as_f64().unwrap() < 1e-6, "{p}");
    }
    // Without the flag no point carries the report.
    let plain = dir.path().join("plain");
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--static",
        "--gas",
        "volume",
        "--volume-ratio",
        "1.5",
        "--out",
        plain.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stats = std::fs::read_to_string(plain.join("stats.jsonl")).unwrap();
    assert!(!stats.contains("stability"), "{stats}");
}

#[test]
fn stability_without_a_static_solve_is_refused() {
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--stability",
        "--steps",
        "1",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--stability") && err.contains("--static"),
        "{err}"
    );
}
