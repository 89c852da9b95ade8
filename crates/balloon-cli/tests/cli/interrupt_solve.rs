//! A signal stops a solve in progress within one Newton iteration: a static solve asked for a
//! tolerance it cannot reach runs for minutes (about 190 s for this one with a release build)
//! before it gives up; SIGTERM ends it at once with its records and status 143.

use super::records::{read_json, signal_and_wait, spawn, wait_for};
use std::time::{Duration, Instant};

#[test]
fn sigterm_stops_a_stalling_static_solve_within_a_newton_iteration() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut child = spawn(&[
        "inflate",
        "builtin:teddy",
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "1500",
        "--newton-tol",
        "1e-15",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    // The rest frame is written before the solve starts; give the solve a moment to be under
    // way.
    wait_for(&mut child, &run.join("frame_00000.obj"));
    std::thread::sleep(Duration::from_millis(500));
    let sent = Instant::now();
    // `signal_and_wait` allows 60 s; the solve alone would take minutes.
    let out = signal_and_wait(&mut child, "TERM");
    let waited = sent.elapsed();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "after {waited:?}: {err}");
    assert!(err.contains("interrupted"), "{err}");
    let s = read_json(&run.join("summary.json"));
    assert_eq!(s["interrupted"], true, "{s}");
    assert!(s["error"].is_null(), "{s}");
    assert_eq!(s["points"], 0, "{s}");
}

/// Ctrl-C keeps the best design so far, checks it with a forward solve that runs to its end
/// (not one stopped by the same signal at its first iteration) and writes it: the Teddy as the
/// target with the paper's wall is a design whose inverse solve creeps for minutes.
#[test]
fn sigint_keeps_the_best_design_and_checks_it() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("design");
    let mut child = spawn(&[
        "design",
        "builtin:teddy",
        "--pressure",
        "2000",
        "--material",
        "neo-hookean",
        "--young",
        "1e6",
        "--poisson",
        "0.45",
        "--thickness",
        "1e-3",
        "--quiet",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    std::thread::sleep(Duration::from_secs(3));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the design ended before the signal"
    );
    let out = signal_and_wait(&mut child, "INT");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    let s = read_json(&out_dir.join("summary.json"));
    assert_eq!(s["interrupted"], true, "{s}");
    assert_eq!(s["inverse"]["converged"], false, "{s}");
    let check = &s["check"];
    assert_eq!(check["converged"], true, "{check}");
    assert!(check["iterations"].as_u64().unwrap() > 0, "{check}");
    assert!(out_dir.join("rest.obj").exists());
    assert!(out_dir.join("inflated.obj").exists());
}
