//! `balloon volumetric` end-to-end tests.

use crate::{last_json_line, run_balloon};

#[test]
fn json_summary_has_every_key_and_volume_is_conserved() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "16",
        "--voxels-per-cell",
        "2",
        "--steps",
        "20",
        "--dt",
        "5e-4",
        "--frame-every",
        "10",
        "--soft-diagonals",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = last_json_line(&o);
    for key in [
        "cells",
        "tetrahedra",
        "particles",
        "steps",
        "max_cell_volume_error",
        "total_volume_ratio",
        "momentum_drift",
        "angular_momentum_drift",
        "external_impulse",
        "momentum_balance",
        "resolution",
        "step_halvings",
        "mean_step_ms",
    ] {
        assert!(j.get(key).is_some(), "missing key {key} in {j}");
    }
    assert_eq!(j["steps"], 20);
    // Gravity and the floor act: no drift is claimed, the balance with their impulse is given.
    assert!(j["momentum_drift"].is_null(), "{j}");
    let weight_impulse = j["mass"].as_f64().unwrap() * 9.81 * 20.0 * 5e-4;
    assert!(
        j["momentum_balance"].as_f64().unwrap() < 1e-9 * weight_impulse,
        "{j}"
    );
    assert_eq!(
        j["tetrahedra"].as_u64().unwrap(),
        5 * j["cells"].as_u64().unwrap()
    );
    assert!(j["max_cell_volume_error"].as_f64().unwrap() <= 1e-10);
    assert!((j["total_volume_ratio"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    // Files: the lattice for ParaView, frames 0, 10, 20, one stats line per step, the summary.
    let vtk = std::fs::read_to_string(out.join("lattice.vtk")).unwrap();
    assert!(vtk.starts_with("# vtk DataFile Version 3.0"));
    assert!(vtk.contains(&format!("CELLS {} ", j["tetrahedra"])));
    for f in [
        "frame_00000.obj",
        "frame_00010.obj",
        "frame_00020.obj",
        "summary.json",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 20);
    for line in stats.lines() {
        let row: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(row["max_cell_volume_error"].as_f64().unwrap() <= 1e-10);
    }
}

#[test]
fn bad_parameter_is_named_in_the_error() {
    let o = run_balloon(&["volumetric", "builtin:icosphere", "--p-in", "1.5"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--p-in") && err.contains("1.5"), "{err}");
    let o = run_balloon(&["volumetric", "builtin:icosphere", "--dt", "0"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("dt"));
}

#[test]
fn missing_mesh_file_is_reported() {
    let o = run_balloon(&["volumetric", "/nonexistent/soup.obj"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/soup.obj"));
}

#[test]
fn inversion_stops_with_step_and_cell_and_keeps_written_output() {
    // Springs far too soft to hold the falling sphere: the body's tetrahedra invert even after
    // the bounded step halvings; the error names the step and cell, and every stats line written
    // before it parses.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fail");
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "12",
        "--voxels-per-cell",
        "2",
        "--edge-stiffness",
        "0.01",
        "--damping",
        "0",
        "--steps",
        "400",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("step") && err.contains("cell") && err.contains("halvings"),
        "{err}"
    );
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    assert!(stats.lines().count() > 10);
    for line in stats.lines() {
        serde_json::from_str::<serde_json::Value>(line).unwrap();
    }
    assert!(out.join("lattice.vtk").is_file());
}

#[test]
fn global_volume_solver_conserves_cells_in_few_iterations_on_a_real_soup() {
    // The bunny from ../shared/meshes (the built-in teddy when the folder is absent) under the
    // falling sphere, once with the paper's sweeps and once with the global solver.
    let mesh = crate::shared_meshes_dir()
        .map(|d| d.join("bunny_closed_libigl.off").display().to_string())
        .unwrap_or_else(|| "builtin".into());
    let run = |solver: &str| {
        let o = run_balloon(&[
            "volumetric",
            &mesh,
            "--resolution",
            "24",
            "--steps",
            "60",
            "--volume-solver",
            solver,
            "--json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        last_json_line(&o)
    };
    let (sweeps, global) = (run("gauss-seidel"), run("global"));
    assert_eq!(global["volume_solver"], "global");
    assert_eq!(global["cells"], sweeps["cells"]);
    for j in [&sweeps, &global] {
        assert!(j["max_cell_volume_error"].as_f64().unwrap() <= 1e-10, "{j}");
        assert!(
            (j["total_volume_ratio"].as_f64().unwrap() - 1.0).abs() < 1e-9,
            "{j}"
        );
    }
    let (gs, newton) = (
        sweeps["mean_sweeps"].as_f64().unwrap(),
        global["mean_sweeps"].as_f64().unwrap(),
    );
    assert!(
        newton <= 12.0 && newton < gs,
        "global {newton} vs Gauss-Seidel {gs} per step"
    );
    // The global solver only moves along the volume gradients: the scaling correction is
    // refused with the setting named.
    let o = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--volume-solver",
        "global",
        "--correction",
        "scaling",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("`correction`") && err.contains("gradient"),
        "{err}"
    );
}

/// The default lattice is sized for about 1000 cells (0.8 to 1.25 times), on the built-in teddy
/// and on real models at their natural size (the bunny is 0.15 m, the torus 2.5 m across); a
/// resolution that leaves nothing names one that works.
#[test]
fn default_lattice_is_sized_for_a_thousand_cells_on_any_model() {
    let mut models = vec!["builtin".to_string(), "builtin:torus".to_string()];
    if let Some(dir) = crate::shared_meshes_dir() {
        for f in ["torus.obj", "bunny_closed_libigl.off"] {
            models.push(dir.join(f).to_string_lossy().into_owned());
        }
    }
    for m in &models {
        let o = run_balloon(&["volumetric", m, "--steps", "0", "--json"]);
        assert!(
            o.status.success(),
            "{m}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let j = last_json_line(&o);
        let cells = j["cells"].as_u64().unwrap();
        assert!((800..=1250).contains(&cells), "{m}: {cells} cells");
        assert!(j["resolution"].as_u64().unwrap() > 24, "{m}: {j}");
    }
    // `--cells` overrides the target.
    let o = run_balloon(&[
        "volumetric",
        "builtin",
        "--cells",
        "300",
        "--steps",
        "0",
        "--json",
    ]);
    let cells = last_json_line(&o)["cells"].as_u64().unwrap();
    assert!((240..=375).contains(&cells), "{cells}");
    // A resolution too coarse for the model says which one would work.
    let o = run_balloon(&[
        "volumetric",
        "builtin:torus",
        "--resolution",
        "6",
        "--steps",
        "0",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("resolution 6 leaves no cell; --resolution ") && err.contains("cells"),
        "{err}"
    );
}

/// Signed tetrahedron volume from positions.
fn tet_volume(x: &[nalgebra::Point3<f64>], t: &[usize; 4]) -> f64 {
    let [a, b, c, d] = t.map(|i| x[i]);
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

/// Distance from `p` to the triangle `(a, b, c)`: the closest point by the Voronoi regions of
/// its vertices, edges and face.
fn point_triangle_distance(p: nalgebra::Point3<f64>, [a, b, c]: [nalgebra::Point3<f64>; 3]) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).norm();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).norm();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm()
}

#[test]
fn drop_sphere_impact_with_the_global_solver_keeps_every_cell_and_the_sphere_outside() {
    // The drop-sphere scene exactly as `balloon volumetric` sets it up (springs, time step,
    // sphere size, height and speed from the body), on the built-in teddy sized for 300 cells,
    // stepped here past the impact. Measured independently of the solver after every step: each
    // tetrahedron's volume recomputed from the positions (none inverts), each cell's volume (the
    // sum of its five) against its rest volume, and the distance from the sphere's centre to the
    // lattice's boundary triangles (the sphere may not sink into the body).
    let args = super::volumetric_args(&["builtin", "--cells", "300"]);
    let mut sim = balloon_cli::cmd_volumetric::build(&args, None).unwrap().sim;
    let lattice = sim.lattice().clone();
    let tets = &lattice.tet_mesh.tets;
    let cell_volumes = |x: &[nalgebra::Point3<f64>]| -> Vec<f64> {
        lattice
            .cell_tets
            .iter()
            .map(|c| c.iter().map(|&t| tet_volume(x, &tets[t])).sum())
            .collect()
    };
    let v0 = cell_volumes(&lattice.tet_mesh.vertices);
    // Boundary triangles: the tetrahedron faces that belong to one tetrahedron only.
    let mut faces: std::collections::HashMap<[usize; 3], usize> = Default::default();
    for t in tets {
        for f in [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
            let mut k = f.map(|i| t[i]);
            k.sort_unstable();
            *faces.entry(k).or_default() += 1;
        }
    }
    let boundary: Vec<[usize; 3]> = faces
        .into_iter()
        .filter_map(|(f, n)| (n == 1).then_some(f))
        .collect();
    let cell = lattice.info.cell_size;
    let sphere0 = *sim.sphere().unwrap();
    // The contacts act between the sphere and the particles (Diziol, Bender and Bayer 2011, Sec. 5), so a sphere
    // resting on the corners of a boundary triangle dips into it by at most the sagitta
    // `r - sqrt(r^2 - R^2)` of the triangle's circumradius R. The bound takes the largest rest
    // circumradius, stretched by 25 % for the deformation under the impact.
    let circumradius = |[a, b, c]: [nalgebra::Point3<f64>; 3]| {
        let (ab, bc, ca) = ((b - a).norm(), (c - b).norm(), (a - c).norm());
        ab * bc * ca / (2.0 * (b - a).cross(&(c - a)).norm())
    };
    let r_face = 1.25
        * boundary
            .iter()
            .map(|f| circumradius(f.map(|i| lattice.tet_mesh.vertices[i])))
            .fold(0.0, f64::max);
    let r = sphere0.radius;
    let sagitta = r - (r * r - r_face.min(r).powi(2)).sqrt();
    let mut deepest_particle = f64::MIN;
    let (mut worst_cell, mut min_tet, mut deepest) = (0.0f64, f64::MAX, f64::MIN);
    let (mut touched_at, mut min_vz, mut end_vz) = (None, 0.0f64, 0.0);
    let mut rebound = f64::MIN;
    for step in 1..=1200 {
        sim.step()
            .unwrap_or_else(|e| panic!("step {step} failed: {e}"));
        let x = sim.positions();
        min_tet = tets
            .iter()
            .map(|t| tet_volume(x, t))
            .fold(min_tet, f64::min);
        worst_cell = cell_volumes(x)
            .iter()
            .zip(&v0)
            .map(|(v, r)| (v / r - 1.0).abs())
            .fold(worst_cell, f64::max);
        let s = sim.sphere().unwrap();
        let gap = boundary
            .iter()
            .map(|f| point_triangle_distance(s.position, f.map(|i| x[i])))
            .fold(f64::MAX, f64::min)
            - s.radius;
        deepest = deepest.max(-gap);
        let particle_gap = x
            .iter()
            .map(|p| (p - s.position).norm())
            .fold(f64::MAX, f64::min)
            - s.radius;
        deepest_particle = deepest_particle.max(-particle_gap);
        if touched_at.is_none() && gap < 0.05 * cell {
            touched_at = Some(step);
        }
        min_vz = min_vz.min(s.velocity.z);
        end_vz = s.velocity.z;
        if touched_at.is_some() {
            rebound = rebound.max(s.velocity.z);
        }
    }
    eprintln!(
        "contact at step {touched_at:?}; smallest tet {min_tet:.3e} m^3, cell error \
         {worst_cell:.1e}, particles {deepest_particle:.1e} m and faces {deepest:.3e} m into the \
         sphere (bound {sagitta:.3e} m), vz {min_vz:.3} .. {rebound:.3} m/s, at the end {end_vz:.3} m/s"
    );
    assert!(
        min_tet > 0.0,
        "a tetrahedron inverted (smallest volume {min_tet:e})"
    );
    assert!(worst_cell <= 1e-9, "cell volume error {worst_cell:e}");
    let touched = touched_at.expect("the sphere never reached the body");
    assert!(touched < 900, "contact only at step {touched}");
    // No particle enters the sphere (beyond the contacts' round-off), and the sphere dips into
    // the boundary faces no deeper than it can between their corners. Measured on the teddy:
    // particles -5e-8 m inside at worst, faces 3.2 mm (cell 21 mm, sphere radius 39 mm).
    assert!(
        deepest_particle < 1e-5 * r,
        "a particle is {deepest_particle:.3e} m inside the sphere"
    );
    assert!(
        deepest < sagitta,
        "the sphere sank {deepest:.3e} m into the body's boundary (bound {sagitta:.3e} m, \
         cell {cell:.3e} m, radius {r:.3e} m)"
    );
    // It was stopped: falling at least as fast as it started, then thrown back up by the body
    // (restitution 0.2 and the body's elastic rebound), and at the end no longer falling as
    // fast as it started.
    let v_start = sphere0.velocity.z;
    assert!(min_vz <= v_start, "{min_vz} vs {v_start}");
    assert!(rebound > 0.0, "the sphere never moved up after the contact");
    assert!(
        end_vz > 0.5 * v_start,
        "still falling at {end_vz} m/s (start {v_start} m/s)"
    );
}

/// `--volume-solver gauss-seidel` defaults to the gradient correction with adaptive
/// over-relaxation (fewer sweeps than fixed `--over-relaxation 1` on the same run), recorded
/// resolved in scenario.toml; the paper's exact sweeps (`--correction scaling
/// --over-relaxation 1`) stay reachable; a fixed over-relaxation is refused with the global
/// solver, naming the option.
#[test]
fn gauss_seidel_defaults_to_adaptive_gradient_sweeps_and_the_paper_stays_reachable() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let out_s = out.to_str().unwrap();
    let base = [
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "16",
        "--steps",
        "20",
        "--volume-solver",
        "gauss-seidel",
        "--json",
    ];
    let sweeps = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let out = run_balloon(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let j = last_json_line(&out);
        assert!(j["max_cell_volume_error"].as_f64().unwrap() <= 1e-10, "{j}");
        j["mean_sweeps"].as_f64().unwrap()
    };
    let default = sweeps(&["--out", out_s]);
    let plain = sweeps(&["--over-relaxation", "1"]);
    assert!(
        default < plain,
        "default (adaptive) {default} vs fixed omega = 1: {plain} sweeps per step"
    );
    let rec = std::fs::read_to_string(out.join("scenario.toml")).unwrap();
    for line in [
        "over_relaxation = \"adaptive\"",
        "correction = \"gradient\"",
        "volume_solver = \"gauss-seidel\"",
    ] {
        assert!(rec.lines().any(|l| l == line), "{line} not in\n{rec}");
    }
    // The paper's sweeps: scaling about the cell centre, no over-relaxation.
    let paper = sweeps(&["--correction", "scaling", "--over-relaxation", "1"]);
    assert!(paper >= 1.0, "{paper}");
    let out = run_balloon(&[
        "volumetric",
        "builtin:icosphere",
        "--resolution",
        "16",
        "--steps",
        "2",
        "--over-relaxation",
        "1.5",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("over_relaxation"), "{err}");
    let out = run_balloon(&["volumetric", "--over-relaxation", "fast"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("adaptive"), "{err}");
}
