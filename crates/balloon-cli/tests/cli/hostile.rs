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

/// Runs `args`, expects a failure and returns its stderr.
fn refused(args: &[&str]) -> String {
    let out = run_within(args, None, Duration::from_secs(120));
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    err
}

#[test]
fn a_vanishing_gent_limit_is_refused_naming_jm() {
    // It once "converged" with residual 0 after 0 iterations: even the rest shape's rounding of
    // I1 - 3 exceeded the limit.
    for jm in ["1e-300", "1e-20", "1e-7"] {
        let err = refused(&[
            "inflate",
            "builtin:icosphere",
            "--material",
            "membrane-gent",
            "--mu",
            "4e5",
            "--jm",
            jm,
            "--static",
            "--gas",
            "constant",
        ]);
        assert!(
            err.contains("--jm") && err.contains("at least 1e-6") && !err.contains("0.0000000"),
            "{jm}: {err}"
        );
    }
}

#[test]
fn a_continuation_step_lost_in_rounding_is_refused() {
    for ratios in ["1:2:1e-300", "1:1.0000000000000002:1e-17"] {
        let err = refused(&[
            "inflate",
            "builtin:icosphere",
            "--static",
            "--gas",
            "volume",
            "--volume-ratios",
            ratios,
        ]);
        assert!(
            err.contains("--volume-ratios") && err.contains("would not differ"),
            "{ratios}: {err}"
        );
    }
}

#[test]
fn pinning_every_vertex_is_refused_as_such() {
    for extra in [
        &["--steps", "2"][..],
        &["--static", "--gas", "constant"][..],
    ] {
        let mut args = vec!["inflate", "builtin:icosphere", "--pin", "below:z:100"];
        args.extend_from_slice(extra);
        let err = refused(&args);
        assert!(
            err.contains("--pin holds all") && err.contains("nothing can move"),
            "{err}"
        );
        assert!(
            !err.contains("--cg-tol") && !err.contains("linear solver"),
            "{err}"
        );
    }
    // Springs instead of hard pins may hold every vertex: the balloon still moves.
    let out = run_balloon(&[
        "inflate",
        "builtin:icosphere",
        "--pin",
        "below:z:100@100",
        "--steps",
        "1",
        "--gas",
        "constant",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_negative_count_names_the_flag_or_key() {
    let err = refused(&["inflate", "--steps", "-1"]);
    assert!(
        err.contains("'--steps <STEPS>'") && err.contains("not a whole number"),
        "{err}"
    );
    assert!(!err.contains("unexpected argument"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.toml");
    std::fs::write(
        &file,
        "[mesh]\npath = \"builtin:icosphere\"\n[run]\nsteps = -1\n",
    )
    .unwrap();
    let f = file.to_str().unwrap();
    let err = refused(&["run", f]);
    assert!(
        err.contains("s.toml:4") && err.contains("`run.steps`") && err.contains("'-1'"),
        "{err}"
    );
    let err = refused(&["run", f, "--steps", "-1"]);
    assert!(
        err.contains("'--steps <STEPS>'") && !err.contains("unexpected argument"),
        "{err}"
    );
}

#[test]
fn a_directory_as_mesh_path_is_called_a_directory() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.toml");
    std::fs::write(&file, "[mesh]\npath = \".\"\n[run]\nsteps = 1\n").unwrap();
    let err = refused(&["run", file.to_str().unwrap()]);
    assert!(
        err.contains("is a directory") && !err.contains("unsupported"),
        "{err}"
    );
    let err = refused(&["inflate", dir.path().to_str().unwrap(), "--steps", "1"]);
    assert!(err.contains("is a directory"), "{err}");
}

#[test]
fn a_wrong_transform_in_a_file_names_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    for (value, what) in [
        ("[1, 2, 3]", "takes 12 numbers"),
        ("[-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]", "determinant"),
    ] {
        let file = dir.path().join("t.toml");
        std::fs::write(
            &file,
            format!(
                "[mesh]\npath = \"builtin:icosphere\"\ntransform = {value}\n[run]\nsteps = 1\n"
            ),
        )
        .unwrap();
        let err = refused(&["run", file.to_str().unwrap()]);
        assert!(
            err.contains("t.toml:3") && err.contains("`mesh.transform`") && err.contains(what),
            "{err}"
        );
    }
}

#[test]
fn a_static_solve_above_the_limit_pressure_points_to_volume_control() {
    // A membrane's gauge pressure has a maximum (docs/membranes.md): a few kPa for this
    // sphere of radius 0.1 m of latex, so 1e5 Pa has no equilibrium. A coarse sphere (162
    // vertices) keeps the failing solve short.
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("ico2.obj");
    balloon::mesh::io::write_obj(&mesh, &balloon::mesh::generate::icosphere(0.1, 2).unwrap())
        .unwrap();
    let err = refused(&[
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
        "--tangent",
        "projected",
    ]);
    assert!(
        err.contains("may exceed the largest the balloon can hold")
            && err.contains("no equilibrium exists")
            && err.contains("--gas volume")
            && err.contains("--volume-ratio"),
        "{err}"
    );
    // The tangent the run already used is not suggested again.
    assert!(!err.contains("--tangent projected"), "{err}");
}

/// Unmounts the small file system of a test when it ends (also when it fails).
struct Mounted(std::path::PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// A real full disk: a 96 kB tmpfs. Mounting one needs root (or the capability to mount);
/// where the mount is refused the test says so on stderr and checks nothing (the injected
/// failing writer of the unit tests covers the same paths everywhere).
#[test]
fn a_full_disk_leaves_whole_lines_no_temporary_file_and_no_success_message() {
    let dir = tempfile::tempdir().unwrap();
    let mount = dir.path().join("small");
    std::fs::create_dir(&mount).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=96k", "tmpfs"])
        .arg(&mount)
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped: cannot mount a tmpfs here (needs root)");
        return;
    }
    let _guard = Mounted(mount.clone());
    let run = mount.join("run");
    let out = run_within(
        &[
            "inflate",
            "builtin:icosphere",
            "--gas",
            "constant",
            "--steps",
            "400",
            "--out",
            run.to_str().unwrap(),
        ],
        None,
        Duration::from_secs(300),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "a full disk went unnoticed: {stdout}"
    );
    assert!(!stdout.contains("output written"), "{stdout}");
    assert!(
        stderr.contains("No space left") || stderr.contains("space"),
        "{stderr}"
    );
    let stats = std::fs::read(run.join("stats.jsonl")).unwrap_or_default();
    assert!(
        stats.is_empty() || stats.ends_with(b"\n"),
        "stats.jsonl ends in a partial line"
    );
    for line in String::from_utf8_lossy(&stats).lines() {
        serde_json::from_str::<serde_json::Value>(line).unwrap();
    }
    for entry in std::fs::read_dir(&run).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "temporary file {name} left behind");
    }
}
