//! Times shell-balloon steps with one solver configuration, for comparing solver variants by
//! hand (wall clock) or under `valgrind --tool=callgrind` (instruction counts).
//!
//! `cargo run --release -p balloon-benches --example step_profile -- MODEL SOLVER [PRECOND]
//! [STEPS] [WARMUP] [TANGENT] [REFACTOR] [seq|par]` with MODEL one of `teddy11k`, `teddy8k`, `torus`, `octasphere`;
//! SOLVER a `LinearSolverKind` name; PRECOND `jacobi|ic0`; TANGENT `exact|projected`.

use balloon::integrate::implicit::BackwardEulerParams;
use balloon::integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon::mesh::TriMesh;
use balloon::mesh::generate::teddy::{TeddyParams, teddy};
use balloon::mesh::generate::{octahedron_sphere, torus};
use balloon::shell::{
    DEFAULT_LINEAR_TOLERANCE, DEFAULT_MASS_DAMPING, ShellBalloon, ShellSimulation,
};
use std::time::Instant;

fn model(name: &str) -> TriMesh {
    match name {
        "teddy11k" => teddy(&TeddyParams {
            resolution: 40,
            ..Default::default()
        })
        .expect("teddy"),
        "teddy8k" => teddy(&TeddyParams::default()).expect("teddy"),
        "torus" => torus(0.1, 0.04, 128, 48).expect("torus"),
        "octasphere" => octahedron_sphere(0.15, 5).expect("octasphere"),
        other => {
            eprintln!("unknown model `{other}` (teddy11k, teddy8k, torus, octasphere)");
            std::process::exit(2);
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let mesh = model(&arg(0, "teddy11k"));
    let kind: LinearSolverKind = arg(1, "pcg").parse().unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let pre: PcgPreconditioner = arg(2, "ic0").parse().unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let steps: usize = arg(3, "10").parse().expect("STEPS is a number");
    let warmup: usize = arg(4, "3").parse().expect("WARMUP is a number");
    let tangent = arg(5, "exact");
    let mut params = BackwardEulerParams {
        newton_iterations: 3,
        newton_tolerance: 0.0,
        mass_damping: DEFAULT_MASS_DAMPING,
        pcg_preconditioner: pre,
        ..Default::default()
    };
    params.linear.relative_tolerance = DEFAULT_LINEAR_TOLERANCE;
    set_tangent(&mut params, &tangent);
    params.refactor_iterations = arg(6, "8").parse().expect("REFACTOR is a number");
    params.parallel_factorization = arg(7, "seq") == "par";
    let mut sim = ShellBalloon::new(mesh.clone())
        .with_pump_rate(2e-3) // the fixed 2 L/s these figures were measured with
        .with_integrator(params)
        .with_linear_solver(kind)
        .build()
        .expect("balloon");
    for _ in 0..warmup {
        sim.step().expect("warm-up step");
    }
    let t = Instant::now();
    let (newton, lin, sub) = timed_steps(&mut sim, steps);
    let ms = t.elapsed().as_secs_f64() * 1e3 / steps as f64;
    println!(
        "{} v, {kind} {pre} {tangent}: {ms:.1} ms/step, Newton {:.2}/step, CG {:.1}/step, substeps {:.2}/step, V/V0 {:.4}",
        mesh.num_vertices(),
        newton as f64 / steps as f64,
        lin as f64 / steps as f64,
        sub as f64 / steps as f64,
        sim.gas_volume() / sim.rest_gas_volume()
    );
}

/// The timed steps, in a function of their own so that callgrind can count only them:
/// `valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*timed_steps*' ...`.
/// Returns the Newton iterations, CG iterations and sub-steps summed over the steps.
#[inline(never)]
fn timed_steps(sim: &mut ShellSimulation, steps: usize) -> (usize, usize, usize) {
    let (mut newton, mut lin, mut sub) = (0, 0, 0);
    for _ in 0..steps {
        let s = sim.step().expect("step");
        newton += s.newton_iterations;
        lin += s.linear_iterations;
        sub += s.substeps;
    }
    (newton, lin, sub)
}

fn set_tangent(params: &mut BackwardEulerParams, tangent: &str) {
    params.tangent = tangent.parse().unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
}
