//! The USD stage's structure, read back with a small parser of the parts it writes: a valid
//! stage after every frame (balanced blocks, one sample per frame in every block, the header's
//! time range), the same samples after the reserve is grown and after `finish`, topology once.

use super::*;
use crate::output::frame::{Body, Field, Frame};
use balloon_render::Prop;

/// A frame of a two-body surface (two triangles each) at `step`, time `0.01 * step`.
fn frame(step: usize) -> Frame {
    let s = step as f64;
    let positions = vec![
        0.0,
        0.0,
        s,
        1.0,
        0.0,
        0.0,
        0.0,
        1.0,
        0.0,
        1.0,
        1.0,
        0.0, //
        5.0,
        0.0,
        0.0,
        6.0,
        0.0,
        0.0,
        5.0,
        1.0,
        0.0,
        6.0,
        1.0,
        0.5 * s,
    ];
    let triangles = vec![[0, 1, 2], [1, 3, 2], [4, 5, 6], [5, 7, 6]];
    let mut f = Frame::new(step, 0.01 * s, positions, triangles).with_bodies(vec![
        Body {
            name: "balloon_0".into(),
            vertices: 0..4,
            faces: 0..2,
            pressure: Some(100.0 + s),
        },
        Body {
            name: "balloon_1".into(),
            vertices: 4..8,
            faces: 2..4,
            pressure: Some(200.0 + s),
        },
    ]);
    f.cell_data
        .push(Field::scalar("thickness", vec![1e-3, 2e-3, 3e-3, 4e-3 + s]));
    f.point_data.push(Field::vector("velocity", vec![s; 24]));
    f.props = vec![Prop::sphere([0.0, 0.0, 2.0 - s], 0.5)];
    f
}

/// The blocks `NAME.timeSamples = { ... }` of `text` as (name, sample lines).
fn blocks(text: &str) -> Vec<(String, Vec<String>)> {
    let mut out = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        let Some(head) = line.trim().strip_suffix(".timeSamples = {") else {
            continue;
        };
        let name = head.rsplit(' ').next().unwrap().to_string();
        let mut samples = Vec::new();
        for l in lines.by_ref() {
            let t = l.trim();
            if t == "}" {
                break;
            }
            if !t.is_empty() {
                samples.push(t.to_string());
            }
        }
        out.push((name, samples));
    }
    out
}

fn header(text: &str, key: &str) -> String {
    text.lines()
        .find_map(|l| l.trim().strip_prefix(&format!("{key} = ")))
        .unwrap_or_else(|| panic!("no {key} in the header"))
        .trim()
        .to_string()
}

fn braces_balance(text: &str) -> bool {
    let mut depth = 0i64;
    for c in text.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ => {}
        }
        if depth < 0 {
            return false;
        }
    }
    depth == 0
}

#[test]
fn valid_after_every_frame_with_one_sample_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.usda");
    let mut w = UsdWriter::new(&path, UpAxis::Z);
    for step in 0..40 {
        w.push(&frame(step)).unwrap();
        // What a reader sees if the run stops here (no `finish`).
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("#usda 1.0\n"));
        assert!(braces_balance(&text), "unbalanced after step {step}");
        let b = blocks(&text);
        assert!(!b.is_empty());
        for (name, samples) in &b {
            assert_eq!(samples.len(), step + 1, "{name} after step {step}");
            assert!(samples.last().unwrap().starts_with(&format!("{step}: ")));
        }
        assert_eq!(header(&text, "endTimeCode"), step.to_string());
        if step > 0 {
            // One time code per 0.01 s: the time range is the simulated time.
            let r: f64 = header(&text, "timeCodesPerSecond").parse().unwrap();
            assert!((r - 100.0).abs() < 1e-9, "{r}");
        }
    }
    w.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(!text.contains("\n\n\n"), "reserve left after finish");
    assert_eq!(header(&text, "upAxis"), "\"Z\"");
    assert_eq!(header(&text, "metersPerUnit"), "1");
    let b = blocks(&text);
    let names: Vec<&str> = b.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "balloon:time",
            "balloon:step",
            "extent",
            "points",
            "velocities",
            "primvars:thickness",
            "primvars:pressure",
            "extent",
            "points",
            "velocities",
            "primvars:thickness",
            "primvars:pressure",
            "xformOp:translate"
        ]
    );
    // Topology once per body, local to the body.
    assert_eq!(text.matches("faceVertexIndices").count(), 3);
    assert!(text.contains("int[] faceVertexIndices = [0, 1, 2, 1, 3, 2]"));
    // Samples carry the frame's values: the moving vertex of balloon_1, its pressure, the
    // sphere's centre.
    let (_, points1) = &b[8];
    assert!(points1[7].ends_with("(6, 1, 3.5)],"), "{}", points1[7]);
    assert_eq!(b[11].1[3], "3: 203,");
    assert_eq!(b[12].1[2], "2: (0, 0, 0),");
    assert_eq!(b[0].1[39], "39: 0.39,");
}

#[test]
fn a_changed_topology_is_an_error_naming_the_step() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.usda");
    let mut w = UsdWriter::new(&path, UpAxis::Y);
    w.push(&frame(0)).unwrap();
    let mut f = frame(1);
    f.triangles.pop();
    f.bodies[1].faces = 2..3;
    let e = format!("{:#}", w.push(&f).unwrap_err());
    assert!(e.contains("step 1") && e.contains("topology"), "{e}");
    // The file still holds the first frame.
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(blocks(&text).iter().all(|(_, s)| s.len() == 1));
}

#[test]
fn frames_at_one_time_are_numbered() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.usda");
    let mut w = UsdWriter::new(&path, UpAxis::Y);
    for step in 0..3 {
        let mut f = frame(step);
        f.time = 0.0;
        w.push(&f).unwrap();
    }
    w.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(header(&text, "endTimeCode"), "2");
    assert_eq!(header(&text, "timeCodesPerSecond"), "1");
}

#[test]
fn a_body_with_vertices_of_another_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut f = frame(0);
    f.bodies[0].faces = 0..3;
    let e = format!(
        "{:#}",
        UsdWriter::new(&dir.path().join("run.usda"), UpAxis::Y)
            .push(&f)
            .unwrap_err()
    );
    assert!(e.contains("balloon_0") && e.contains("vertex"), "{e}");
}
