//! Reading scenario files (errors at their line and key) and the recorded scenario.

use super::*;
use crate::connect::ConnectScenario;
use crate::selection::{LoadKind, Selector};
use crate::shell::ShellScenario;
use balloon::shell::connected::Conductance;

/// The shell scenario of a file.
fn shell(path: &Path) -> Result<(ShellScenario, Literals), ScenarioError> {
    let f = read(path, &[])?;
    match f.scenario {
        Scenario::Shell(s) => Ok((s, f.literals)),
        other => panic!("not a shell scenario: {other:?}"),
    }
}

#[test]
fn the_recorded_scenario_of_the_defaults_reads_back_to_the_same_values() {
    let mut s = Scenario::new(SystemKind::Shell);
    s.set("dt", &Value::Float(0.005)).unwrap();
    s.set("ogden_mu", &Value::List(vec![Value::Int(1), Value::Int(2)]))
        .unwrap();
    let mut literals = Literals::default();
    literals.set("dt", vec![".005".into()]);
    literals.set("ogden_mu", vec!["1".into(), "2".into()]);
    let text = record(&s, &literals);
    assert!(text.contains("dt = 0.005\n"), "{text}");
    assert!(text.contains("steps = 300\n"), "{text}");
    assert!(text.contains("ogden_mu = [1, 2]\n"), "{text}");
    assert!(text.contains("# pump_rate = "), "{text}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(&path, &text).unwrap();
    let (back, back_literals) = shell(&path).unwrap();
    assert_eq!(back.run.dt, 0.005);
    assert_eq!(back.run.steps, 300);
    assert_eq!(back.shell.material.ogden_mu, Some(vec![1.0, 2.0]));
    assert_eq!(record(&Scenario::Shell(back), &back_literals), text);
}

#[test]
fn errors_name_the_line_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    let cases = [
        ("[run]\nsteps = 5\ndtt = 0.1\n", 3, "run.dtt", "unknown key"),
        ("[run]\n\ndt = \"fast\"\n", 3, "run.dt", "expected a number"),
        ("[run]\ndt = 2.0\n", 2, "run.dt", "(0, 1]"),
        (
            "[mesh]\nscale = 1\n[anchor]\nx = 1\n",
            3,
            "anchor",
            "unknown table",
        ),
        (
            "[mesh]\nscale = 1\n[anchors]\nx = 1\n",
            3,
            "anchors",
            "array of tables",
        ),
        (
            "[[anchors]]\nbelow = { axis = \"w\", value = 0 }\n",
            1,
            "anchors",
            "axis",
        ),
        (
            "[[anchors]]\nindices = [1]\nbox = [0, 0, 0, 1, 1, 1]\n",
            3,
            "anchors.box",
            "second selector",
        ),
        (
            "[[loads]]\ngravity = [0, 0]\n",
            2,
            "loads.gravity",
            "3 numbers",
        ),
        (
            "[shell]\nthickness_rule = { axis = \"z\", from = 1e-4 }\n",
            2,
            "shell.thickness_rule",
            "axis",
        ),
        (
            "[run]\nuntil_converged = 1\n",
            2,
            "run.until_converged",
            "boolean",
        ),
        (
            "[system]\nkind = \"bogus\"\n",
            2,
            "system.kind",
            "not a system",
        ),
    ];
    for (text, line, key, what) in cases {
        std::fs::write(&path, text).unwrap();
        let e = shell(&path).unwrap_err().to_string();
        let place = format!("s.toml:{line}: `{key}`");
        assert!(e.contains(&place) && e.contains(what), "{text:?}: {e}");
    }
    std::fs::write(&path, "[run\n").unwrap();
    let e = shell(&path).unwrap_err().to_string();
    assert!(e.contains("s.toml:1: not valid TOML"), "{e}");
    // A bad value of a parameter given elsewhere (a command-line override) is not the file's
    // error; its type still is.
    std::fs::write(&path, "[run]\ndt = -1\n").unwrap();
    assert!(read(&path, &["dt"]).is_ok());
    let e = shell(&path).unwrap_err().to_string();
    assert!(e.contains("s.toml:2: `run.dt`: invalid value '-1'"), "{e}");
    std::fs::write(&path, "[run]\ndt = \"x\"\n").unwrap();
    assert!(read(&path, &["dt"]).is_err());
}

#[test]
fn anchors_loads_and_thickness_keys_are_read_and_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[shell]\nthickness_file = \"wall.txt\"\npin_stiffness = 50\n\
         [[anchors]]\nvertices_file = \"neck.txt\"\n\
         [[anchors]]\nbelow = { axis = \"z\", value = 0.01 }\nstiffness = 200\n\
         [[anchors]]\nspec = \"box:0,0,0,1,1,1\"\n\
         [[loads]]\ngravity = [0, 0, -9.81]\n\
         [[loads]]\nforce = [0, 0.5, 0]\nper = \"total\"\nindices = [3, 4]\nstart = 0.1\nend = 0.2\n\
         [[loads]]\ngrab = [0, 0, 1]\nstiffness = 10\nabove = { axis = \"y\", value = 0.3 }\n",
    )
    .unwrap();
    let (a, literals) = shell(&path).unwrap();
    assert_eq!(a.shell.thickness_file, Some(dir.path().join("wall.txt")));
    assert_eq!(a.shell.pin_stiffness, Some(50.0));
    assert_eq!(a.anchors.len(), 3);
    assert_eq!(
        a.anchors[0].selector,
        Selector::File(dir.path().join("neck.txt"))
    );
    assert_eq!(a.anchors[1].stiffness, Some(200.0));
    assert_eq!(a.loads.len(), 3);
    assert_eq!(a.loads[0].kind, LoadKind::Gravity([0.0, 0.0, -9.81]));
    assert_eq!((a.loads[1].start, a.loads[1].end), (0.1, 0.2));
    assert!(matches!(
        a.loads[2].kind,
        LoadKind::Grab {
            stiffness: 10.0,
            ..
        }
    ));
    // The recorded scenario repeats them and reads back to the same values.
    let text = record(&Scenario::Shell(a.clone()), &literals);
    assert_eq!(text.matches("[[anchors]]").count(), 3, "{text}");
    assert_eq!(text.matches("[[loads]]").count(), 3, "{text}");
    let rec = dir.path().join("r.toml");
    std::fs::write(&rec, &text).unwrap();
    let (b, _) = shell(&rec).unwrap();
    assert_eq!(b.anchors, a.anchors);
    assert_eq!(b.loads, a.loads);
    assert_eq!(b.shell.thickness_file, a.shell.thickness_file);
    // A rule as a table.
    std::fs::write(
        &path,
        "[shell]\nthickness_rule = { axis = \"z\", from = 3e-4, to = 6e-4 }\n",
    )
    .unwrap();
    let (c, literals) = shell(&path).unwrap();
    let rule = c.shell.thickness_rule.unwrap();
    assert_eq!((rule.axis, rule.from, rule.to), (2, 3e-4, 6e-4));
    assert!(
        record(&Scenario::Shell(c), &literals).contains("thickness_rule = \"z:0.0003:0.0006\"")
    );
}

#[test]
fn connect_scenarios_read_their_table_and_record_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[mesh]\npath = \"builtin:icosphere\"\n[connect]\ncopies = 2\nstretches = [1.35, 1.6]\n\
         conductance = 2.5\ntubes = \"0-1\"\n[run]\ndt = 0.02\n",
    )
    .unwrap();
    let f = read(&path, &[]).unwrap();
    let Scenario::Connect(a) = &f.scenario else {
        panic!("a [connect] table selects the connected balloons")
    };
    assert_eq!(a.connect.copies, Some(2));
    assert_eq!(a.connect.stretches, Some(vec![1.35, 1.6]));
    assert_eq!(a.connect.conductance, Conductance::Finite(2.5));
    assert_eq!(a.shell.run.dt, 0.02);
    let text = record(&f.scenario, &f.literals);
    assert!(text.contains("kind = \"connect\""), "{text}");
    assert!(text.contains("conductance = 2.5\n"), "{text}");
    assert!(text.contains("\nmodel = \"ideal\"\n"), "{text}");
    let rec = dir.path().join("r.toml");
    std::fs::write(&rec, &text).unwrap();
    let mut back = read(&rec, &[]).unwrap().scenario;
    back.set("conductance", &Value::Text("instant".into()))
        .unwrap();
    let Scenario::Connect(b) = &back else {
        panic!("the record is a connect scenario")
    };
    assert_eq!(b.connect.stretches, a.connect.stretches);
    assert_eq!(b.connect.conductance, Conductance::Instant);
    // Keys of the table are checked like the others.
    std::fs::write(&path, "[connect]\nconductance = true\n").unwrap();
    let e = read(&path, &[]).unwrap_err().to_string();
    assert!(
        e.contains("s.toml:2: `connect.conductance`") && e.contains("a number or a string"),
        "{e}"
    );
    std::fs::write(&path, "[connect]\ncopies = 0\n").unwrap();
    let e = read(&path, &[]).unwrap_err().to_string();
    assert!(
        e.contains("`connect.copies`") && e.contains("from 1 to 1000"),
        "{e}"
    );
    assert!(ConnectScenario::default().validate().is_err());
}

#[test]
fn paths_are_relative_to_the_file_and_json_names_its_lines() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[mesh]\npath = \"m.obj\"\n[run]\ndt = 0.02\nsteps = 7\n",
    )
    .unwrap();
    let (a, _) = shell(&path).unwrap();
    assert_eq!(PathBuf::from(&a.mesh.path), dir.path().join("m.obj"));
    assert_eq!((a.run.dt, a.run.steps), (0.02, 7));
    let json = dir.path().join("v.json");
    std::fs::write(&json, "{\n  \"run\": {\n    \"steps\": -3\n  }\n}\n").unwrap();
    let e = read(&json, &[]).unwrap_err().to_string();
    assert!(e.contains("v.json:3: `run.steps`"), "{e}");
}

#[test]
fn a_connect_scenario_with_the_pump_records_the_ideal_gas_that_ran() {
    // Given as `model = 'pump'` (a literal string, which a text replacement of the record's
    // `"pump"` line would miss) or left at the shell's default: connected balloons hold the
    // ideal gas, and the record says so and reads back to that.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    for gas in [
        "[gas]\nmodel = 'pump'\n",
        "[gas]\nmodel =   \"pump\"  # given\n",
        "",
    ] {
        std::fs::write(
            &path,
            format!("[mesh]\npath = \"builtin:icosphere\"\n[connect]\ncopies = 2\n{gas}"),
        )
        .unwrap();
        let f = read(&path, &[]).unwrap();
        let text = record(&f.scenario, &f.literals);
        assert!(text.contains("\nmodel = \"ideal\"\n"), "{gas}: {text}");
        assert!(!text.contains("pump\""), "{gas}: {text}");
        let rec = dir.path().join("r.toml");
        std::fs::write(&rec, &text).unwrap();
        let Scenario::Connect(back) = read(&rec, &[]).unwrap().scenario else {
            panic!("the record is a connect scenario")
        };
        let Scenario::Connect(mut ran) = f.scenario else {
            panic!("a connect scenario")
        };
        ran.shell.gas.model = crate::gas::GasControl::Ideal;
        assert_eq!(back, ran, "{gas}");
    }
}
