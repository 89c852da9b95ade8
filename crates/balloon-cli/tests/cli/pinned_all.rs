//! Runs that cannot do anything are refused, and failures say only what happened: hard pins on
//! every particle of a volumetric or two-layer body are refused naming the selections (as the
//! shell's are), and a static solve that fails before its first point prints no
//! "0 point(s)" result line and counts the Newton iterations it spent.

use super::run_balloon;

/// stderr of a run that must fail without a panic.
fn refused(args: &[&str]) -> String {
    let out = run_balloon(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    err
}

#[test]
fn hard_pins_on_every_particle_are_refused_naming_the_selections() {
    for (system, what) in [
        ("volumetric", "particles of the lattice"),
        ("two-layer", "particles of the body"),
    ] {
        // Two selections that together cover everything: each alone would leave some free.
        let err = refused(&[
            system,
            "--pin",
            "below:z:0.0",
            "--pin",
            "above:z:-1e-9",
            "--steps",
            "2",
        ]);
        assert!(
            err.contains("--pin holds all")
                && err.contains(what)
                && err.contains("`below:z:0.0`")
                && err.contains("`above:z:-1e-9`")
                && err.contains("nothing can move"),
            "{system}: {err}"
        );
        // Springs may hold every particle: the body still moves.
        let out = run_balloon(&[system, "--pin", "below:z:100@100", "--steps", "2"]);
        assert!(
            out.status.success(),
            "{system}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        // One pin short of all is a run.
        let out = run_balloon(&[system, "--pin", "below:z:0.0", "--steps", "2"]);
        assert!(
            out.status.success(),
            "{system}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn a_static_solve_that_fails_before_its_first_point_says_so_and_what_it_spent() {
    // Above the membrane's limit pressure (see `hostile.rs`): no equilibrium, the first point
    // fails after many iterations. No "0 point(s)" result line is printed, and the summary
    // counts what the failed point spent (it used to report `newton_iterations_total: 0`:
    // only converged points counted).
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("ico2.obj");
    balloon::mesh::io::write_obj(&mesh, &balloon::mesh::generate::icosphere(0.1, 2).unwrap())
        .unwrap();
    let run = dir.path().join("run");
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "1e5",
        "--out",
        run.to_str().unwrap(),
    ]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!out.status.success(), "{stdout}");
    assert!(stderr.contains("did not converge"), "{stderr}");
    assert!(!stdout.contains("point(s)"), "{stdout}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["points"], 0, "{summary}");
    // The load path ends where no increment converged any more (whatever stopped the last
    // one: here a matrix no shift made definite), and the error says where.
    let error = summary["error"].as_str().unwrap();
    assert!(
        error.contains("did not converge") && error.contains("at load factor"),
        "{error}"
    );
    // The first outer iteration failed, so the total is that solve's count.
    let spent: u64 = error
        .split("after ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no iteration count in {error}"));
    assert!(spent > 0, "{error}");
    assert_eq!(summary["newton_iterations_total"], spent, "{summary}");
    // The residual it ended at (above the tolerance) and the time it took, not 0.
    assert!(
        summary["newton_residual"].as_f64().unwrap() > 1e-3,
        "{summary}"
    );
    assert!(summary["solve_ms"].as_f64().unwrap() > 0.0, "{summary}");
}
