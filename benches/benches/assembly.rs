//! Shell stiffness assembly alone (Wang et al. 2015, Eq. 11 and 23): the 9x9 three-prism stiffness blocks
//! of an inflating balloon scattered into triplets, and the triplets summed into the CSR matrix
//! `A = M + dt^2 K` with the cached pattern (what the PCG and Cholesky solvers do once per Newton
//! iteration). The element blocks themselves are timed in `element.rs`, the solves in
//! `linear_solve.rs`.

use balloon::integrate::ForceSystem;
use balloon::linalg::{LinearSolverKind, SparseAssembler};
use balloon::shell::ShellBalloon;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Duration;

fn assembly(c: &mut Criterion) {
    let mesh = balloon_benches::teddy_about_11k();
    let mut group = c.benchmark_group(format!("assembly/shell_{}v", mesh.num_vertices()));
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1));
    // A few Cholesky steps so the balloon is inflating and the system holds the element
    // stiffness blocks of a stressed state.
    let mut sim = ShellBalloon::new(mesh)
        .with_pump_rate(2e-3) // the fixed 2 L/s these figures were measured with
        .with_linear_solver(LinearSolverKind::Cholesky)
        .build()
        .expect("valid balloon");
    for _ in 0..3 {
        sim.step().expect("step");
    }
    let dt = sim.dt();
    let masses = sim.masses().to_vec();
    let system = sim.system();
    let mut triplets = Vec::new();
    group.bench_function("stiffness_triplets", |b| {
        b.iter(|| {
            triplets.clear();
            system
                .add_stiffness_triplets(black_box(&mut triplets))
                .expect("triplets");
        })
    });
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, 1.0, &triplets, dt * dt)
        .expect("assemble");
    group.bench_function("csr_cached_pattern", |b| {
        b.iter(|| {
            asm.assemble(&masses, 1.0, black_box(&triplets), dt * dt)
                .expect("assemble")
        })
    });
    group.bench_function("triplets_and_csr", |b| {
        b.iter(|| {
            triplets.clear();
            system
                .add_stiffness_triplets(&mut triplets)
                .expect("triplets");
            asm.assemble(&masses, 1.0, black_box(&triplets), dt * dt)
                .expect("assemble")
        })
    });
    group.finish();
}

criterion_group!(benches, assembly);
criterion_main!(benches);
