//! `balloon inflate --gas polytropic|leak|supply-pump`: the flags and their checks, short runs
//! that behave physically, and the pressure-volume plot of a static continuation.

use super::{last_json_line, run_balloon};

fn inflate(extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["inflate", "builtin:box", "--json", "--dt", "0.05"];
    args.extend_from_slice(extra);
    let out = run_balloon(&args);
    assert!(
        out.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    last_json_line(&out)
}

#[test]
fn bad_gas_law_flags_are_rejected_naming_the_flag() {
    let cases: &[(&[&str], &str)] = &[
        (&["--gas", "leak"], "--gas leak needs --leak-conductance"),
        (
            &["--gas", "supply-pump"],
            "--gas supply-pump needs --supply-pressure",
        ),
        (
            &["--gas", "pump", "--gamma", "1.2"],
            "--gamma 1.2 is a parameter of --gas polytropic",
        ),
        (
            &["--gas", "polytropic", "--gamma", "0"],
            "invalid --gamma 0",
        ),
        (
            &["--gas", "leak", "--leak-conductance", "-1"],
            "invalid --leak-conductance -1",
        ),
        (
            &["--gas", "supply-pump", "--supply-pressure", "-5"],
            "invalid --supply-pressure -5",
        ),
        (
            &["--gas", "ideal", "--supply-pressure", "500"],
            "--supply-pressure 500 is a parameter of --gas supply-pump",
        ),
    ];
    for (extra, want) in cases {
        let mut args = vec!["inflate", "builtin:box", "--steps", "1"];
        args.extend_from_slice(extra);
        let out = run_balloon(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        assert!(err.contains(want), "{extra:?}: `{want}` not in: {err}");
    }
}

#[test]
fn gas_laws_run_and_behave_physically() {
    let ambient = 101_325.0;
    let base = ["--pressure", "3000", "--steps", "5"];
    let ideal = inflate(&[&base[..], &["--gas", "ideal"]].concat());
    // Adiabatic expansion: p V^1.4 stays at its start value, and the gas ends below the
    // isothermal one.
    let adiabatic = inflate(&[&base[..], &["--gas", "polytropic", "--gamma", "1.4"]].concat());
    let v0 = adiabatic["initial_gas_volume"].as_f64().unwrap();
    let v = adiabatic["final_gas_volume"].as_f64().unwrap();
    let p = adiabatic["final_gauge_pressure"].as_f64().unwrap() + ambient;
    let invariant = p * (v / v0).powf(1.4) / (3000.0 + ambient);
    assert!(
        (invariant - 1.0).abs() < 1e-9,
        "p V^gamma / p0 V0^gamma = {invariant}"
    );
    assert!(v > v0);
    assert!(p - ambient < ideal["final_gauge_pressure"].as_f64().unwrap());
    // A leak loses gas: less volume and pressure than the tight balloon.
    let leak = inflate(&[&base[..], &["--gas", "leak", "--leak-conductance", "0.01"]].concat());
    for key in ["final_gauge_pressure", "final_gas_volume"] {
        let (l, i) = (leak[key].as_f64().unwrap(), ideal[key].as_f64().unwrap());
        assert!(l < i, "{key}: leak {l} vs tight {i}");
    }
    // The supply pump stops at its supply pressure.
    let pump = inflate(&[
        "--gas",
        "supply-pump",
        "--supply-pressure",
        "500",
        "--pump-rate",
        "0.01",
        "--steps",
        "10",
    ]);
    let g = pump["final_gauge_pressure"].as_f64().unwrap();
    assert!((g - 500.0).abs() < 1e-6, "final gauge {g}");
}

#[test]
fn volume_continuation_writes_the_pressure_volume_plot() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("pv");
    let out = run_balloon(&[
        "inflate",
        "builtin:box",
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
        "1:1.6:0.2",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let png = std::fs::read(out_dir.join("pressure_volume.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 4);
    // A single point draws no curve.
    let single = dir.path().join("one");
    let out = run_balloon(&[
        "inflate",
        "builtin:box",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--thickness",
        "1e-3",
        "--static",
        "--gas",
        "volume",
        "--volume-ratio",
        "1.2",
        "--out",
        single.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!single.join("pressure_volume.png").exists());
}

/// `--static` with the default gas (the pump, whose amount at the start is the rest amount)
/// would "solve" to the mesh itself and exit 0: it is refused, naming what to give instead,
/// and the same static solve with a gauge pressure inflates the shell.
#[test]
fn a_static_solve_with_the_pump_is_refused_with_what_to_give() {
    for gas in [None, Some("supply-pump")] {
        let mut args = vec!["inflate", "builtin:sphere", "--static"];
        if let Some(g) = gas {
            args.extend(["--gas", g, "--supply-pressure", "500"]);
        }
        let out = run_balloon(&args);
        assert!(
            !out.status.success(),
            "{gas:?}: a no-op static solve exited 0"
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("rest amount") && err.contains("--gas constant --pressure"),
            "{gas:?}: {err}"
        );
    }
    let out = run_balloon(&[
        "inflate",
        "builtin:sphere",
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "500",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = last_json_line(&out);
    assert!(
        s["final_gas_volume"].as_f64().unwrap() > 1.01 * s["initial_gas_volume"].as_f64().unwrap()
    );
}
