//! Times `solve_static` on the peer comparison's sphere (icosphere level 5, 10242 vertices,
//! radius 1 m, E t = 1155 N/m with t = 1 mm, nu = 1/3, 1 kg, ideal gas at 377 Pa gauge, no
//! ambient, mass damping 20 1/s), for profiling (`perf record`) and for comparing the static
//! solver's settings by hand.
//!
//! `cargo run --release -p balloon-benches --example static_profile -- [LEVEL] [SOLVER]
//! [REPEATS]` (defaults: 5, the static default linear solver, 1; `-` keeps a default). Prints
//! the report's counts and its per-phase times.

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
    let repeats: usize = arg(2).map_or(1, |s| s.parse().expect("REPEATS is a number"));
    for _ in 0..repeats {
        let mut sim = balloon_tests::peer_sphere(level)
            .expect("peer sphere")
            .build()
            .expect("balloon");
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
