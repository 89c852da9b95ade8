//! One full shell-balloon step (3 Newton iterations + volume projection) on a mesh of about 11k
//! vertices, for each linear solver, with the exact tangent and, for the solvers that need an SPD
//! matrix, the projected one (issue 3, part 8). The paper reports 278 ms per frame for its
//! 11090-vertex Teddy; compare `cargo bench -p balloon-benches --bench shell_step`.

use balloon::integrate::TangentKind;
use balloon::integrate::linear::LinearSolverKind;
use balloon::shell::ShellBalloon;
use criterion::{Criterion, criterion_group, criterion_main};
use std::time::Duration;

fn bench_mesh() -> balloon::mesh::TriMesh {
    // The built-in teddy at the resolution closest to the paper's 11090-vertex Teddy.
    balloon_benches::teddy_about_11k()
}

fn shell_step(c: &mut Criterion) {
    let mesh = bench_mesh();
    let mut group = c.benchmark_group(format!("shell_step_{}v", mesh.num_vertices()));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8))
        .warm_up_time(Duration::from_secs(1));
    for (kind, tangent) in [
        (LinearSolverKind::MatrixFreeCg, TangentKind::Exact),
        (LinearSolverKind::Pcg, TangentKind::Exact),
        (LinearSolverKind::Cholesky, TangentKind::Exact),
        (LinearSolverKind::Cholesky, TangentKind::Projected),
        (LinearSolverKind::FactorizedPcg, TangentKind::Projected),
    ] {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_pump_rate(2e-3) // the fixed 2 L/s these figures were measured with
            .with_linear_solver(kind)
            .build()
            .expect("valid balloon");
        sim.configure_integrator(|p| p.tangent = tangent).unwrap();
        // A few steps first so the balloon is inflating (not at the trivial rest state).
        for _ in 0..3 {
            sim.step().expect("step");
        }
        group.bench_function(format!("{kind}-{tangent}"), |b| {
            b.iter(|| sim.step().expect("step"))
        });
    }
    group.finish();
}

criterion_group!(benches, shell_step);
criterion_main!(benches);
