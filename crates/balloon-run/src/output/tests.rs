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
