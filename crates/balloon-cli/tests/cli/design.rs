//! `balloon design`: the files it writes, its summary, and its errors.

use crate::run_balloon;

#[test]
fn design_writes_rest_shape_check_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("design");
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--pressure",
        "4000",
        "--thickness",
        "1e-3",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], true);
    assert_eq!(summary["check"]["converged"], true);
    assert!(
        summary["check"]["distance"]["max_relative"]
            .as_f64()
            .unwrap()
            < 1e-4
    );
    // The rest shape encloses less than the target (the gas stretched it).
    assert!(summary["rest_volume"].as_f64().unwrap() < summary["target_volume"].as_f64().unwrap());
    let rest = balloon_mesh::io::read_obj(&out.join("rest.obj")).unwrap();
    let inflated = balloon_mesh::io::read_obj(&out.join("inflated.obj")).unwrap();
    assert_eq!(rest.num_vertices(), 2562);
    assert_eq!(inflated.num_triangles(), rest.num_triangles());
    let csv = std::fs::read_to_string(out.join("distance.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2563);
    // The picture: target and check side by side from one camera; the check is on the target
    // (1e-4 of the diagonal), so the two panels are nearly the same picture.
    assert_eq!(summary["picture"], "design.png");
    let img = balloon_render::Image::read_png(&out.join("design.png")).unwrap();
    assert_eq!((img.width(), img.height()), picture_size());
    assert!(panels_differ(&img) < 0.01, "{}", panels_differ(&img));
}

fn picture_size() -> (u32, u32) {
    use balloon_run::jobs::design::{PICTURE_CAPTION_HEIGHT, PICTURE_PANEL};
    (
        2 * PICTURE_PANEL.0,
        PICTURE_PANEL.1 + PICTURE_CAPTION_HEIGHT,
    )
}

/// Fraction of the pixels of the two panels of `design.png` (below the captions) that differ by
/// more than 8 levels in a channel.
fn panels_differ(img: &balloon_render::Image) -> f64 {
    use balloon_run::jobs::design::{PICTURE_CAPTION_HEIGHT, PICTURE_PANEL};
    let (pw, ph) = PICTURE_PANEL;
    let mut differ = 0usize;
    for y in PICTURE_CAPTION_HEIGHT..PICTURE_CAPTION_HEIGHT + ph {
        for x in 0..pw {
            let (a, b) = (img.get(x, y).unwrap(), img.get(x + pw, y).unwrap());
            differ += usize::from(a.iter().zip(&b).any(|(p, q)| p.abs_diff(*q) > 8));
        }
    }
    differ as f64 / (pw * ph) as f64
}

/// A design that does not converge (a flat-faced box: no rest shape holds its faces flat under
/// pressure) still writes its best design and the picture, whose check is visibly off the
/// target.
#[test]
fn unconverged_design_writes_the_picture_of_the_best_design() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("design");
    let o = design_box(dir.path(), &out, &["--fallback", "off"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("the best design so far is written"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], false);
    assert_eq!(summary["picture"], "design.png");
    let max = summary["check"]["distance"]["max_relative"]
        .as_f64()
        .unwrap();
    assert!(max > 1e-3, "{max}");
    let img = balloon_render::Image::read_png(&out.join("design.png")).unwrap();
    assert_eq!((img.width(), img.height()), picture_size());
    assert!(panels_differ(&img) > 0.02, "{}", panels_differ(&img));
}

#[test]
fn design_errors_name_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--pressure",
        "-5",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--pressure"));
    let o = run_balloon(&[
        "design",
        "no-such-file.obj",
        "--pressure",
        "100",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no-such-file.obj"));
    for (flag, value, why) in [
        ("--method", "newton", "one of \"gauss-newton\" or \"lbfgs\""),
        ("--shape-weight", "-2", "in [0, 1e6]"),
        ("--shape-stages", "1.5", "a whole number from 1 to 20"),
        ("--shape-stages", "many", "a number"),
        ("--thickness-min", "0", "in (0, 1] m"),
        (
            "--thickness-iterations",
            "0",
            "a whole number from 1 to 100000",
        ),
        ("--conditioning-modes", "65", "a whole number from 1 to 64"),
        ("--bending", "-1", "in [0, 1e6]"),
        ("--bending", "nan", "in [0, 1e6]"),
        ("--bending", "inf", "in [0, 1e6]"),
        ("--bending", "2e6", "in [0, 1e6]"),
        (
            "--conditioning-iterations",
            "0",
            "a whole number from 1 to 1000",
        ),
    ] {
        let o = run_balloon(&[
            "design",
            "builtin:icosphere",
            "--pressure",
            "100",
            flag,
            value,
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(flag) && err.contains(why),
            "{flag} {value}: {err}"
        );
    }
}

/// The stated forward check can be repeated: the `balloon inflate` command that `design` prints
/// (and records as `check_command`) inflates the written `rest.obj` to the volume the design's
/// check reports, on a three-prism wall (whose default `inflate --static` thins the wall by the
/// shell-volume projection, which the design does not model).
#[test]
fn design_check_is_repeated_by_the_printed_inflate_command() {
    let dir = tempfile::tempdir().unwrap();
    let summary = design_and_repeat_the_check(dir.path(), &["--pressure", "2000"]);
    // And the check is the target (the design converged onto it).
    let checked = summary["check"]["volume"].as_f64().unwrap();
    let target_volume = summary["target_volume"].as_f64().unwrap();
    assert!(((checked - target_volume) / target_volume).abs() < 1e-6);
    assert!(summary["gas_amount"].is_null());

    // The same target with the load as the amount of ideal gas that holds it at 2 kPa over the
    // atmosphere: the same gauge pressure at the target, a check command with the gas
    // (`--gas ideal`, its gauge pressure at the rest volume), repeated to the same volume.
    let amount = (2000.0 + 101_325.0) * target_volume;
    let gas = dir.path().join("gas");
    std::fs::create_dir_all(&gas).unwrap();
    let with_gas = design_and_repeat_the_check(&gas, &["--gas-amount", &amount.to_string()]);
    let p = with_gas["pressure"].as_f64().unwrap();
    assert!((p - 2000.0).abs() < 1e-8 * 2000.0, "{with_gas}");
    assert_eq!(with_gas["gas_amount"].as_f64(), Some(amount));
    assert_eq!(with_gas["ambient"].as_f64(), Some(101_325.0));
    assert!(
        with_gas["check_command"]
            .as_str()
            .unwrap()
            .contains("--gas ideal --pressure "),
        "{with_gas}"
    );
    let checked = with_gas["check"]["volume"].as_f64().unwrap();
    assert!(((checked - target_volume) / target_volume).abs() < 1e-6);

    // With the wall-thickness fit after an inexact inverse solve (stopped at a relative
    // residual of 0.5, no shape optimisation): the fitted map is written as rest.ply's
    // `thickness` face property, and the printed command inflates rest.ply with it to the
    // check's volume.
    let fit = dir.path().join("fit");
    std::fs::create_dir_all(&fit).unwrap();
    let fitted = design_and_repeat_the_check(
        &fit,
        &[
            "--pressure",
            "2000",
            "--tolerance",
            "0.5",
            "--fallback",
            "off",
            "--fit-thickness",
            "--thickness-iterations",
            "5",
        ],
    );
    let f = &fitted["thickness_fit"];
    assert!(f["iterations"].as_u64().unwrap() >= 1, "{fitted}");
    assert!(
        f["min"].as_f64().unwrap() < f["max"].as_f64().unwrap(),
        "{fitted}"
    );
    assert!(f["end"]["rms"].as_f64().unwrap() < f["start"]["rms"].as_f64().unwrap());
    assert!(
        fitted["check_command"]
            .as_str()
            .unwrap()
            .contains("rest.ply"),
        "{fitted}"
    );
    assert!(fit.join("design/rest.ply").exists());

    // The load is one of the two, and `--ambient` belongs to the gas amount.
    for args in [
        vec!["--pressure", "2000", "--gas-amount", "5000"],
        vec!["--pressure", "2000", "--ambient", "1e5"],
        vec![],
    ] {
        let unused = gas.join("unused");
        let mut all = vec![
            "design",
            "builtin:icosphere",
            "--out",
            unused.to_str().unwrap(),
        ];
        all.extend(args.iter().copied());
        let o = run_balloon(&all);
        assert!(!o.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("--gas-amount") || err.contains("--ambient"),
            "{args:?}: {err}"
        );
    }
    // An amount that does not fill the target above the atmosphere is named.
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--gas-amount",
        "1",
        "--out",
        gas.join("low").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("gas-amount") || err.contains("gas_amount"),
        "{err}"
    );
}

/// The wall of the designs on the inflated icosphere: a neo-Hookean prism, 1 mm.
const PRISM_WALL: [&str; 8] = [
    "--material",
    "neo-hookean",
    "--young",
    "1e6",
    "--poisson",
    "0.45",
    "--thickness",
    "1e-3",
];

/// A target that the [`PRISM_WALL`] at its rest thickness holds exactly at 2 kPa: the built-in
/// icosphere inflated so (statically, without the shell-volume projection) into `dir/made`;
/// returns the path of its `final.obj`.
fn inflated_icosphere_target(dir: &std::path::Path) -> std::path::PathBuf {
    let made = dir.join("made");
    let mut args = vec![
        "inflate",
        "builtin:icosphere",
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "2000",
        "--volume-projection",
        "off",
        "--out",
        made.to_str().unwrap(),
    ];
    args.extend(PRISM_WALL);
    let o = run_balloon(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    made.join("final.obj")
}

/// `balloon design TARGET --rest builtin:icosphere` at 2 kPa with the [`PRISM_WALL`] and a
/// tolerance of 1e-6 into `out`, with the `extra` flags: the icosphere kept as the rest shape
/// of `target` ([`inflated_icosphere_target`]).
fn keep_the_icosphere(
    target: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "design",
        target.to_str().unwrap(),
        "--rest",
        "builtin:icosphere",
        "--pressure",
        "2000",
        "--tolerance",
        "1e-6",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(PRISM_WALL);
    args.extend(extra);
    run_balloon(&args)
}

/// [`keep_the_icosphere`] from a scenario file in `dir` (beside `made/`, with the `extra`
/// `[design]` lines) into `dir/from-file`; returns its `summary.json`.
fn keep_the_icosphere_from_a_scenario(dir: &std::path::Path, extra: &str) -> serde_json::Value {
    let file = dir.join("d.toml");
    std::fs::write(
        &file,
        format!(
            "[design]\ntarget = \"made/final.obj\"\nrest = \"builtin:icosphere\"\n\
             pressure = 2000\ntolerance = 1e-6\n{extra}\
             material = \"neo-hookean\"\nyoung = 1e6\npoisson = 0.45\nthickness = 1e-3\n\
             out = \"from-file\"\n"
        ),
    )
    .unwrap();
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_str(&std::fs::read_to_string(dir.join("from-file/summary.json")).unwrap())
        .unwrap()
}

/// Designs for the sphere that a neo-Hookean prism wall at its rest thickness holds at 2 kPa
/// (inflated so into `dir/made`), with `load` as the load flags, runs the printed check
/// command and checks that it repeats the design's check volume; returns `summary.json`.
fn design_and_repeat_the_check(dir: &std::path::Path, load: &[&str]) -> serde_json::Value {
    let target = inflated_icosphere_target(dir);
    let out = dir.join("design");
    let mut args = vec![
        "design",
        target.to_str().unwrap(),
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(load);
    args.extend(PRISM_WALL);
    let o = run_balloon(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let command = summary["check_command"]
        .as_str()
        .expect("summary.json has no check_command");
    // The command is printed too.
    assert!(String::from_utf8_lossy(&o.stdout).contains(command));
    let words: Vec<&str> = command.split_whitespace().collect();
    assert_eq!(&words[..2], ["balloon", "inflate"], "{command}");
    assert!(!command.contains('\''), "{command}");
    let mut args = words[1..].to_vec();
    args.push("--json");
    let o = run_balloon(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let inflated = crate::last_json_line(&o);
    let repeated = inflated["final_gas_volume"].as_f64().unwrap();
    let checked = summary["check"]["volume"].as_f64().unwrap();
    assert!(
        ((repeated - checked) / checked).abs() < 1e-6,
        "design check {checked:e} m^3, `{command}` {repeated:e} m^3"
    );
    summary
}

/// `balloon run` on a scenario with a `[design]` table runs the job of `balloon design`: the
/// example (the thin neo-Hookean sphere, rest radius 0.1 m / 2^(1/6)) designs the same rest shape, bit
/// for bit, as the command its comment gives.
#[test]
fn design_scenario_runs_the_design_job() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/design-sphere/scenario.toml");
    let file = dir.path().join("scenario.toml");
    std::fs::copy(&example, &file).unwrap();
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("out");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], true, "{summary}");
    let rest = balloon_mesh::io::read_obj(&out.join("rest.obj")).unwrap();
    let radius =
        rest.vertices.iter().map(|p| p.coords.norm()).sum::<f64>() / rest.num_vertices() as f64;
    let analytic = 0.1 / 2f64.powf(1.0 / 6.0);
    assert!(
        ((radius - analytic) / analytic).abs() < 5e-3,
        "rest radius {radius} vs {analytic}"
    );
    let by_flags = dir.path().join("flags");
    let o = run_balloon(&[
        "design",
        "builtin:icosphere",
        "--pressure",
        "4000",
        "--thickness",
        "1e-3",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--quiet",
        "--out",
        by_flags.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(out.join("rest.obj")).unwrap(),
        std::fs::read(by_flags.join("rest.obj")).unwrap()
    );
    // Run again: the folder of the first run is refused, in the file's spelling, until the
    // table says `overwrite = true`.
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("earlier design") && err.contains("overwrite"),
        "{err}"
    );
    let text = std::fs::read_to_string(&file).unwrap() + "overwrite = true\n";
    std::fs::write(&file, text).unwrap();
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn design_scenario_errors_name_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("d.toml");
    let cases = [
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nthickness = -1\n",
            "d.toml:4: `design.thickness`: invalid value '-1'",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npresure = 100\n",
            "d.toml:3: `design.presure`: unknown key",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\n",
            "d.toml:1: `design.pressure`: missing",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\n[run]\nsteps = 3\n",
            "d.toml:4: `run`: a scenario with a [design] table holds only that table",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nmaterial = \"rubber\"\n",
            "d.toml:4: `design.material`: invalid value 'rubber'",
        ),
        (
            "[design]\ntarget = \"no-such.obj\"\npressure = 100\n",
            "no-such.obj",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nfallback = \"sometimes\"\n",
            "d.toml:4: `design.fallback`: invalid value",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nfallback_iterations = 0\n",
            "d.toml:4: `design.fallback_iterations`: invalid value",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\naccept_distance = 2\n",
            "d.toml:4: `design.accept_distance`: invalid value '2': in [0, 1]",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nmethod = \"newton\"\n",
            "d.toml:4: `design.method`: invalid value 'newton': \"gauss-newton\" or \"lbfgs\"",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nnewton_polish = 1\n",
            "d.toml:4: `design.newton_polish`: expected true or false, found an integer",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nshape_stages = 0\n",
            "d.toml:4: `design.shape_stages`: invalid value '0': a whole number from 1 to 20",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nshape_weight = [1]\n",
            "d.toml:4: `design.shape_weight`: expected a single value, found an array",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\ngas_amount = 5e4\n",
            "d.toml:4: `design.gas_amount`: give the key pressure or the key gas_amount, not both",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nambient = 1e5\n",
            "d.toml:4: `design.ambient`: the key ambient is the ambient pressure of the key gas_amount",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\ngas_amount = -1\n",
            "d.toml:3: `design.gas_amount`: invalid value '-1'",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nshape_weight = -1\n",
            "d.toml:4: `design.shape_weight`: invalid value '-1': in [0, 1e6]",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nconditioning = 1\n",
            "d.toml:4: `design.conditioning`: expected true or false, found an integer",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nbending = -1\n",
            "d.toml:4: `design.bending`: invalid value '-1': in [0, 1e6]",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nbending = nan\n",
            "d.toml:4: `design.bending`: invalid value 'nan': in [0, 1e6]",
        ),
        (
            "[design]\ntarget = \"builtin:icosphere\"\npressure = 100\nbending = \"stiff\"\n",
            "d.toml:4: `design.bending`: expected a number",
        ),
    ];
    for (text, expected) in cases {
        std::fs::write(&file, text).unwrap();
        let o = run_balloon(&["run", file.to_str().unwrap()]);
        assert!(!o.status.success(), "{text}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expected), "{text}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// Writes the flat-faced box target `dir/box.obj` (0.1 x 0.08 x 0.06 m) and designs for it at
/// 2 kPa with a 1 mm neo-Hookean membrane (mu 400 kPa) into `out`, with the `extra` flags
/// (and `--quiet`: [`design_box_with_progress`] prints the progress).
fn design_box(
    dir: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    let mut quiet = vec!["--quiet"];
    quiet.extend_from_slice(extra);
    design_box_with_progress(dir, out, &quiet)
}

/// [`design_box`] with its progress on stderr.
fn design_box_with_progress(
    dir: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    let target = dir.join("box.obj");
    let mesh =
        balloon_mesh::generate::box_mesh(nalgebra::Vector3::new(0.1, 0.08, 0.06), 2).unwrap();
    balloon_mesh::io::write_obj(&target, &mesh).unwrap();
    let mut args = vec![
        "design",
        target.to_str().unwrap(),
        "--pressure",
        "2000",
        "--thickness",
        "1e-3",
        "--material",
        "membrane-neo-hookean",
        "--mu",
        "4e5",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    run_balloon(&args)
}

/// A flat-faced target has no exact design: the inverse does not converge, the shape
/// optimisation runs, prints the distance before and after, records it in `summary.json`,
/// and the design still ends as not converged, with the remaining distance in the error.
#[test]
fn design_of_a_flat_faced_box_runs_the_shape_optimisation() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("design");
    let o = design_box(dir.path(), &out, &["--fallback-iterations", "8"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stdout}");
    assert!(stdout.contains("shape optimisation: "), "{stdout}");
    assert!(
        stderr.contains("its forward equilibrium lies within"),
        "{stderr}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["converged"], false);
    let f = &summary["inverse"]["fallback"];
    let rms = |d: &serde_json::Value| d["rms"].as_f64().unwrap();
    assert!(f["iterations"].as_u64().unwrap() >= 1, "{f}");
    assert!(f["iterations"].as_u64().unwrap() <= 8, "{f}");
    assert!(rms(&f["end"]) < rms(&f["start"]), "{f}");
    let check = rms(&summary["check"]["distance"]);
    assert!(
        (check - rms(&f["end"])).abs() <= 1e-6 * check,
        "{check} vs {f}"
    );
}

/// `--accept-distance` accepts a design whose inverse has no exact answer when its forward
/// check lies within that fraction of the diagonal: the flat-faced box's design ends without
/// the error and says so, `summary.json` has `accepted` (and still `converged = false`); a
/// distance below the check's keeps the error, which names it.
#[test]
fn a_design_within_the_accepted_distance_ends_without_the_error() {
    let dir = tempfile::tempdir().unwrap();
    let read = |out: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
    };
    let near = dir.path().join("near");
    let o = design_box(
        dir.path(),
        &near,
        &["--fallback-iterations", "2", "--accept-distance", "0.5"],
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("design accepted: "), "{stdout}");
    let s = read(&near);
    let reached = s["check"]["distance"]["max_relative"].as_f64().unwrap();
    assert!(reached > 1e-9 && reached <= 0.5, "{s}");
    assert_eq!(
        (&s["converged"], &s["accepted"]),
        (&serde_json::json!(false), &serde_json::json!(true)),
        "{s}"
    );
    assert_eq!(s["params"]["accept_distance"], 0.5, "{s}");
    // A distance below the one reached: the error, naming the distance asked for.
    let far = dir.path().join("far");
    let o = design_box(
        dir.path(),
        &far,
        &["--fallback-iterations", "2", "--accept-distance", "1e-9"],
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("outside `accept_distance` = 1e-9"),
        "{stderr}"
    );
    assert_eq!(read(&far)["accepted"], false);
    // Without it, the error says what would accept a near design.
    let plain = dir.path().join("plain");
    let o = design_box(dir.path(), &plain, &["--fallback-iterations", "2"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("`accept_distance` accepts a design"),
        "{stderr}"
    );
}

/// When the shape optimisation begins, the human progress says once why, what it costs and
/// what else to ask for (`accept_distance`, and `bending` for a wall without it), before its
/// first step.
#[test]
fn the_shape_optimisation_says_why_it_runs_when_it_begins() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("box");
    let o = design_box_with_progress(dir.path(), &out, &["--fallback-iterations", "1"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    let notice = "design: the inverse found no exact design; the shape optimisation now";
    assert_eq!(stderr.matches(notice).count(), 1, "{stderr}");
    let at = stderr.find(notice).unwrap();
    let step = stderr
        .find("design: shape optimisation step 1")
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(at < step, "{stderr}");
    let line = stderr[at..].lines().next().unwrap();
    assert!(
        line.contains("steps: at most 1,")
            && line.contains("`accept_distance`")
            && line.contains("`bending` = 1"),
        "{line}"
    );
    // Before it, the inverse said once, at its first halving, what the continuation does: a
    // flat-faced box holds no fraction of the pressure, so halving never makes a stage easier
    // and the continuation ends after three failed stages instead of twelve halvings.
    let halving = "design: the stage to pressure factor 1.000 did not converge in 60 iterations";
    assert_eq!(stderr.matches(halving).count(), 1, "{stderr}");
    let first_half = stderr
        .find("stage to 0.500")
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(stderr.find(halving).unwrap() < first_half, "{stderr}");
    assert!(stderr.find(halving).unwrap() < at, "{stderr}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let inverse = &summary["inverse"];
    assert_eq!(inverse["no_easier"], true, "{inverse}");
    assert_eq!(inverse["halvings"], 2, "{inverse}");
    assert!(!stderr.contains("stage to 0.125"), "{stderr}");
}

/// The shape optimisation's options reach the library from the flags and from a scenario's
/// `[design]` table alike: the run's record shows the outer loop and the stages they asked for
/// (L-BFGS takes no Gauss-Newton step; the shape term's stages are counted by the optimisation
/// itself), `summary.json` lists them under `params`, and the two front ends write the same
/// rest shape.
#[test]
fn design_options_reach_the_shape_optimisation_from_flags_and_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let by_flags = dir.path().join("flags");
    let o = design_box(
        dir.path(),
        &by_flags,
        &[
            "--fallback-iterations",
            "2",
            "--method",
            "lbfgs",
            "--shape-weight",
            "1",
            "--shape-stages",
            "2",
            "--bending-weight",
            "0.5",
            "--inverse-bending-stages",
            "4",
            "--warm-start",
        ],
    );
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("shape optimisation: "),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let read = |out: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
    };
    let summary = read(&by_flags);
    let p = &summary["params"]["fallback"];
    assert_eq!(p["method"], "lbfgs", "{p}");
    assert_eq!(p["shape_weight"], 1.0, "{p}");
    assert_eq!(p["shape_stages"], 2, "{p}");
    assert_eq!(p["warm_start"], true, "{p}");
    assert_eq!(p["newton_polish"], false, "{p}");
    assert_eq!(p["max_iterations"], 2, "{p}");
    assert_eq!(p["bending_weight"], 0.5, "{p}");
    assert_eq!(summary["params"]["inverse"]["bending_stages"], 4);
    // `--warm-start` is the thickness fit's too.
    assert_eq!(summary["params"]["thickness"]["warm_start"], true);
    let f = &summary["inverse"]["fallback"];
    assert_eq!(f["gauss_newton_steps"], 0, "{f}");
    assert_eq!(f["shape_stages"], 2, "{f}");
    // Two stages with the term and the last without it, each at most 2 steps.
    assert!(f["iterations"].as_u64().unwrap() <= 6, "{f}");

    let file = dir.path().join("d.toml");
    std::fs::write(
        &file,
        "[design]\ntarget = \"box.obj\"\npressure = 2000\nthickness = 1e-3\n\
         material = \"membrane-neo-hookean\"\nmu = 4e5\nfallback_iterations = 2\n\
         method = \"lbfgs\"\nshape_weight = 1\nshape_stages = 2\nwarm_start = true\n\
         bending_weight = 0.5\ninverse_bending_stages = 4\n\
         out = \"scenario\"\n",
    )
    .unwrap();
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("shape optimisation: "),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let by_scenario = dir.path().join("scenario");
    assert_eq!(read(&by_scenario)["params"], summary["params"]);
    assert_eq!(
        std::fs::read(by_scenario.join("rest.obj")).unwrap(),
        std::fs::read(by_flags.join("rest.obj")).unwrap()
    );
}

/// `--rest FILE` keeps a given rest shape instead of designing one: the icosphere that a
/// neo-Hookean prism wall inflates onto the target holds it (residual near zero, no inverse
/// iterations, the check on the target, exit 0); a rest shape with other vertices is refused
/// with both counts; a scenario's `rest` key does the same as the flag.
#[test]
fn a_given_rest_shape_is_kept_checked_and_refused_when_it_does_not_match() {
    let dir = tempfile::tempdir().unwrap();
    let target = inflated_icosphere_target(dir.path());
    let out = dir.path().join("kept");
    let o = keep_the_icosphere(&target, &out, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    // The target was written by a static solve to its default tolerance, so it is an
    // equilibrium of the icosphere to about 1e-7.
    assert!(stdout.contains("within the design tolerance"), "{stdout}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(
        summary["inverse"]["iterations"].as_u64(),
        Some(0),
        "{summary}"
    );
    assert!(
        summary["inverse"]["relative_residual"].as_f64().unwrap() < 1e-6,
        "{summary}"
    );
    assert!(
        summary["check"]["distance"]["max_relative"]
            .as_f64()
            .unwrap()
            < 1e-6
    );
    // The rest shape written is the one given.
    let given = balloon_mesh::builtin::builtin("icosphere").unwrap();
    let written = balloon_mesh::io::read_mesh(&out.join("rest.obj")).unwrap();
    let gap = given
        .vertices
        .iter()
        .zip(&written.vertices)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(gap < 1e-9, "{gap:e}");

    // Another mesh as the rest shape: both counts named.
    let bad = dir.path().join("bad");
    let mut args = vec![
        "design",
        target.to_str().unwrap(),
        "--rest",
        "builtin:teddy",
        "--pressure",
        "2000",
        "--out",
        bad.to_str().unwrap(),
    ];
    args.extend(PRISM_WALL);
    let o = run_balloon(&args);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("vertices") && err.contains("target's vertices"),
        "{err}"
    );

    // The scenario key.
    let from_file = keep_the_icosphere_from_a_scenario(dir.path(), "");
    assert_eq!(from_file["inverse"]["iterations"].as_u64(), Some(0));
    assert_eq!(
        std::fs::read(out.join("rest.obj")).unwrap(),
        std::fs::read(dir.path().join("from-file/rest.obj")).unwrap()
    );
}

/// `--conditioning` (and the scenario key `conditioning`) reports how well the target
/// determines the rest shape: on the icosphere kept as the rest of its own inflated target,
/// six singular values of `dr/dX` outside the rigid motions, ascending, positive, over the
/// largest as `relative`, with the forward gain of each; the printed line names them. Without
/// the flag the record is null.
#[test]
fn the_rest_shape_conditioning_is_reported_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let target = inflated_icosphere_target(dir.path());
    let design = |out: &std::path::Path, extra: &[&str]| {
        let o = keep_the_icosphere(&target, out, extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        (String::from_utf8_lossy(&o.stdout).into_owned(), summary)
    };
    let (stdout, summary) = design(&dir.path().join("with"), &["--conditioning"]);
    assert!(
        stdout.contains("rest-shape conditioning: the 6 smallest"),
        "{stdout}"
    );
    let c = &summary["conditioning"];
    let numbers = |key: &str| -> Vec<f64> {
        c[key]
            .as_array()
            .unwrap_or_else(|| panic!("{key}: {c}"))
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let smallest = numbers("smallest");
    let largest = c["largest"].as_f64().unwrap();
    assert_eq!(smallest.len(), 6, "{c}");
    assert!(
        smallest[0] > 0.0 && smallest.windows(2).all(|w| w[0] <= w[1]),
        "{c}"
    );
    assert!(smallest[5] < largest, "{c}");
    for (r, s) in numbers("relative").iter().zip(&smallest) {
        assert!(
            (r - s / largest).abs() <= 1e-12 * r.abs().max(1e-300),
            "{c}"
        );
    }
    let gains = numbers("forward_gain");
    assert_eq!(gains.len(), 6, "{c}");
    assert!(gains.iter().all(|g| *g > 0.0 && *g < 10.0), "{c}");
    // The singular vectors: one row per vertex, three columns per mode, unit norm each.
    assert_eq!(summary["conditioning_modes"], "conditioning_modes.csv");
    let csv = std::fs::read_to_string(dir.path().join("with/conditioning_modes.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 1 + 3 * 6, "{header:?}");
    assert_eq!(header[1], "mode_1_x");
    let mut norms = [0.0f64; 6];
    let mut rows = 0;
    for line in lines {
        let values: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|v| v.parse().unwrap())
            .collect();
        for (k, n) in norms.iter_mut().enumerate() {
            *n += values[3 * k..3 * k + 3].iter().map(|x| x * x).sum::<f64>();
        }
        rows += 1;
    }
    assert_eq!(rows, summary["vertices"].as_u64().unwrap() as usize);
    assert!(norms.iter().all(|n| (n - 1.0).abs() < 1e-9), "{norms:?}");
    // Without the flag: no record, no line.
    let (stdout, summary) = design(&dir.path().join("without"), &[]);
    assert!(summary["conditioning"].is_null(), "{summary}");
    assert!(summary["conditioning_modes"].is_null(), "{summary}");
    assert!(!dir.path().join("without/conditioning_modes.csv").exists());
    assert!(!stdout.contains("conditioning"), "{stdout}");
    // The scenario key does the same (the same numbers: the computation is deterministic).
    let from_file = keep_the_icosphere_from_a_scenario(dir.path(), "conditioning = true\n");
    assert_eq!(from_file["conditioning"]["smallest"], c["smallest"]);
}

/// `--bending F` (and the `[design]` key `bending`) designs with the wall's bending stiffness:
/// on the icosphere that a prism wall with `--bending 1` inflates to at 2 kPa, the flag and the
/// key record `wall_bending` and give the same rest shape; the printed check command carries
/// `--bending 1` and inflates the written rest shape to the check's volume; the design without
/// the flag is another rest shape.
#[test]
fn the_bending_wall_reaches_the_design_from_flag_and_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let made = dir.path().join("made");
    let mut args = vec![
        "inflate",
        "builtin:icosphere",
        "--static",
        "--gas",
        "constant",
        "--pressure",
        "2000",
        "--volume-projection",
        "off",
        "--bending",
        "1",
        "--out",
        made.to_str().unwrap(),
    ];
    args.extend(PRISM_WALL);
    let o = run_balloon(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let target = made.join("final.obj");
    let design = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "design",
            target.to_str().unwrap(),
            "--pressure",
            "2000",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(PRISM_WALL);
        args.extend(extra);
        let o = run_balloon(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o
    };
    let read = |out: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
    };
    let by_flag = dir.path().join("flag");
    let o = design(&by_flag, &["--bending", "1"]);
    let summary = read(&by_flag);
    assert_eq!(summary["params"]["wall_bending"], 1.0, "{summary}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let command = stdout
        .lines()
        .find_map(|l| l.strip_prefix("repeat the check: "))
        .expect("a check command");
    assert!(command.ends_with("--bending 1"), "{command}");
    let words: Vec<&str> = command.split_whitespace().collect();
    let mut args = words[1..].to_vec();
    args.push("--json");
    let o = run_balloon(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let repeated = crate::last_json_line(&o)["final_gas_volume"]
        .as_f64()
        .unwrap();
    let checked = summary["check"]["volume"].as_f64().unwrap();
    assert!(
        ((repeated - checked) / checked).abs() < 1e-6,
        "design check {checked:e} m^3, `{command}` {repeated:e} m^3"
    );

    let file = dir.path().join("d.toml");
    std::fs::write(
        &file,
        "[design]\ntarget = \"made/final.obj\"\npressure = 2000\nbending = 1\n\
         material = \"neo-hookean\"\nyoung = 1e6\npoisson = 0.45\nthickness = 1e-3\n\
         out = \"scenario\"\n",
    )
    .unwrap();
    let o = run_balloon(&["run", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let by_scenario = dir.path().join("scenario");
    assert_eq!(read(&by_scenario)["params"], summary["params"]);
    let rest = std::fs::read(by_flag.join("rest.obj")).unwrap();
    assert_eq!(std::fs::read(by_scenario.join("rest.obj")).unwrap(), rest);

    let plain = dir.path().join("plain");
    design(&plain, &[]);
    assert_eq!(read(&plain)["params"]["wall_bending"], 0.0);
    assert_ne!(std::fs::read(plain.join("rest.obj")).unwrap(), rest);
}

#[test]
fn a_folder_of_an_earlier_design_is_refused_unless_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d");
    let design = |extra: &[&str]| {
        let mut args = vec![
            "design",
            "builtin:icosphere",
            "--pressure",
            "100",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        run_balloon(&args)
    };
    let o = design(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rest = std::fs::read(out.join("rest.obj")).unwrap();
    // A file of the user's beside the design, and one of the design's names that this design
    // does not write (no --conditioning).
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("conditioning_modes.csv"), "vertex\n").unwrap();

    // Again into the same folder: refused, naming the folder and the flag, nothing changed.
    let o = design(&["--tolerance", "1e-6"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains(&out.display().to_string())
            && err.contains("earlier design")
            && err.contains("--overwrite"),
        "{err}"
    );
    assert_eq!(std::fs::read(out.join("rest.obj")).unwrap(), rest);
    assert!(out.join("conditioning_modes.csv").exists());

    // With --overwrite: the design's files are replaced, the stale one removed, the user's kept.
    let o = design(&["--tolerance", "1e-6", "--overwrite"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(!out.join("conditioning_modes.csv").exists());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["params"]["inverse"]["tolerance"], 1e-6);
    // No temporary file is left behind.
    for entry in std::fs::read_dir(&out).unwrap() {
        let name = entry.unwrap().file_name();
        assert!(!name.to_string_lossy().ends_with(".tmp"), "{name:?}");
    }

    // A rest shape read from the folder is an input: never replaced, even with --overwrite.
    let kept = out.join("rest.obj");
    let o = design(&["--rest", kept.to_str().unwrap(), "--overwrite"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("an input of this design"), "{err}");
}
