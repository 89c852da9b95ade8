//! Times the converged default shell solve (line-searched Newton to a relative residual, the
//! `balloon inflate` defaults) on the built-in teddy at a given resolution with the paper's gas
//! (`--gas ideal --ambient 0`, 0.3 mm wall), for profiling (`perf record`, or callgrind with
//! `--toggle-collect='*timed_steps*'`) and for comparing solver settings by hand.
//!
//! `cargo run --release -p balloon-benches --example converged_profile -- [RESOLUTION] [STEPS]
//! [SOLVER] [TOL] [ITERS] [seq]` (defaults: 40, 30, the shell's default solver, the default
//! Newton tolerance and cap; `-` keeps a default; `seq` factorises on the calling thread). Prints one line per 30 steps (gas volume) and a summary: ms/step,
//! Newton iterations, linear iterations and numeric factorisations per step (every step with
//! `STEP_LOG=1`), and where the time went (`ShellStepStats::times` summed: forces, line-search
//! energies, assembly, factorisations, solves, projection), in all and per Newton iteration.

use balloon::gas::GasKind;
use balloon::integrate::PhaseTimes;
use balloon::integrate::linear::LinearSolverKind;
use balloon::mesh::generate::teddy::{TeddyParams, teddy};
use balloon::shell::{ShellBalloon, ShellSimulation};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).filter(|s| s.as_str() != "-").cloned();
    let resolution: usize = arg(0).map_or(40, |s| s.parse().expect("RESOLUTION is a number"));
    let steps: usize = arg(1).map_or(30, |s| s.parse().expect("STEPS is a number"));
    let mesh = teddy(&TeddyParams {
        resolution,
        ..Default::default()
    })
    .expect("teddy");
    let mut builder = ShellBalloon::new(mesh.clone())
        .with_gas(GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_thickness(3e-4);
    if let Some(kind) = arg(2) {
        let kind: LinearSolverKind = kind.parse().expect("SOLVER is a linear solver kind");
        builder = builder.with_linear_solver(kind);
    }
    if let Some(tol) = arg(3) {
        let tol: f64 = tol.parse().expect("TOL is a number");
        builder = builder.configure_integrator(|p| p.newton_tolerance = tol);
    }
    if let Some(iters) = arg(4) {
        let iters: usize = iters.parse().expect("ITERS is a number");
        builder = builder.configure_integrator(|p| p.newton_iterations = iters);
    }
    if arg(5).as_deref() == Some("seq") {
        builder = builder.configure_integrator(|p| p.parallel_factorization = false);
    }
    let mut sim = builder.build().expect("balloon");
    let v0 = sim.rest_gas_volume();
    let t = Instant::now();
    let totals = timed_steps(&mut sim, steps);
    let secs = t.elapsed().as_secs_f64();
    let per = |n: usize| n as f64 / steps as f64;
    println!(
        "{} v, {} steps: {:.3} s ({:.1} ms/step), Newton {:.2}/step, linear it. {:.1}/step, \
         factorisations {:.2}/step, substeps {:.2}/step, V/V0 {:.5}",
        mesh.num_vertices(),
        steps,
        secs,
        secs * 1e3 / steps as f64,
        per(totals.newton),
        per(totals.linear),
        per(totals.factorizations),
        per(totals.substeps),
        sim.gas_volume() / v0
    );
    let p = totals.times;
    let other = secs * 1e3 - p.total_ms();
    println!("phases, ms: {p}; other {other:.1} (state checks, statistics, copies)");
    let per_newton = |ms: f64| ms / totals.newton.max(1) as f64;
    println!(
        "per Newton iteration, ms: forces {:.2}, energy {:.2}, assembly {:.2}, factorisation \
         {:.2}, solves {:.2}, projection {:.2}",
        per_newton(p.forces_ms),
        per_newton(p.energy_ms),
        per_newton(p.assembly_ms),
        per_newton(p.factorization_ms),
        per_newton(p.solve_ms),
        per_newton(p.projection_ms)
    );
}

/// Iteration counts summed over the timed steps.
#[derive(Default)]
struct Totals {
    newton: usize,
    linear: usize,
    factorizations: usize,
    substeps: usize,
    times: PhaseTimes,
}

/// The timed steps, in a function of their own so that callgrind can count only them.
#[inline(never)]
fn timed_steps(sim: &mut ShellSimulation, steps: usize) -> Totals {
    let mut t = Totals::default();
    let v0 = sim.rest_gas_volume();
    for k in 0..steps {
        let s = sim.step().expect("step");
        t.newton += s.newton_iterations;
        t.linear += s.linear_iterations;
        t.factorizations += s.factorizations;
        t.substeps += s.substeps;
        t.times += s.times;
        if std::env::var_os("STEP_LOG").is_some() {
            eprintln!(
                "step {}: Newton {}, linear {}, factorisations {}, cuts {}, residual {:.2e}, {:.1} ms",
                k + 1,
                s.newton_iterations,
                s.linear_iterations,
                s.factorizations,
                s.line_search_cuts,
                s.newton_residual,
                s.step_ms
            );
        }
        if (k + 1) % 30 == 0 {
            println!("step {:4}: V/V0 {:.6}", k + 1, s.gas_volume / v0);
        }
    }
    t
}
