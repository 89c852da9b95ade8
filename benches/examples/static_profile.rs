//! Times `solve_static` on the peer comparison's sphere (icosphere level 5, 10242 vertices,
//! radius 1 m, E t = 1155 N/m with t = 1 mm, nu = 1/3, 1 kg, ideal gas at 377 Pa gauge, no
//! ambient, mass damping 20 1/s), for profiling (`perf record`) and for comparing the static
//! solver's settings by hand.
//!
//! `cargo run --release -p balloon-benches --example static_profile -- [LEVEL] [SOLVER]
//! [REPEATS]` (defaults: 5, the static default linear solver, 1; `-` keeps a default). Prints
//! the report's counts and its per-phase times.
//!
//! Environment: `OUTER_LOG=1` prints every outer (thickness) iteration; `STATIC_TOL` and
//! `THICK_TOL` set the solver's and the thickness tolerance, `INITIAL_SHIFT` the first
//! Levenberg-Marquardt shift, `FORCING` the inexact Newton's forcing (0: every linear solve to
//! the CG tolerance); `NO_PROJECTION=1` keeps the
//! thickness at its rest value (no shell-volume projection: one outer solve);
//! `WRITE_REF=FILE` writes the rest shape's coordinates and `REF=FILE` reports the largest
//! vertex distance from such a file over the bounding-box diagonal (the accuracy of a looser
//! setting against a tight solve).

use balloon::integrate::linear::LinearSolverKind;
use balloon::shell::statics::StaticOptions;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).filter(|s| s.as_str() != "-").cloned();
    let level: u32 = arg(0).map_or(5, |s| s.parse().expect("LEVEL is a number"));
    let mut options = StaticOptions::default();
    if let Some(kind) = arg(1) {
        let kind: LinearSolverKind = kind.parse().expect("SOLVER is a linear solver kind");
        options.solver.solver.linear.kind = kind;
    }
    if let Some(t) = std::env::var("STATIC_TOL")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        options.solver.tolerance = t;
    }
    if let Some(t) = std::env::var("FORCING").ok().and_then(|s| s.parse().ok()) {
        options.solver.inexact_forcing = t;
    }
    if let Some(t) = std::env::var("INITIAL_SHIFT")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        options.solver.initial_shift = t;
    }
    if let Some(t) = std::env::var("THICK_TOL").ok().and_then(|s| s.parse().ok()) {
        options.thickness_tolerance = t;
    }
    let reference: Option<Vec<f64>> = std::env::var("REF").ok().map(|p| {
        std::fs::read_to_string(&p)
            .unwrap_or_else(|e| panic!("REF={p}: {e}"))
            .split_whitespace()
            .map(|x| x.parse().expect("REF holds numbers"))
            .collect()
    });
    let repeats: usize = arg(2).map_or(1, |s| s.parse().expect("REPEATS is a number"));
    for _ in 0..repeats {
        let mut builder = balloon_tests::peer_sphere(level).expect("peer sphere");
        if std::env::var_os("NO_PROJECTION").is_some() {
            builder = builder.with_projection(None);
        }
        let mut sim = builder.build().expect("balloon");
        let t = Instant::now();
        let r = sim.solve_static(&options).expect("static solve");
        let secs = t.elapsed().as_secs_f64();
        println!(
            "{} v: {:.3} s, outer {}, Newton {}, factorisations {}, linear it. {}, cuts {}, \
             residual {:.2e}, thickness change {:.1e}, V/V0 {:.6}",
            sim.positions().len() / 3,
            secs,
            r.outer_iterations,
            r.newton_iterations,
            r.factorizations,
            r.linear_iterations,
            r.line_search_cuts,
            r.relative_residual,
            r.thickness_change,
            sim.gas_volume() / sim.rest_gas_volume()
        );
        println!("    phases (ms): {}", r.times);
        if let Ok(p) = std::env::var("WRITE_REF") {
            let t: Vec<String> = sim
                .positions()
                .iter()
                .map(|x| format!("{x:.17e}"))
                .collect();
            std::fs::write(&p, t.join(" ")).unwrap_or_else(|e| panic!("WRITE_REF={p}: {e}"));
        }
        if let Some(r) = &reference {
            assert_eq!(r.len(), sim.positions().len(), "REF is of another mesh");
            println!(
                "    shape difference from REF: {:.2e} of the bounding-box diagonal",
                balloon_tests::max_vertex_distance(sim.positions(), r)
                    / balloon_tests::bbox_diagonal(r)
            );
        }
        if std::env::var_os("OUTER_LOG").is_some() {
            for (k, o) in r.outer.iter().enumerate() {
                println!(
                    "    outer {k}: tol {:.0e}, residual {:.2e}, Newton {}, factorisations {}, \
                     regularised {}, thickness change {:.2e}, accelerated {}",
                    o.tolerance,
                    o.relative_residual,
                    o.newton_iterations,
                    o.factorizations,
                    o.regularized_solves,
                    o.thickness_change,
                    o.accelerated
                );
            }
        }
    }
}
