//! `balloon inflate --material membrane-*`: the flags, their checks, the summary, and short
//! inflations of the built-in teddy with every membrane model.

use super::{last_json_line, run_balloon};

/// Every bad combination of material flags fails before any work, and the message names the
/// flag (and its value where there is one).
#[test]
fn bad_membrane_flags_are_rejected_naming_the_flag() {
    let cases: &[(&[&str], &[&str])] = &[
        // Gent needs jm > 0.
        (
            &["--material", "membrane-gent", "--mu", "4e5", "--jm", "0"],
            &["--jm 0", "jm"],
        ),
        (
            &["--material", "membrane-gent", "--mu", "4e5", "--jm", "-5"],
            &["--jm -5"],
        ),
        (
            &["--material", "membrane-gent", "--mu", "4e5"],
            &["membrane-gent needs --jm"],
        ),
        // Ogden: matching list lengths, a positive initial shear modulus, non-zero exponents.
        (
            &[
                "--material",
                "membrane-ogden",
                "--ogden-mu",
                "6e5,1e3,-1e4",
                "--ogden-alpha",
                "1.3,5",
            ],
            &[
                "--ogden-mu 600000,1000,-10000",
                "--ogden-alpha 1.3,5",
                "3 mu and 2 alpha",
            ],
        ),
        (
            &[
                "--material",
                "membrane-ogden",
                "--ogden-mu",
                "-1e5,1e3",
                "--ogden-alpha",
                "2,1",
            ],
            &["initial_shear_modulus", "--ogden-mu -100000,1000"],
        ),
        (
            &[
                "--material",
                "membrane-ogden",
                "--ogden-mu",
                "1e5",
                "--ogden-alpha",
                "0",
            ],
            &["--ogden-alpha 0"],
        ),
        (
            &["--material", "membrane-ogden", "--ogden-mu", "1e5"],
            &["needs --ogden-mu and --ogden-alpha"],
        ),
        // The other models' own ranges.
        (
            &["--material", "membrane-neo-hookean", "--mu", "-1"],
            &["--mu -1"],
        ),
        (
            &["--material", "membrane-neo-hookean"],
            &["membrane-neo-hookean needs --mu"],
        ),
        (
            &[
                "--material",
                "membrane-mooney-rivlin",
                "--c1",
                "1e5",
                "--c2",
                "-1",
            ],
            &["--c2 -1"],
        ),
        (
            &["--material", "membrane-yeoh", "--yeoh", "0,1e3"],
            &["--yeoh 0,1000", "c1"],
        ),
        (
            &["--material", "membrane-yeoh", "--yeoh", "1,2,3,4"],
            &["--yeoh 1,2,3,4", "1 to 3"],
        ),
        // A membrane flag with a 3D material is an error, not ignored.
        (
            &["--material", "stvk", "--mu", "4e5"],
            &["--mu 400000", "st-venant-kirchhoff"],
        ),
        (&["--jm", "30"], &["--jm 30", "membrane parameter"]),
        (
            &["--material", "neo-hookean", "--yeoh", "1e5"],
            &["--yeoh 100000", "neo-hookean"],
        ),
        // A flag the chosen membrane does not take, and the 3D flags with a membrane.
        (
            &[
                "--material",
                "membrane-neo-hookean",
                "--mu",
                "4e5",
                "--jm",
                "30",
            ],
            &["--jm 30", "not a parameter of membrane-neo-hookean"],
        ),
        (
            &[
                "--material",
                "membrane-neo-hookean",
                "--mu",
                "4e5",
                "--young",
                "2e6",
            ],
            &["--young 2000000"],
        ),
        // Presets: no parameter flags with them, and a matching --material.
        (
            &["--material-preset", "natural-rubber", "--mu", "3e5"],
            &["--mu 300000", "--material-preset natural-rubber"],
        ),
        (
            &[
                "--material-preset",
                "natural-rubber",
                "--material",
                "membrane-yeoh",
            ],
            &["natural-rubber", "membrane-yeoh"],
        ),
        (
            &["--material-preset", "elastosil-m4601", "--material", "stvk"],
            &["elastosil-m4601", "st-venant-kirchhoff"],
        ),
        (
            &["--material-preset", "ecoflex"],
            &["ecoflex", "natural-rubber"],
        ),
        (&["--material", "rubber"], &["rubber", "membrane-gent"]),
        (
            &["--material", "membrane-ogden", "--ogden-mu", "a,b"],
            &["--ogden-mu", "'a'"],
        ),
    ];
    for (flags, words) in cases {
        // A mesh that does not exist: the flags must be rejected before it is looked at.
        let mut args = vec!["inflate", "no-such-mesh.obj", "--steps", "1"];
        args.extend_from_slice(flags);
        let out = run_balloon(&args);
        assert!(!out.status.success(), "{flags:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !err.contains("no-such-mesh"),
            "{flags:?}: checked the mesh before the flags: {err}"
        );
        for w in *words {
            assert!(err.contains(w), "{flags:?}: `{w}` not in: {err}");
        }
    }
}

/// A short inflation (one pump step) of the built-in teddy (7996 vertices) with every membrane model and both
/// presets runs, the gas volume grows, the summary records the model with its parameters, the
/// incompressible thickness thins and the shell volume is kept without a projection.
#[test]
fn teddy_inflates_with_every_membrane_model() {
    let runs: &[(&[&str], &str, &str)] = &[
        (
            &["--material", "membrane-neo-hookean", "--mu", "4e5"],
            "membrane-neo-hookean",
            "mu",
        ),
        (
            &[
                "--material",
                "membrane-mooney-rivlin",
                "--c1",
                "1.8e5",
                "--c2",
                "2e4",
            ],
            "membrane-mooney-rivlin",
            "c2",
        ),
        (
            &["--material", "membrane-gent", "--mu", "4e5", "--jm", "30"],
            "membrane-gent",
            "jm",
        ),
        (
            &[
                "--material",
                "membrane-ogden",
                "--ogden-mu",
                "6.3e5,1.2e3,-1e4",
                "--ogden-alpha",
                "1.3,5,-2",
            ],
            "membrane-ogden",
            "alpha",
        ),
        (
            &["--material", "membrane-yeoh", "--yeoh", "1.1e5,2e4"],
            "membrane-yeoh",
            "c3",
        ),
        (
            &["--material-preset", "natural-rubber"],
            "membrane-ogden",
            "alpha",
        ),
        (
            &["--material-preset", "elastosil-m4601"],
            "membrane-yeoh",
            "c1",
        ),
    ];
    for (flags, model, key) in runs {
        let mut args = vec!["inflate", "builtin", "--steps", "1", "--json"];
        args.extend_from_slice(flags);
        let out = run_balloon(&args);
        assert!(
            out.status.success(),
            "{flags:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let s = last_json_line(&out);
        assert_eq!(s["vertices"], 7996);
        assert_eq!(s["steps"], 1);
        assert_eq!(s["material"], *model, "{s}");
        assert_eq!(s["material_parameters"]["model"], *model, "{s}");
        assert!(
            s["material_parameters"].get(*key).is_some(),
            "{flags:?}: no `{key}` in {s}"
        );
        let (v0, v1) = (
            s["initial_gas_volume"].as_f64().unwrap(),
            s["final_gas_volume"].as_f64().unwrap(),
        );
        assert!(v1 > v0, "{flags:?}: gas volume {v0} -> {v1}");
        assert!(s["final_thickness_min"].as_f64().unwrap() < 3.0e-4);
        assert!(s["shell_volume_ratio_max_deviation"].as_f64().unwrap() < 1e-12);
    }
}

/// The 3D materials keep their defaults and their summary gains the parameters.
#[test]
fn solid_material_summary_records_its_parameters() {
    let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.obj");
    balloon_mesh::io::write_obj(&path, &mesh).unwrap();
    let out = run_balloon(&[
        "inflate",
        path.to_str().unwrap(),
        "--material",
        "neo-hookean",
        "--young",
        "2e6",
        "--steps",
        "1",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert_eq!(s["material"], "neo-hookean");
    assert_eq!(s["material_parameters"]["model"], "neo-hookean");
    // E = 2 MPa, nu = 0.45: mu = E / (2 (1 + nu)).
    let mu = s["material_parameters"]["mu"].as_f64().unwrap();
    assert!((mu - 2e6 / 2.9).abs() < 1e-6 * mu, "{s}");
}
