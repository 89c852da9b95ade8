//! The volumetric scenario's `floor` scene, `up` axis and `floor_height`.

use super::*;
use crate::Scenario;

/// The scenario of `text` (a `kind = "volumetric"` file) read and validated, or the error with
/// its causes.
fn read(text: &str) -> Result<VolumetricScenario, String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.toml");
    std::fs::write(&path, text).unwrap();
    let chain = |e: &dyn std::error::Error| {
        let mut s = e.to_string();
        let mut c = e.source();
        while let Some(x) = c {
            s += &format!(": {x}");
            c = x.source();
        }
        s
    };
    let f = crate::file::read(&path, &[]).map_err(|e| chain(&e))?;
    let Scenario::Volumetric(v) = f.scenario else {
        panic!("not a volumetric scenario")
    };
    v.validate().map_err(|e| chain(&e))?;
    Ok(v)
}

const HEAD: &str = "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"builtin:icosphere\"\n\
                    [lattice]\nresolution = 10\nvoxels_per_cell = 2\n";

#[test]
fn the_floor_scene_stands_the_body_on_a_floor_along_up() {
    for (up, axis) in [("y", 1), ("z", 2)] {
        let s = read(&format!(
            "{HEAD}[run]\nscene = \"floor\"\nup = \"{up}\"\ngravity = -3.0\n"
        ))
        .unwrap();
        assert_eq!(s.run.scene, SceneChoice::Floor);
        let mut g = [0.0; 3];
        g[axis] = -3.0;
        assert_eq!(s.params().gravity, g, "up = {up}");
        let built = s.build(None).unwrap();
        let sim = &built.sim;
        assert!(sim.sphere().is_none());
        let [floor] = sim.planes() else {
            panic!("up = {up}: {} planes", sim.planes().len())
        };
        assert_eq!(floor.normal, s.run.up.vector());
        // Just under the lowest particle: a thousandth of the particles' diagonal.
        let x = sim.positions();
        let lowest = x.iter().map(|p| p[axis]).fold(f64::INFINITY, f64::min);
        let gap = lowest - floor.point[axis];
        assert!(gap > 0.0 && gap < 2e-3 * 0.2 * 3f64.sqrt(), "gap {gap}");
        assert_eq!(floor.point[axis], default_floor_height(x, s.run.up));
    }
    // A given height.
    let s = read(&format!(
        "{HEAD}[run]\nscene = \"floor\"\nup = \"y\"\nfloor_height = -0.25\n"
    ))
    .unwrap();
    let built = s.build(None).unwrap();
    assert_eq!(
        built.sim.planes()[0].point,
        nalgebra::Point3::new(0.0, -0.25, 0.0)
    );
}

#[test]
fn the_body_falls_along_up_onto_the_floor_and_stays_above_it() {
    let s = read(&format!(
        "{HEAD}[run]\nscene = \"floor\"\nup = \"y\"\nfloor_height = -0.11\ndt = 5e-4\n"
    ))
    .unwrap();
    let mut sim = s.build(None).unwrap().sim;
    let y0: f64 = sim.positions().iter().map(|p| p.y).sum();
    let z0: f64 = sim.positions().iter().map(|p| p.z).sum();
    for _ in 0..400 {
        sim.step().unwrap();
    }
    let n = sim.positions().len() as f64;
    let y1: f64 = sim.positions().iter().map(|p| p.y).sum();
    let z1: f64 = sim.positions().iter().map(|p| p.z).sum();
    // 0.2 s of fall from 1 cm above the floor: it landed (a free fall would be 0.2 m lower).
    assert!((y1 - y0) / n < -5e-3, "mean y moved {}", (y1 - y0) / n);
    assert!((y1 - y0) / n > -0.05, "mean y moved {}", (y1 - y0) / n);
    assert!(
        ((z1 - z0) / n).abs() < 1e-9,
        "mean z moved {}",
        (z1 - z0) / n
    );
    let lowest = sim
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest >= -0.11 - 1e-9, "lowest particle {lowest}");
}

#[test]
fn scene_keys_out_of_place_or_range_are_errors_naming_the_key() {
    for (run, words) in [
        (
            "floor_height = 0.5\n",
            &["`floor_height`", "`scene`", "drop-sphere"][..],
        ),
        (
            "scene = \"free\"\nfloor_height = 0.5\n",
            &["`floor_height`", "\"free\""],
        ),
        ("up = \"y\"\n", &["`up`", "drop-sphere", "\"z\""]),
        (
            "scene = \"floor\"\nfloor_height = 2e6\n",
            &["floor_height", "2000000"],
        ),
        ("scene = \"floor\"\nup = \"x\"\n", &["up", "`x`", "y, z"]),
        ("scene = \"ceiling\"\n", &["scene", "floor"]),
    ] {
        let e = read(&format!("{HEAD}[run]\n{run}")).unwrap_err();
        for w in words {
            assert!(e.contains(w), "{run}: {e} (no {w})");
        }
    }
}

#[test]
fn the_new_keys_record_and_read_back() {
    let s = read(&format!(
        "{HEAD}[run]\nscene = \"floor\"\nup = \"y\"\nfloor_height = -0.123456789012345678\n"
    ))
    .unwrap();
    let text = crate::file::record(&Scenario::Volumetric(s.clone()), &Default::default());
    assert!(text.contains("scene = \"floor\"\n"), "{text}");
    assert!(text.contains("up = \"y\"\n"), "{text}");
    let back = read(&text).unwrap();
    assert_eq!(back, s);
    assert_eq!(back.run.floor_height, Some(-0.123_456_789_012_345_68));
}
