//! Unit tests of the output folder.

use super::*;
use balloon_scenario::names::{Spelling, respell};

#[test]
fn only_files_this_program_writes_count_as_an_earlier_run() {
    for ours in [
        "stats.jsonl",
        "summary.json",
        ".summary.json.tmp",
        "series.pvd",
        ".series.pvd.tmp",
        "frame_00000.obj",
        "frame_12345.vtp",
        ".frame_00010.vtp.tmp",
        "frame_00002.tmp",
        "final.ply",
        "final.pov",
        "run.gif",
        ".run.gif.tmp",
        "lattice.vtk",
        "lattice_00020.vtk",
        "input_soup.obj",
        "sphere_00020.obj",
        "sphere1_00020.vtp",
        ".sphere_00020.vtp.tmp",
        "floor.ply",
    ] {
        assert!(is_run_file(ours), "{ours}");
    }
    for theirs in [
        "notes.txt",
        "frame_.obj",
        "frame_abc.obj",
        "frame_00001.png",
        "final.txt",
        "my_summary.json",
        "lattice_1.vtp",
        "teddy.obj",
        "sphere.obj",
        "sphere_a.obj",
        "floor_1.obj",
    ] {
        assert!(!is_run_file(theirs), "{theirs}");
    }
}

#[test]
fn prepare_refuses_a_reused_folder_and_overwrite_removes_only_run_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    prepare_out_dir(&out, false).unwrap();
    std::fs::create_dir_all(out.join("renders")).unwrap();
    for f in [
        "frame_00000.obj",
        "summary.json",
        "mine.txt",
        "renders/frame_00003.png",
    ] {
        std::fs::write(out.join(f), "x").unwrap();
    }
    let e = prepare_out_dir(&out, false).unwrap_err().to_string();
    assert!(
        e.contains(&out.display().to_string()) && e.contains("`overwrite`"),
        "{e}"
    );
    assert!(respell(&e, Spelling::Flag).contains("--overwrite"), "{e}");
    prepare_out_dir(&out, true).unwrap();
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, ["mine.txt"]);
    let file = dir.path().join("file");
    std::fs::write(&file, "x").unwrap();
    let e = prepare_out_dir(&file, true).unwrap_err().to_string();
    assert!(e.contains("not a folder"), "{e}");
}

#[test]
fn stretch_of_a_soup_with_a_degenerate_triangle_is_nan_there() {
    let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0];
    let x: Vec<f64> = rest.iter().map(|c| 2.0 * c).collect();
    let f = Frame::new(0, 0.0, x, vec![[0, 1, 2], [0, 1, 3]])
        .with_stretch(&rest)
        .unwrap();
    let s = &f.cell_data[0].values;
    assert!((s[0] - 2.0).abs() < 1e-12 && s[1].is_nan());
}

/// A file on a disk with `room` bytes left: writes fill it, then fail as a full disk does.
struct FullDisk {
    bytes: Vec<u8>,
    room: usize,
}

impl Write for FullDisk {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.room - self.bytes.len());
        if n == 0 {
            return Err(std::io::Error::from(std::io::ErrorKind::StorageFull));
        }
        self.bytes.extend_from_slice(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Truncate for FullDisk {
    fn truncate_to(&mut self, len: u64) -> std::io::Result<()> {
        self.bytes.truncate(len as usize);
        Ok(())
    }
}

#[test]
fn a_full_disk_leaves_stats_ending_at_the_last_whole_line() {
    let mut disk = FullDisk {
        bytes: Vec::new(),
        room: 40,
    };
    let mut len = 0;
    let mut written = 0;
    for step in 1..10 {
        let line = format!("{{\"step\":{step},\"x\":1.5}}\n");
        match append_whole_line(&mut disk, len, line.as_bytes()) {
            Ok(()) => {
                len += line.len() as u64;
                written += 1;
            }
            Err(e) => {
                assert_eq!(e.kind(), std::io::ErrorKind::StorageFull);
                break;
            }
        }
    }
    // Two lines of 19 bytes fit in 40; the third was cut back off.
    assert_eq!(written, 2);
    let text = String::from_utf8(disk.bytes).unwrap();
    assert!(text.ends_with('\n'), "{text:?}");
    assert_eq!(text.lines().count(), 2);
    for line in text.lines() {
        serde_json::from_str::<serde_json::Value>(line).unwrap();
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_failing_stats_file_is_an_error_naming_it() {
    // `/dev/full` fails every write with "no space left on device".
    let dir = tempfile::tempdir().unwrap();
    let mut out = OutputDir::create(dir.path(), FrameFormat::Obj).unwrap();
    out.stats = Some(File::options().write(true).open("/dev/full").unwrap());
    let e = out
        .append_stats(&serde_json::json!({"step": 1}))
        .unwrap_err();
    let text = format!("{e:#}");
    assert!(text.contains("stats.jsonl"), "{text}");
}

#[test]
fn temp_files_are_recognised_and_removed_on_request() {
    for tmp in [
        ".run.gif.tmp",
        ".summary.json.tmp",
        "frame_00002.tmp",
        ".frame_00003.vtp.tmp",
        ".frame_00004.png.tmp",
        ".pressure_volume.png.tmp",
    ] {
        assert!(is_temp_file(tmp), "{tmp}");
    }
    for not in ["run.gif", "notes.tmp", ".notes.txt.tmp", "frame_00001.obj"] {
        assert!(!is_temp_file(not), "{not}");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = OutputDir::create(dir.path(), FrameFormat::Obj).unwrap();
    std::fs::write(out.path().join(".run.gif.tmp"), "partial").unwrap();
    std::fs::write(out.path().join("notes.tmp"), "the user's").unwrap();
    assert!(super::temp::remove_temp_files() >= 1);
    assert!(!out.path().join(".run.gif.tmp").exists());
    assert!(out.path().join("notes.tmp").exists());
    // A job's own files written through `.NAME.tmp` (a design's), in a folder it watches.
    let design = tempfile::tempdir().unwrap();
    super::temp::watch_out_files(design.path(), &["rest.obj"]);
    std::fs::write(design.path().join(".rest.obj.tmp"), "partial").unwrap();
    std::fs::write(design.path().join(".mine.obj.tmp"), "the user's").unwrap();
    assert!(super::temp::remove_temp_files() >= 1);
    assert!(!design.path().join(".rest.obj.tmp").exists());
    assert!(design.path().join(".mine.obj.tmp").exists());
}

#[test]
fn an_input_of_the_run_is_never_removed_by_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, "[mesh]\npath = \"builtin:sphere\"\n").unwrap();
    balloon::mesh::io::read_input_text(&scenario, 1000).unwrap();
    let e = prepare_out_dir(dir.path(), true).unwrap_err().to_string();
    assert!(e.contains("an input of this run"), "{e}");
    assert!(scenario.exists());
}

#[test]
fn a_job_with_named_files_refuses_and_replaces_only_those() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("design");
    let names = ["rest.obj", "summary.json"];
    // A folder that does not exist yet, or holds none of the names, is fine.
    check_out_dir_files(&out, false, &names, "design").unwrap();
    std::fs::create_dir_all(&out).unwrap();
    // A run's frame is not one of this job's files: it is left alone.
    for f in ["rest.obj", "mine.txt", "frame_00000.obj"] {
        std::fs::write(out.join(f), "x").unwrap();
    }
    let e = prepare_out_dir_files(&out, false, &names, "design")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("earlier design (1 file(s), e.g. rest.obj)") && e.contains("`overwrite`"),
        "{e}"
    );
    assert!(out.join("rest.obj").exists());
    prepare_out_dir_files(&out, true, &names, "design").unwrap();
    let mut left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["frame_00000.obj", "mine.txt"]);
    let file = dir.path().join("file");
    std::fs::write(&file, "x").unwrap();
    let e = check_out_dir_files(&file, true, &names, "design")
        .unwrap_err()
        .to_string();
    assert!(e.contains("is not a folder"), "{e}");
}
