//! What a careless or hostile user does: special files as inputs, an empty scenario, a mistyped
//! mesh with `--overwrite`, `--out .` beside the scenario file. Nothing hangs, nothing is lost.

use super::run_balloon;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs the binary with `args`, killing it after `limit` (a hang fails the test instead of
/// hanging the suite).
fn run_within(args: &[&str], cwd: Option<&std::path::Path>, limit: Duration) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_balloon"));
    cmd.args(args).stdout(Stdio::piped()).stderr(Stdio::piped());
    if let Some(d) = cwd {
        cmd.current_dir(d);
    }
    let mut child = cmd.spawn().unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("`balloon {}` still running after {limit:?}", args.join(" "));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[cfg(unix)]
#[test]
fn fifos_and_devices_as_input_files_are_refused_at_once_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.txt");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let zero = dir.path().join("zero.txt");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    for special in [&fifo, &zero] {
        let p = special.to_str().unwrap();
        let pin = format!("file:{p}");
        for args in [
            vec!["run", p],
            vec!["inflate", "--steps", "1", "--thickness-file", p],
            vec!["inflate", "--steps", "1", "--pin", &pin],
        ] {
            let out = run_within(&args, None, Duration::from_secs(60));
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{args:?} succeeded");
            assert!(
                err.contains(p) && err.contains("not a regular file"),
                "{args:?}: {err}"
            );
        }
    }
}

#[test]
fn an_empty_scenario_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.toml");
    std::fs::write(&empty, "# nothing yet\n\n").unwrap();
    let out = run_balloon(&["run", empty.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "an empty scenario ran");
    assert!(
        err.contains("empty.toml") && err.contains("is empty"),
        "{err}"
    );
}

#[test]
fn overwrite_keeps_the_earlier_run_when_the_new_one_cannot_start() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let r = run.to_str().unwrap();
    let first = run_balloon(&["two-layer", "--level", "1", "--steps", "5", "--out", r]);
    assert!(first.status.success());
    let first = run_balloon(&[
        "inflate",
        "builtin:sphere",
        "--steps",
        "1",
        "--out",
        r,
        "--overwrite",
    ]);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let summary = std::fs::read_to_string(run.join("summary.json")).unwrap();
    // A mistyped mesh: refused, and the earlier run is still there.
    let typo = run_balloon(&[
        "inflate",
        "no-such-mesh.obj",
        "--steps",
        "1",
        "--out",
        r,
        "--overwrite",
    ]);
    assert!(!typo.status.success());
    assert_eq!(
        std::fs::read_to_string(run.join("summary.json")).unwrap(),
        summary
    );
    assert!(run.join("stats.jsonl").is_file());
}

#[test]
fn out_dot_beside_the_scenario_file_never_replaces_it() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    let text = "[mesh]\npath = \"builtin:sphere\"\n\n[run]\nsteps = 1\n\n[output]\nout = \".\"\noverwrite = true\n";
    std::fs::write(&scenario, text).unwrap();
    let out = run_within(
        &["run", "scenario.toml"],
        Some(dir.path()),
        Duration::from_secs(120),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "the scenario file was replaced");
    assert!(err.contains("an input of this run"), "{err}");
    assert_eq!(std::fs::read_to_string(&scenario).unwrap(), text);
}
