//! Pictures and standard outputs (issue 7): `--format vtk` (.vtp + series.pvd), `--render`,
//! `--gif`, `--pov`, `--color`, `--image-size`, and their errors.

use super::run_balloon;
use balloon_mesh::io::{read_pvd, read_vtp};
use balloon_render::Image;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// A small closed sphere (162 vertices, 320 triangles) written as OBJ into `dir`.
fn small_sphere(dir: &Path) -> PathBuf {
    let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let path = dir.join("sphere.obj");
    balloon_mesh::io::write_obj(&path, &mesh).unwrap();
    path
}

fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Distinct colours, and the fraction of the left 75% (the body's viewport without the legend)
/// that differs from the background (the top-left pixel).
fn content(img: &Image) -> (usize, f64) {
    let colours: HashSet<&[u8]> = img.pixels().chunks(3).collect();
    let bg = img.get(0, img.height() - 1).unwrap();
    let (w, h) = (img.width() * 3 / 4, img.height());
    let mut body = 0;
    for y in 0..h {
        for x in 0..w {
            body += usize::from(img.get(x, y) != Some(bg));
        }
    }
    (colours.len(), body as f64 / (w * h) as f64)
}

/// Whether the colour bar is drawn: the unshaded ends of the viridis map appear in the right
/// 40% of the image (shaded body pixels practically never hit them exactly).
fn legend_drawn(img: &Image) -> bool {
    let ends = [
        balloon_render::ColorMap::Viridis.eval_u8(0.0),
        balloon_render::ColorMap::Viridis.eval_u8(1.0),
    ];
    ends.iter().all(|c| {
        (img.width() * 6 / 10..img.width())
            .any(|x| (0..img.height()).any(|y| img.get(x, y) == Some(*c)))
    })
}

#[test]
fn inflate_writes_vtk_series_pngs_gif_and_pov() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let out_dir = dir.path().join("run");
    let out = run_balloon(&[
        "inflate",
        mesh.to_str().unwrap(),
        "--steps",
        "4",
        "--frame-every",
        "2",
        "--dt",
        "0.02",
        "--format",
        "vtk",
        "--render",
        "0,3,last",
        "--color",
        "stretch",
        "--gif",
        "--pov",
        "--image-size",
        "200x150",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    ok(&out);

    // VTK: frames 0, 2, 4 listed with their times; fields with the right counts and values.
    let series = read_pvd(&out_dir.join("series.pvd")).unwrap();
    let files: Vec<&str> = series.iter().map(|e| e.file.as_str()).collect();
    assert_eq!(
        files,
        ["frame_00000.vtp", "frame_00002.vtp", "frame_00004.vtp"]
    );
    for (e, t) in series.iter().zip([0.0, 0.04, 0.08]) {
        assert!((e.time - t).abs() < 1e-12, "{} at {}", e.file, e.time);
    }
    let first = read_vtp(&out_dir.join("frame_00000.vtp")).unwrap();
    let last = read_vtp(&out_dir.join("frame_00004.vtp")).unwrap();
    assert_eq!(last.positions.len(), 3 * 162);
    assert_eq!(last.triangles.len(), 320);
    for (name, comps) in [("velocity", 3), ("speed", 1), ("pressure_force", 3)] {
        let (c, v) = &last.point_data[name];
        assert_eq!((*c, v.len()), (comps, comps * 162), "{name}");
    }
    for name in ["thickness", "stretch", "max_stretch"] {
        assert_eq!(last.cell_data[name].1.len(), 320, "{name}");
    }
    // At rest nothing moves and nothing is stretched; after 4 pump steps the sphere grew.
    assert!(first.point_data["speed"].1.iter().all(|&s| s == 0.0));
    assert!(
        first.cell_data["stretch"]
            .1
            .iter()
            .all(|&s| (s - 1.0).abs() < 1e-12)
    );
    let stretch = &last.cell_data["stretch"].1;
    assert!(stretch.iter().all(|&s| s > 1.0 && s < 2.0), "{stretch:?}");
    // speed = |velocity|, and a uniform pressure has no resultant on a closed surface.
    let (_, v) = &last.point_data["velocity"];
    for (i, s) in last.point_data["speed"].1.iter().enumerate() {
        let n = (v[3 * i].powi(2) + v[3 * i + 1].powi(2) + v[3 * i + 2].powi(2)).sqrt();
        assert!((n - s).abs() <= 1e-12 * n.max(1.0));
    }
    let f = &last.point_data["pressure_force"].1;
    let scale: f64 = f.iter().map(|c| c.abs()).sum();
    assert!(scale > 0.0);
    for k in 0..3 {
        let r: f64 = f.iter().skip(k).step_by(3).sum();
        assert!(r.abs() < 1e-9 * scale, "resultant {k}: {r}");
    }
    // Thickness mean matches the summary.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    let th = &last.cell_data["thickness"].1;
    let mean = th.iter().sum::<f64>() / th.len() as f64;
    let expect = summary["final_thickness_mean"].as_f64().unwrap();
    assert!((mean - expect).abs() < 1e-12 * expect, "{mean} vs {expect}");

    // PNGs: the asked steps (3 is not a frame step but is rendered anyway), right size,
    // non-trivial content, a legend, and growth between the first and the last.
    let renders = out_dir.join("renders");
    let mut names: Vec<String> = std::fs::read_dir(&renders)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["frame_00000.png", "frame_00003.png", "frame_00004.png"]
    );
    let a = Image::read_png(&renders.join("frame_00000.png")).unwrap();
    let b = Image::read_png(&renders.join("frame_00004.png")).unwrap();
    for img in [&a, &b] {
        assert_eq!((img.width(), img.height()), (200, 150));
        let (colours, body) = content(img);
        assert!(colours > 40, "{colours} colours");
        assert!(body > 0.15 && body < 0.9, "body fraction {body}");
        assert!(legend_drawn(img));
    }
    let differing = a
        .pixels()
        .chunks(3)
        .zip(b.pixels().chunks(3))
        .filter(|(p, q)| p != q)
        .count();
    assert!(differing > 1000, "{differing} pixels differ");

    // GIF: one frame per written frame, right size, frames differ.
    let frames = balloon_render::read_gif(&out_dir.join("run.gif")).unwrap();
    assert_eq!(frames.len(), 3);
    for (img, delay) in &frames {
        assert_eq!((img.width(), img.height()), (200, 150));
        assert!(*delay >= 4);
        let (colours, body) = content(img);
        assert!(
            colours > 20 && body > 0.05,
            "{colours} colours, body {body}"
        );
    }
    // Same framing in every frame: the growing balloon covers more pixels at the end.
    let (_, body0) = content(&frames[0].0);
    let (_, body2) = content(&frames[2].0);
    assert!(body2 > body0, "{body0} -> {body2}");

    // POV: counts of the mesh2 blocks.
    let pov = std::fs::read_to_string(out_dir.join("final.pov")).unwrap();
    for (block, n) in [
        ("vertex_vectors", 162),
        ("normal_vectors", 162),
        ("texture_list", 162),
        ("face_indices", 320),
    ] {
        assert!(
            pov.contains(&format!("{block} {{ {n},")),
            "{block} {n} missing"
        );
    }
    assert!(pov.contains("camera {") && pov.contains("light_source"));
}

#[test]
fn volumetric_and_two_layer_pictures_with_their_default_colours() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("vol");
    let out = run_balloon(&[
        "volumetric",
        "builtin:sphere",
        "--resolution",
        "8",
        "--scene",
        "free",
        "--steps",
        "4",
        "--frame-every",
        "2",
        "--format",
        "vtk",
        "--render",
        "all",
        "--image-size",
        "160x120",
        "--out",
        vol.to_str().unwrap(),
        "--json",
    ]);
    ok(&out);
    let last = read_vtp(&vol.join("frame_00004.vtp")).unwrap();
    assert!(last.point_data.contains_key("velocity") && last.cell_data.contains_key("stretch"));
    // Free fall for 4 steps: every vertex moves down at about g t.
    let (_, v) = &last.point_data["velocity"];
    assert!(v.iter().skip(2).step_by(3).all(|&vz| vz < 0.0));
    for step in [0, 2, 4] {
        let img = Image::read_png(&vol.join(format!("renders/frame_{step:05}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (160, 120));
        assert!(legend_drawn(&img), "stretch legend at step {step}");
    }

    let tl = dir.path().join("tl");
    let out = run_balloon(&[
        "two-layer",
        "--dim",
        "2",
        "--steps",
        "20",
        "--frame-every",
        "10",
        "--render",
        "last",
        "--gif",
        "--image-size",
        "160x120",
        "--out",
        tl.to_str().unwrap(),
        "--json",
    ]);
    ok(&out);
    let img = Image::read_png(&tl.join("renders/frame_00020.png")).unwrap();
    let (colours, body) = content(&img);
    assert!(
        colours > 10 && body > 0.05,
        "{colours} colours, body {body}"
    );
    assert_eq!(
        balloon_render::read_gif(&tl.join("run.gif")).unwrap().len(),
        3
    );
}

#[test]
fn a_failing_run_still_leaves_its_pictures_and_reports_the_error() {
    let dir = tempfile::tempdir().unwrap();
    // Springs far too stiff for the explicit step: blows up after a few dozen steps.
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
        "--frame-every",
        "5",
        "--format",
        "vtk",
        "--render",
        "all,last",
        "--gif",
        "--pov",
        "--image-size",
        "96x72",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("blew up"), "{err}");
    let series = read_pvd(&dir.path().join("series.pvd")).unwrap();
    assert!(!series.is_empty());
    for e in &series {
        read_vtp(&dir.path().join(&e.file)).unwrap();
        let png = dir
            .path()
            .join("renders")
            .join(e.file.replace(".vtp", ".png"));
        let img = Image::read_png(&png).unwrap();
        assert_eq!((img.width(), img.height()), (96, 72));
    }
    let gif = balloon_render::read_gif(&dir.path().join("run.gif")).unwrap();
    assert_eq!(gif.len(), series.len(), "one GIF frame per written frame");
    assert!(dir.path().join("final.pov").is_file());
}

#[test]
fn bad_picture_flags_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("o");
    let o = out_dir.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["inflate", "builtin:sphere", "--render", "last"],
            "--render needs --out",
        ),
        (
            vec!["inflate", "builtin:sphere", "--gif"],
            "--gif needs --out",
        ),
        (vec!["two-layer", "--pov"], "--pov needs --out"),
        (
            vec!["inflate", "builtin:sphere", "--render", "first", "--out", o],
            "invalid --render `first`",
        ),
        (
            vec!["inflate", "builtin:sphere", "--render", "1,,2", "--out", o],
            "step number",
        ),
        (
            vec![
                "volumetric",
                "builtin:sphere",
                "--color",
                "thickness",
                "--render",
                "last",
                "--out",
                o,
            ],
            "invalid --color thickness",
        ),
        (
            vec!["two-layer", "--dim", "1", "--render", "last", "--out", o],
            "--dim 2 or 3",
        ),
        (
            vec![
                "inflate",
                "builtin:sphere",
                "--image-size",
                "10x10",
                "--out",
                o,
            ],
            "640x480",
        ),
        (
            vec![
                "inflate",
                "builtin:sphere",
                "--color-range",
                "2:1",
                "--out",
                o,
            ],
            "expected full, robust or MIN:MAX",
        ),
    ];
    for (args, expect) in cases {
        let out = run_balloon(&args);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(expect),
            "{args:?}: expected `{expect}` in: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(
        !out_dir.exists(),
        "nothing is written when the flags are rejected"
    );
    let help = run_balloon(&["inflate", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--render",
        "--gif",
        "--pov",
        "--color",
        "--image-size",
        "vtk",
    ] {
        assert!(help.contains(flag), "--help lacks {flag}");
    }
}

#[test]
fn color_range_full_robust_and_fixed() {
    // A sphere inflated for 3 steps, coloured by stretch. A fixed range below every value
    // paints the body in the top (yellow: green above blue) colour, one above every value in
    // the bottom (purple: blue above green) colour (measured: 92% and 0.5% of the body pixels
    // have green above blue; edges and highlights make up the rest); `full` and `robust` span
    // the values, so both hues appear (which values `robust` leaves out is unit-tested).
    let dir = tempfile::tempdir().unwrap();
    let mesh = small_sphere(dir.path());
    let picture = |range: &str| {
        let out_dir = dir.path().join(format!("run-{}", range.replace(':', "_")));
        let out = run_balloon(&[
            "inflate",
            mesh.to_str().unwrap(),
            "--steps",
            "3",
            "--color",
            "stretch",
            "--color-range",
            range,
            "--render",
            "last",
            "--image-size",
            "160x120",
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        ok(&out);
        Image::read_png(&out_dir.join("renders").join("frame_00003.png")).unwrap()
    };
    // Body pixels (left 75%, not background) with green above blue, and all body pixels.
    let greenish = |img: &Image| {
        let bg = img.get(0, img.height() - 1).unwrap();
        let (mut g, mut n) = (0, 0);
        for y in 0..img.height() {
            for x in 0..img.width() * 3 / 4 {
                let c = img.get(x, y).unwrap();
                if c != bg {
                    n += 1;
                    g += usize::from(c[1] > c[2]);
                }
            }
        }
        assert!(n > 500, "the body covers only {n} pixels");
        g as f64 / n as f64
    };
    let below = greenish(&picture("0.1:0.2"));
    let above = greenish(&picture("10:20"));
    assert!(
        below > 0.8,
        "values above the range: {below} of the body yellow-green"
    );
    assert!(
        above < 0.2,
        "values below the range: {above} of the body yellow-green"
    );
    for range in ["full", "robust"] {
        let g = greenish(&picture(range));
        assert!((0.02..0.98).contains(&g), "{range}: {g}");
    }
}

#[test]
fn volumetric_pictures_draw_the_sphere_above_the_body_and_the_floor() {
    // A plain red body (--color none): the steel-blue sphere's pixels are the only ones with
    // blue well above red, and the grey floor the only ones with red, green and blue close
    // together below the background; in the free scene neither appears.
    let dir = tempfile::tempdir().unwrap();
    let picture = |scene: &str| {
        let out = dir.path().join(scene);
        ok(&run_balloon(&[
            "volumetric",
            "builtin:icosphere",
            "--resolution",
            "12",
            "--voxels-per-cell",
            "2",
            "--scene",
            scene,
            "--steps",
            "10",
            "--frame-every",
            "10",
            "--color",
            "none",
            "--render",
            "last",
            "--gif",
            "--image-size",
            "200x150",
            "--out",
            out.to_str().unwrap(),
        ]));
        assert!(out.join("run.gif").is_file());
        Image::read_png(&out.join("renders/frame_00010.png")).unwrap()
    };
    let count = |img: &Image| {
        let (mut ball, mut ball_rows, mut floor, mut body_rows) = (0, Vec::new(), 0, Vec::new());
        for y in 0..img.height() {
            for x in 0..img.width() {
                let [r, g, b] = img.get(x, y).unwrap().map(i32::from);
                if b > r + 25 {
                    ball += 1;
                    ball_rows.push(y);
                } else if r > g + 60 {
                    body_rows.push(y);
                } else if (r - b).abs() < 30 && r < 200 && r > 60 {
                    floor += 1;
                }
            }
        }
        let mean = |v: &[u32]| v.iter().map(|&y| f64::from(y)).sum::<f64>() / v.len().max(1) as f64;
        (ball, mean(&ball_rows), floor, mean(&body_rows))
    };
    let (ball, ball_y, floor, body_y) = count(&picture("drop-sphere"));
    assert!(
        ball > 300 && floor > 300,
        "sphere {ball} px, floor {floor} px"
    );
    assert!(
        ball_y < body_y,
        "the sphere is drawn above the body: rows {ball_y} vs {body_y}"
    );
    let (ball, _, floor, _) = count(&picture("free"));
    assert_eq!((ball, floor), (0, 0));
}
