//! Anchors (`--pin`) and loads (`--load`) of the volumetric and two-layer bodies, measured on
//! the simulation the command ran.

use crate::run_balloon;
use balloon_cli::cmd_volumetric::{build, execute};

/// A small free icosphere body (about 200 cells).
const BODY: &[&str] = &[
    "builtin:icosphere",
    "--resolution",
    "10",
    "--voxels-per-cell",
    "2",
    "--scene",
    "free",
];

fn volumetric(extra: &[&str]) -> balloon_cli::cmd_volumetric::VolumetricArgs {
    let mut argv = BODY.to_vec();
    argv.extend_from_slice(extra);
    super::volumetric_args(&argv)
}

#[test]
fn a_volumetric_body_pinned_at_its_bottom_hangs_without_moving_its_pins() {
    // Where the lattice's bottom layer is: the pins are the particles within 0.3 cells of it.
    let probe = build(&volumetric(&[]), None).unwrap().sim;
    let rest = probe.lattice().tet_mesh.vertices.clone();
    let cell = probe.lattice().info.cell_size;
    let bottom = rest.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let below = format!("below:z:{}", bottom + 0.3 * cell);
    let pinned: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i].z < bottom + 0.3 * cell)
        .collect();
    assert!(
        pinned.len() >= 4 && pinned.len() < rest.len() / 4,
        "{}",
        pinned.len()
    );
    for solver in ["global", "gauss-seidel"] {
        let args = volumetric(&["--pin", &below, "--steps", "500", "--volume-solver", solver]);
        let done = execute(&args, None, true).unwrap();
        let sim = &done.sim;
        let summary = done.summary.unwrap();
        // Not a femtometre of motion: the pinned particles are exactly at rest.
        for &i in &pinned {
            assert_eq!(
                sim.positions()[i],
                rest[i],
                "{solver}: pinned particle {i} moved"
            );
        }
        assert_eq!(
            sim.fixed_particles().iter().filter(|&&f| f).count(),
            pinned.len()
        );
        // The rest hangs from them: without the pins the body would have fallen
        // g t^2 / 2 (here about 1.2 m); pinned, its top sags by a small fraction of a cell.
        let t = sim.time();
        let top = (0..rest.len())
            .max_by(|&a, &b| rest[a].z.total_cmp(&rest[b].z))
            .unwrap();
        let sag = rest[top].z - sim.positions()[top].z;
        let free_fall = 0.5 * 9.81 * t * t;
        assert!(
            sag > 0.0 && sag < 0.5 * cell && sag < 0.01 * free_fall,
            "{solver}: top sagged {sag:e} m (cell {cell} m, free fall {free_fall} m)"
        );
        let com_rest = rest.iter().map(|p| p.z).sum::<f64>() / rest.len() as f64;
        let com = sim.positions().iter().map(|p| p.z).sum::<f64>() / rest.len() as f64;
        assert!(
            com < com_rest,
            "{solver}: the body does not sag ({com} vs {com_rest})"
        );
        let error = summary["max_cell_volume_error"].as_f64().unwrap();
        assert!(error <= 1e-10, "{solver}: cell volume error {error:e}");
        let ratio = summary["total_volume_ratio"].as_f64().unwrap();
        assert!((ratio - 1.0).abs() < 1e-9, "{solver}: volume ratio {ratio}");
    }
}

#[test]
fn a_constant_force_on_a_particle_group_moves_the_centre_of_mass_by_its_impulse() {
    // 0.5 N in total on the particles of the upper half, no gravity, no floor: the momentum
    // grows by F t exactly (the springs and volume impulses are internal), so the centre of mass
    // moves at F t / M and, stepped with v_n = n h F / M, x_n = h^2 F / M * n (n + 1) / 2.
    let (steps, dt, f) = (200usize, 5e-4, 0.5);
    let args = volumetric(&[
        "--gravity",
        "0",
        "--dt",
        "5e-4",
        "--steps",
        "200",
        "--load",
        "force=0,0.5,0;on=above:z:0;per=total",
    ]);
    let rest = build(&args, None).unwrap().sim;
    let done = execute(&args, None, true).unwrap();
    let sim = &done.sim;
    let mass: f64 = sim.masses().iter().sum();
    let t = steps as f64 * dt;
    let p = sim.momentum();
    assert!(
        (p.y - f * t).abs() < 1e-9 * f * t,
        "momentum {p:?} vs F t = {}",
        f * t
    );
    assert!(
        p.x.abs() < 1e-9 * f * t && p.z.abs() < 1e-9 * f * t,
        "{p:?}"
    );
    let com = |x: &[nalgebra::Point3<f64>]| -> nalgebra::Vector3<f64> {
        x.iter()
            .zip(sim.masses())
            .map(|(p, m)| p.coords * *m)
            .sum::<nalgebra::Vector3<f64>>()
            / mass
    };
    let moved = com(sim.positions()) - com(rest.positions());
    let n = steps as f64;
    let want = dt * dt * f / mass * n * (n + 1.0) / 2.0;
    assert!(
        (moved.y - want).abs() < 1e-6 * want,
        "centre of mass moved {} m, F t^2 / 2M stepped: {want} m",
        moved.y
    );
    // The force acted on the upper half only, so the body also turned and deformed, but its
    // centre of mass went straight.
    assert!(
        moved.x.abs() < 1e-6 * want && moved.z.abs() < 1e-6 * want,
        "{moved:?}"
    );
    let summary = done.summary.unwrap();
    let impulse = summary["external_impulse"][1].as_f64().unwrap();
    assert!((impulse - f * t).abs() < 1e-12, "{impulse}");
}

#[test]
fn an_empty_volumetric_selection_is_an_error_naming_the_selector() {
    for (flag, value) in [
        ("--pin", "below:z:-100"),
        ("--load", "force=0,0,1;on=box:5,5,5,6,6,6"),
        ("--pin", "above:x:100@50"),
    ] {
        let mut argv = vec!["volumetric"];
        argv.extend_from_slice(BODY);
        argv.extend_from_slice(&[flag, value, "--steps", "1"]);
        let o = run_balloon(&argv);
        assert!(!o.status.success(), "{value}");
        let err = String::from_utf8_lossy(&o.stderr);
        let selector = value
            .split("on=")
            .last()
            .unwrap()
            .split('@')
            .next()
            .unwrap();
        let shown = shown(selector);
        assert!(
            err.contains(&format!("`{shown}` selects no particle of the body")),
            "{value}: {err}"
        );
    }
}

/// A selector as the error prints it (numbers in Rust's round-trip form).
fn shown(selector: &str) -> String {
    balloon_cli::selection::parse_selector(selector)
        .unwrap()
        .to_string()
}

/// `balloon two-layer`'s flags parsed on their own.
#[derive(clap::Parser)]
struct TwoLayerCli {
    #[command(flatten)]
    args: balloon_cli::cmd_two_layer::TwoLayerArgs,
}

fn two_layer(argv: &[&str]) -> balloon_cli::cmd_two_layer::TwoLayerArgs {
    use clap::Parser as _;
    let mut all = vec!["two-layer"];
    all.extend_from_slice(argv);
    TwoLayerCli::try_parse_from(all)
        .unwrap_or_else(|e| panic!("{e}"))
        .args
}

#[test]
fn spring_pinned_two_layer_particles_hang_at_the_static_deflection_m_g_over_k() {
    // Every particle of a gas-free sphere on a spring of K to its rest position: the body
    // translates as a whole (its own springs stay at rest length), a mass m on a spring K under
    // g, undamped: z(t) = z0 - d (1 - cos w t) about the static deflection d = m g / K, with
    // w = sqrt(K / m). Over whole periods the mean drop is d and the largest is 2 d; both are
    // read from `stats.jsonl` (`min_height`, one row per step).
    let (m, k, g, dt) = (0.01f64, 10.0f64, 9.81f64, 5e-4f64);
    let d = m * g / k;
    let period = 2.0 * std::f64::consts::PI * (m / k).sqrt();
    let steps = (5.0 * period / dt).round() as usize;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let steps_arg = steps.to_string();
    let o = run_balloon(&[
        "two-layer",
        "--level",
        "1",
        "--pressure",
        "0",
        "--inner-pressure",
        "0",
        "--steps",
        &steps_arg,
        "--frame-every",
        &steps_arg,
        "--pin",
        "box:-5,-5,-5,5,5,5",
        "--pin-stiffness",
        "10",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> = std::fs::read_to_string(out.join("stats.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), steps);
    let rest = two_layer(&["--level", "1"]);
    let sim = balloon_cli::cmd_two_layer::build(&rest).unwrap();
    let z0 = sim
        .positions()
        .iter()
        .skip(2)
        .step_by(3)
        .copied()
        .fold(f64::INFINITY, f64::min);
    let drops: Vec<f64> = rows
        .iter()
        .map(|r| z0 - r["min_height"].as_f64().unwrap())
        .collect();
    let mean = drops.iter().sum::<f64>() / drops.len() as f64;
    let largest = drops.iter().copied().fold(0.0, f64::max);
    assert!(
        (mean - d).abs() < 0.01 * d,
        "mean drop {mean} m, m g / K = {d} m"
    );
    assert!(
        (largest - 2.0 * d).abs() < 0.01 * d,
        "largest drop {largest} m vs 2 m g / K"
    );
}

#[test]
fn a_force_load_changes_the_two_layer_momentum_by_f_t() {
    // 0.3 N in total along +x on the upper half of a gas-free sphere, no gravity, no box,
    // from 0.05 s to 0.15 s: the momentum is F (end - start) afterwards, to round-off.
    let args = two_layer(&[
        "--level",
        "1",
        "--pressure",
        "0",
        "--inner-pressure",
        "0",
        "--gravity",
        "0",
        "--no-box",
        "--steps",
        "400",
        "--load",
        "force=0.3,0,0;on=above:z:0;per=total;start=0.05;end=0.15",
    ]);
    let done = balloon_cli::cmd_two_layer::execute(&args, true).unwrap();
    let sim = &done.sim;
    let masses = &sim.model().masses;
    let p: Vec<f64> = (0..3)
        .map(|d| {
            masses
                .iter()
                .enumerate()
                .map(|(i, m)| m * sim.velocities()[3 * i + d])
                .sum()
        })
        .collect();
    let want = 0.3 * (0.15 - 0.05);
    assert!(
        (p[0] - want).abs() < 1e-9 * want,
        "momentum {p:?} vs F t = {want}"
    );
    assert!(
        p[1].abs() < 1e-9 * want && p[2].abs() < 1e-9 * want,
        "{p:?}"
    );
}
