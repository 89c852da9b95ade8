//! A scenario file with the flags after it.

use super::*;
use crate::scenario_cli::arg_id;
use balloon::shell::connected::Conductance;
use balloon_scenario::keys::Kind;
use balloon_scenario::names::flag_of;
use balloon_scenario::selection::Selector;
use balloon_scenario::shell::ShellScenario;

fn shell(path: &Path, flags: &[&str]) -> Result<ShellScenario> {
    let flags: Vec<String> = flags.iter().map(|f| (*f).to_owned()).collect();
    match scenario_of(path, &flags)?.scenario {
        Scenario::Shell(s) => Ok(s),
        other => panic!("not a shell scenario: {other:?}"),
    }
}

#[test]
fn an_invalid_override_names_the_flag_not_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(&path, "[run]\ndt = 0.02\nsteps = 7\n").unwrap();
    for (flags, named) in [
        (vec!["--dt", "-1"], "'--dt <DT>'"),
        (vec!["--dt=nan"], "'--dt <DT>'"),
        (vec!["--steps", "x"], "'--steps <STEPS>'"),
        (vec!["--bogus"], "'--bogus'"),
    ] {
        let text = crate::scenario_cli::error_chain(&shell(&path, &flags).unwrap_err());
        assert!(
            text.contains(named) && text.starts_with("command line") && !text.contains("s.toml"),
            "{flags:?}: {text}"
        );
    }
    // A bad value in the file still names the file, its line and key.
    std::fs::write(&path, "[run]\ndt = -1\n").unwrap();
    let e = crate::scenario_cli::error_chain(&shell(&path, &[]).unwrap_err());
    assert!(e.contains("s.toml:2: `run.dt`"), "{e}");
    // ... unless a flag replaces it.
    assert_eq!(shell(&path, &["--dt", "0.5"]).unwrap().run.dt, 0.5);
}

#[test]
fn flags_override_the_file_and_paths_are_relative_to_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[mesh]\npath = \"m.obj\"\n[run]\ndt = 0.02\nsteps = 7\n",
    )
    .unwrap();
    let a = shell(&path, &["--dt", "0.005"]).unwrap();
    assert_eq!(a.run.dt, 0.005);
    assert_eq!(a.run.steps, 7);
    assert_eq!(PathBuf::from(&a.mesh.path), dir.path().join("m.obj"));
    let a = shell(&path, &["--steps=9"]).unwrap();
    assert_eq!((a.run.dt, a.run.steps), (0.02, 9));
    // The mesh on the command line replaces the file's.
    let a = shell(&path, &["builtin:sphere"]).unwrap();
    assert_eq!(a.mesh.path, "builtin:sphere");
}

#[test]
fn a_pin_on_the_command_line_replaces_the_file_s_anchors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[shell]\nthickness_rule = { axis = \"z\", from = 3e-4, to = 6e-4 }\n[[anchors]]\nindices = [1]\n",
    )
    .unwrap();
    let c = shell(&path, &["--pin", "indices:7"]).unwrap();
    assert_eq!(c.anchors.len(), 1);
    assert_eq!(c.anchors[0].selector, Selector::Indices(vec![7]));
    let rule = c.shell.thickness_rule.unwrap();
    assert_eq!((rule.axis, rule.from, rule.to), (2, 3e-4, 6e-4));
    // The record repeats the flag's value as typed.
    let call = scenario_of(&path, &["--dt".into(), "5e-3".into()]).unwrap();
    assert!(
        call.record().contains("\ndt = 0.005\n"),
        "{}",
        call.record()
    );
}

#[test]
fn connect_overrides_and_another_system_s_flags() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[mesh]\npath = \"builtin:icosphere\"\n[connect]\ncopies = 2\nstretches = [1.35, 1.6]\n\
         conductance = 2.5\n",
    )
    .unwrap();
    let call = scenario_of(&path, &["--conductance".into(), "instant".into()]).unwrap();
    let Scenario::Connect(c) = &call.scenario else {
        panic!("a connect scenario")
    };
    assert_eq!(c.connect.conductance, Conductance::Instant);
    assert!(call.record().contains("conductance = \"instant\""));
    // A volumetric flag is not a connect flag.
    let e = crate::scenario_cli::error_chain(
        &scenario_of(&path, &["--cells".into(), "9".into()]).unwrap_err(),
    );
    assert!(
        e.starts_with("command line") && e.contains("--cells"),
        "{e}"
    );
}

/// Every key of each system is one flag of its command (or the positional mesh), and every
/// flag is one key: the command line, the scenario files and Python name the same
/// parameters.
#[test]
fn every_flag_of_each_system_has_exactly_one_key_of_the_right_kind() {
    for (kind, cmd) in commands() {
        let keys = Scenario::keys(kind);
        for arg in cmd.get_arguments() {
            let id = arg.get_id().as_str();
            if id == "help" || id == "version" {
                continue;
            }
            let matching: Vec<_> = keys.iter().filter(|k| arg_id(k.name) == id).collect();
            assert_eq!(
                matching.len(),
                1,
                "{kind}: argument `{id}` has {} keys",
                matching.len()
            );
            let key = matching[0];
            let is_flag = matches!(arg.get_action(), clap::ArgAction::SetTrue);
            assert_eq!(
                key.kind == Kind::Bool,
                is_flag,
                "{kind}: `{id}`: {:?}",
                key.kind
            );
            if key.name != "mesh" {
                assert_eq!(
                    arg.get_long(),
                    flag_of(key.name),
                    "{kind}: `{}` is set by --{:?}",
                    key.name,
                    arg.get_long()
                );
            }
        }
        for key in &keys {
            assert!(
                cmd.get_arguments().any(|a| a.get_id() == arg_id(key.name)),
                "{kind}: key {}.{} names no argument",
                key.table,
                key.key
            );
        }
    }
}
