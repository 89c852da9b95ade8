//! Run records, however a run ends: interrupted by SIGINT / SIGTERM (the real binary gets the
//! signal after its first frames), failed (summary.json and the `--json` line), an output folder
//! of an earlier run (refused, or cleared with `--overwrite`), output errors (the path named, no
//! temporary files left) and a closed stdout (a quiet exit).

use super::{last_json_line, run_balloon};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub(super) fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}: {text}", path.display()))
}

/// Waits until `path` exists (the run is under way), at most 120 s.
pub(super) fn wait_for(child: &mut Child, path: &Path) {
    let start = Instant::now();
    while !path.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!(
                "the run ended ({status}) before {} appeared",
                path.display()
            );
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends `signal` (a `kill` name) to the child and waits for it, at most 60 s.
pub(super) fn signal_and_wait(child: &mut Child, signal: &str) -> std::process::Output {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the run did not stop after SIG{signal}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut stdout = String::new();
    let mut stderr = String::new();
    use std::io::Read;
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut stdout)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    std::process::Output {
        status: child.wait().unwrap(),
        stdout: stdout.into_bytes(),
        stderr: stderr.into_bytes(),
    }
}

pub(super) fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_balloon"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("failed to start the balloon binary")
}

/// Checks the records of an interrupted run: exit status, summary, stats and frames agree.
pub(super) fn check_interrupted(
    out: &std::process::Output,
    dir: &Path,
    code: i32,
    frame_ext: &str,
) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "stderr: {err}");
    assert!(err.contains("interrupted"), "{err}");
    let s = read_json(&dir.join("summary.json"));
    assert_eq!(s["interrupted"], true, "{s}");
    assert!(s["error"].is_null(), "{s}");
    let steps = s["steps"].as_u64().unwrap() as usize;
    assert!(steps >= 1, "{s}");
    let stats = std::fs::read_to_string(dir.join("stats.jsonl")).unwrap();
    let rows: Vec<serde_json::Value> = stats
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), steps, "one stats line per completed step");
    // Steps are numbered from 1 in every system's stats.
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r["step"], i + 1, "{r}");
    }
    let frames = std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            let n = e.as_ref().unwrap().file_name();
            let n = n.to_string_lossy();
            n.starts_with("frame_") && n.ends_with(frame_ext)
        })
        .count();
    assert!(frames >= 2, "{frames} frames");
    assert_eq!(s["frames"], frames, "{s}");
    assert!(
        std::fs::read_dir(dir).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp")),
        "a temporary file was left"
    );
    // The --json line is the summary.
    assert_eq!(last_json_line(out), s);
}

#[test]
fn sigint_stops_a_two_layer_run_with_its_records_and_status_130() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut child = spawn(&[
        "two-layer",
        "--level",
        "2",
        "--steps",
        "100000000",
        "--frame-every",
        "100",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    wait_for(&mut child, &run.join("frame_00100.obj"));
    let out = signal_and_wait(&mut child, "INT");
    check_interrupted(&out, &run, 130, ".obj");
    assert_eq!(
        read_json(&run.join("summary.json"))["status"],
        "interrupted"
    );
}

#[test]
fn sigterm_stops_an_inflate_run_with_its_records_and_status_143() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut child = spawn(&[
        "inflate",
        "builtin:icosphere",
        "--steps",
        "100000",
        "--frame-every",
        "1",
        "--format",
        "vtk",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    wait_for(&mut child, &run.join("frame_00001.vtp"));
    let out = signal_and_wait(&mut child, "TERM");
    check_interrupted(&out, &run, 143, ".vtp");
    assert!(run.join("final.vtp").is_file());
    // series.pvd lists exactly the frames on disk.
    let pvd = std::fs::read_to_string(run.join("series.pvd")).unwrap();
    let s = read_json(&run.join("summary.json"));
    assert_eq!(
        pvd.matches("<DataSet ").count() as u64,
        s["frames"].as_u64().unwrap()
    );
}

#[test]
fn a_failed_volumetric_run_writes_its_summary_and_json_line() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    // Springs far too stiff for the step: a tetrahedron inverts at the first step.
    let out = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "8",
        "--voxels-per-cell",
        "2",
        "--dt",
        "0.1",
        "--edge-stiffness",
        "1e12",
        "--steps",
        "50",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("step 1 (0 step(s) completed)"), "{err}");
    assert!(!err.contains("no --out"), "{err}");
    let s = read_json(&run.join("summary.json"));
    assert!(s["error"].as_str().unwrap().contains("inverts"), "{s}");
    assert_eq!(s["steps"], 0);
    assert_eq!(s["interrupted"], false);
    assert_eq!(last_json_line(&out), s);
}

#[test]
fn a_blown_up_two_layer_run_counts_completed_steps_only() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--k-structural",
        "2e4",
        "--damping",
        "0",
        "--integrator",
        "euler",
        "--dt",
        "2e-3",
        "--steps",
        "3000",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    let s = read_json(&run.join("summary.json"));
    assert_eq!(
        last_json_line(&out),
        s,
        "the --json line is printed on failure too"
    );
    let steps = s["steps"].as_u64().unwrap();
    let rows = std::fs::read_to_string(run.join("stats.jsonl"))
        .unwrap()
        .lines()
        .count() as u64;
    assert_eq!(steps, rows, "the summary counts completed steps: {s}");
    // The failing step is the one after the last completed one, in the message and the error.
    let failed = format!("step {} failed ({steps} step(s) completed)", steps + 1);
    assert!(err.contains(&failed), "`{failed}` not in {err}");
    assert!(
        s["error"]
            .as_str()
            .unwrap()
            .contains(&format!("step {}", steps + 1)),
        "{s}"
    );
    assert!(!err.contains("e.g. 0e0"), "{err}");
}

#[test]
fn a_reused_out_folder_is_refused_or_cleared_with_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let r = run.to_str().unwrap();
    let base = [
        "two-layer",
        "--level",
        "1",
        "--frame-every",
        "10",
        "--out",
        r,
    ];
    let first = run_balloon(&[&base[..], &["--steps", "40"]].concat());
    assert!(first.status.success());
    assert!(run.join("frame_00040.obj").is_file());
    std::fs::write(run.join("notes.txt"), "mine").unwrap();
    let again = run_balloon(&[&base[..], &["--steps", "10"]].concat());
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success(), "a reused --out was accepted");
    assert!(err.contains(r) && err.contains("--overwrite"), "{err}");
    assert!(
        run.join("frame_00040.obj").is_file(),
        "refused, yet files went"
    );
    let over = run_balloon(&[&base[..], &["--steps", "10", "--overwrite"]].concat());
    assert!(
        over.status.success(),
        "{}",
        String::from_utf8_lossy(&over.stderr)
    );
    assert!(run.join("frame_00010.obj").is_file());
    assert!(
        !run.join("frame_00040.obj").exists(),
        "the old run's frame survived"
    );
    assert_eq!(read_json(&run.join("summary.json"))["steps"], 10);
    assert_eq!(
        std::fs::read_to_string(run.join("notes.txt")).unwrap(),
        "mine",
        "--overwrite removed a file it did not write"
    );
}

#[test]
fn output_errors_name_the_path_and_leave_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    // A file where the folder should be.
    let file = dir.path().join("not-a-folder");
    std::fs::write(&file, "x").unwrap();
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--steps",
        "5",
        "--out",
        file.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains(file.to_str().unwrap()), "{err}");
    // A folder where frame 2 should be: its write fails mid-run.
    let run = dir.path().join("run");
    std::fs::create_dir_all(run.join("frame_00002.obj")).unwrap();
    let out = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--steps",
        "6",
        "--frame-every",
        "2",
        "--out",
        run.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    let target = run.join("frame_00002.obj");
    assert!(err.contains(target.to_str().unwrap()), "{err}");
    let names: Vec<String> = std::fs::read_dir(&run)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.ends_with(".tmp")),
        "temporary files left: {names:?}"
    );
    // The records say what happened.
    let s = read_json(&run.join("summary.json"));
    assert!(
        s["error"].as_str().unwrap().contains("frame_00002.obj"),
        "{s}"
    );
    assert_eq!(s["steps"], 2);
}

#[test]
fn a_closed_stdout_is_a_quiet_exit() {
    for json in [false, true] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let mut args = vec!["mesh", "info", "builtin:teddy"];
        if json {
            args.push("--json");
        }
        let out = Command::new(env!("CARGO_BIN_EXE_balloon"))
            .args(&args)
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {:?} {err}", out.status);
        assert!(err.is_empty(), "{args:?}: {err}");
    }
}

#[test]
fn a_two_layer_run_whose_frame_cannot_be_written_fails_with_status_failed() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let mut child = spawn(&[
        "two-layer",
        "--level",
        "2",
        "--steps",
        "1000000",
        "--frame-every",
        "1000",
        "--out",
        run.to_str().unwrap(),
        "--json",
    ]);
    wait_for(&mut child, &run.join("frame_01000.obj"));
    // Folders where the later frames go: the next of them cannot be written (those the run
    // wrote meanwhile are skipped).
    for k in (2..1000).map(|k| k * 1000) {
        let _ = std::fs::create_dir(run.join(format!("frame_{k:05}.obj")));
    }
    let out = child.wait_with_output().unwrap();
    assert!(!out.status.success(), "a run that lost a frame exited 0");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("cannot write"), "{stderr}");
    let summary = read_json(&run.join("summary.json"));
    assert_eq!(summary["status"], "failed", "{summary}");
    assert!(summary["error"].as_str().unwrap().contains("cannot write"));
    assert_eq!(last_json_line(&out), summary);
}

/// Every run's summary repeats the physical parameters (issue 15, item 2): `scenario` holds
/// the resolved scenario (the values of `scenario.toml`), in `summary.json` and the `--json`
/// line, for each system, and `scenario.toml` of the same run says the same.
#[test]
fn summaries_repeat_the_resolved_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str], &str); 4] = [
        (
            "inflate",
            &[
                "inflate",
                "builtin:sphere",
                "--steps",
                "1",
                "--thickness",
                "4e-4",
                "--dt",
                "0.005",
            ],
            "shell",
        ),
        (
            "static",
            &[
                "inflate",
                "builtin:sphere",
                "--static",
                "--gas",
                "constant",
                "--pressure",
                "300",
            ],
            "shell",
        ),
        (
            "volumetric",
            &[
                "volumetric",
                "builtin:icosphere",
                "--resolution",
                "12",
                "--steps",
                "2",
            ],
            "volumetric",
        ),
        (
            "two-layer",
            &["two-layer", "--level", "1", "--steps", "3"],
            "two-layer",
        ),
    ];
    for (name, args, kind) in cases {
        let run = dir.path().join(name);
        let mut all = args.to_vec();
        all.extend(["--out", run.to_str().unwrap(), "--json"]);
        let out = run_balloon(&all);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let s = read_json(&run.join("summary.json"));
        assert_eq!(last_json_line(&out), s, "{name}");
        let sc = &s["scenario"];
        assert_eq!(sc["system"]["kind"], kind, "{name}: {s}");
        // Every `key = value` of scenario.toml's tables is in the summary's `scenario` (read
        // line by line here, not with the code's converter).
        let text = std::fs::read_to_string(run.join("scenario.toml")).unwrap();
        let mut table = String::new();
        let mut keys = 0;
        for line in text.lines().map(str::trim) {
            if let Some(t) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                table = t.to_owned();
            } else if let Some((k, _)) = line.split_once(" = ")
                && !line.starts_with('#')
                && !table.starts_with('[')
            {
                assert!(
                    !sc[&table][k.trim()].is_null(),
                    "{name}: [{table}] {k} missing: {sc}"
                );
                keys += 1;
            }
        }
        assert!(keys > 10, "{name}: {keys} keys in scenario.toml");
        if name == "inflate" {
            // The defaults the run resolved are written in (not "not set").
            assert_eq!(sc["shell"]["material"], "stvk");
            assert_eq!(sc["shell"]["young"], 1e6);
            assert_eq!(sc["shell"]["poisson"], 0.45);
            assert_eq!(sc["shell"]["volume_projection"], "global");
            // 0.7 rest volumes per second of this body.
            let rate = sc["gas"]["pump_rate"].as_f64().unwrap();
            let v0 = s["initial_gas_volume"].as_f64().unwrap();
            assert!((rate / (0.7 * v0) - 1.0).abs() < 1e-12, "{rate} vs {v0}");
            assert_eq!(sc["shell"]["thickness"], 4e-4);
            assert_eq!(sc["run"]["dt"], 0.005);
            assert_eq!(sc["gas"]["model"], "pump");
            assert_eq!(sc["mesh"]["scale"], 1);
        }
        if name == "static" {
            assert_eq!(sc["gas"]["pressure"], 300.0);
            assert_eq!(sc["run"]["static"], true);
        }
    }
}
