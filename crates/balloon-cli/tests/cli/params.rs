//! Every numeric flag outside its documented range is refused up front: non-zero exit, a
//! message naming the flag and the text the user typed, and nothing written (the `--out` folder
//! is never created, and the mesh, a path that does not exist, is never read).

use super::run_balloon;

/// `(subcommand and flags, the flag the message must name, the value it must show)`.
const CASES: &[(&[&str], &str, &str)] = &[
    // inflate: the list.
    (&["inflate", "--cg-max-iters", "0"], "--cg-max-iters", "0"),
    (&["inflate", "--cg-tol", "nan"], "--cg-tol", "nan"),
    (&["inflate", "--cg-tol=-1"], "--cg-tol", "-1"),
    (&["inflate", "--cg-tol", "0"], "--cg-tol", "0"),
    (&["inflate", "--cg-tol", "1"], "--cg-tol", "1"),
    (&["inflate", "--cg-tol", "1e308"], "--cg-tol", "1e308"),
    (&["inflate", "--speed-tol", "nan"], "--speed-tol", "nan"),
    (
        &["inflate", "--speed-tol", "inf", "--volume-tol", "inf"],
        "-tol",
        "inf",
    ),
    (&["inflate", "--volume-tol", "1"], "--volume-tol", "1"),
    (&["inflate", "--ambient", "1e308"], "--ambient", "1e308"),
    (&["inflate", "--dt", "1e308"], "--dt", "1e308"),
    (&["inflate", "--pump-rate=-1"], "--pump-rate", "-1"),
    (
        &["inflate", "--newton-iters", "4294967296"],
        "--newton-iters",
        "4294967296",
    ),
    // inflate: the other numeric flags.
    (&["inflate", "--density", "1e308"], "--density", "1e308"),
    (&["inflate", "--thickness=-3e-4"], "--thickness", "-3e-4"),
    (&["inflate", "--bending=-1"], "--bending", "-1"),
    (&["inflate", "--bending", "nan"], "--bending", "nan"),
    (&["inflate", "--bending", "1e7"], "--bending", "1e7"),
    (&["inflate", "--pressure", "1e308"], "--pressure", "1e308"),
    (
        &["inflate", "--mass-damping", "nan"],
        "--mass-damping",
        "nan",
    ),
    (
        &["inflate", "--stiffness-damping=-1"],
        "--stiffness-damping",
        "-1",
    ),
    (&["inflate", "--scale", "inf"], "--scale", "inf"),
    (&["inflate", "--steps=-1"], "--steps", "-1"),
    (&["inflate", "--steps", "1e3"], "--steps", "1e3"),
    (&["inflate", "--frame-every", "2.5"], "--frame-every", "2.5"),
    (&["inflate", "--volume-ratio", "0"], "--volume-ratio", "0"),
    (&["inflate", "--newton-tol", "inf"], "--newton-tol", "inf"),
    // inflate: material parameters (their sign and model checks come after, still up front).
    (&["inflate", "--young", "1e308"], "--young", "1e308"),
    (&["inflate", "--poisson", "nan"], "--poisson", "nan"),
    (
        &[
            "inflate",
            "--material",
            "membrane-neo-hookean",
            "--mu",
            "inf",
        ],
        "--mu",
        "inf",
    ),
    (
        &[
            "inflate",
            "--material",
            "membrane-gent",
            "--mu",
            "4e5",
            "--jm",
            "1e300",
        ],
        "--jm",
        "1e300",
    ),
    (
        &[
            "inflate",
            "--material",
            "membrane-yeoh",
            "--yeoh",
            "1e5,1e308",
        ],
        "--yeoh",
        "1e308",
    ),
    // volumetric.
    (
        &["volumetric", "--resolution", "400"],
        "--resolution",
        "400",
    ),
    (
        &["volumetric", "--voxels-per-cell", "0"],
        "--voxels-per-cell",
        "0",
    ),
    (&["volumetric", "--rays", "27"], "--rays", "27"),
    (
        &["volumetric", "--band-voxels", "1e308"],
        "--band-voxels",
        "1e308",
    ),
    (&["volumetric", "--p-in", "nan"], "--p-in", "nan"),
    (&["volumetric", "--p-subs", "1"], "--p-subs", "1"),
    (
        &["volumetric", "--density-threshold", "1"],
        "--density-threshold",
        "1",
    ),
    (
        &["volumetric", "--smoothing-weight", "0.6"],
        "--smoothing-weight",
        "0.6",
    ),
    (&["volumetric", "--dt", "1e308"], "--dt", "1e308"),
    (&["volumetric", "--tolerance", "0"], "--tolerance", "0"),
    (
        &["volumetric", "--over-relaxation", "2"],
        "--over-relaxation",
        "2",
    ),
    (&["volumetric", "--gravity", "1e308"], "--gravity", "1e308"),
    (&["volumetric", "--density", "0"], "--density", "0"),
    (
        &["volumetric", "--restitution", "1.5"],
        "--restitution",
        "1.5",
    ),
    (
        &["volumetric", "--edge-stiffness=-1"],
        "--edge-stiffness",
        "-1",
    ),
    (&["volumetric", "--damping", "inf"], "--damping", "inf"),
    (&["volumetric", "--frame-every", "0"], "--frame-every", "0"),
    (&["volumetric", "--scale", "0"], "--scale", "0"),
    // two-layer (its mesh is built in: the range check must still come first).
    (&["two-layer", "--dt", "1e308"], "--dt", "1e308"),
    (&["two-layer", "--level", "8"], "--level", "8"),
    (&["two-layer", "--particles", "2"], "--particles", "2"),
    (&["two-layer", "--slices", "2"], "--slices", "2"),
    (&["two-layer", "--pressure=-1"], "--pressure", "-1"),
    (&["two-layer", "--gravity", "nan"], "--gravity", "nan"),
    (&["two-layer", "--box", "inf"], "--box", "inf"),
    (
        &["two-layer", "--k-structural", "1e308"],
        "--k-structural",
        "1e308",
    ),
    (
        &["two-layer", "--restitution=-0.1"],
        "--restitution",
        "-0.1",
    ),
    (
        &["two-layer", "--drag-stiffness=-1"],
        "--drag-stiffness",
        "-1",
    ),
    (&["two-layer", "--inner-mass", "0"], "--inner-mass", "0"),
    (&["two-layer", "--steps", "1e3"], "--steps", "1e3"),
    // view.
    (&["view", "shell", "--exit-after=-1"], "--exit-after", "-1"),
    (
        &["view", "shell", "--exit-after", "nan"],
        "--exit-after",
        "nan",
    ),
    (&["view", "shell", "--port", "70000"], "--port", "70000"),
];

#[test]
fn every_out_of_range_value_is_refused_naming_flag_and_value_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let missing_mesh = dir.path().join("no-such-mesh.obj");
    let missing_mesh = missing_mesh.to_str().unwrap();
    for (i, (args, flag, value)) in CASES.iter().enumerate() {
        let out_dir = dir.path().join(format!("run{i}"));
        let mut a: Vec<&str> = args.to_vec();
        if matches!(args[0], "inflate" | "volumetric") {
            a.insert(1, missing_mesh);
        }
        if args[0] != "view" {
            a.extend(["--out", out_dir.to_str().unwrap()]);
        }
        let out = run_balloon(&a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{a:?} was accepted");
        assert!(
            err.contains(flag) && err.contains(&format!("'{value}'")),
            "{a:?}: the message must name {flag} and '{value}': {err}"
        );
        assert!(
            !err.contains("no-such-mesh"),
            "{a:?}: the mesh was read before the check: {err}"
        );
        assert!(!err.contains("panicked"), "{a:?}: {err}");
        assert!(!out_dir.exists(), "{a:?} wrote {}", out_dir.display());
    }
}

#[test]
fn help_states_the_ranges() {
    let out = run_balloon(&["inflate", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "in (0, 1]",
        "in (0, 1)",
        "1 to 1e6",
        "in [0, 1e7]",
        "in [0, 100]",
    ] {
        assert!(help.contains(needle), "`{needle}` not in inflate --help");
    }
    let out = run_balloon(&["volumetric", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("4 to 200"), "volumetric --help: {help}");
}

/// A load too small to move the shell beyond round-off: every step "succeeds" but the shell
/// never moves, which is reported as an error (with the records written), not exit 0.
#[test]
fn a_run_that_never_moves_the_shell_under_a_load_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("run");
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--gas",
        "constant",
        "--pressure",
        "1e-300",
        "--steps",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a run that did nothing exited 0");
    assert!(err.contains("no progress"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert!(s["error"].as_str().unwrap().contains("no progress"), "{s}");
    assert_eq!(super::last_json_line(&out)["error"], s["error"]);
    // Without a load, a shell at rest is the right answer.
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--gas",
        "pump",
        "--pump-rate",
        "0",
        "--steps",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
