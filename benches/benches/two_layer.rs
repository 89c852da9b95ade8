//! Two-layer objects (Song 2009): one force evaluation (springs + damping + gas + gravity) and one
//! whole step (integrate, box collisions, inner-layer containment, blow-up check) per explicit
//! method, on octahedron spheres of level 3 (516 particles) and 4 (2052 particles), both of
//! about 5 kg in total. The real-time claim of `docs/two-layer.md`: a level-4 RK4 step at
//! dt = 1 ms (stable up to at least 4 ms) must take < 1 ms. The group `two_layer/rk4_dt1e-4`
//! times the configuration of issue 16 item 5 (RK4 at dt = 0.1 ms, levels 2 to 5, throughput in
//! springs per force evaluation, four per step); compare its per-spring time with
//! `benches/benches/triad.rs` (the memory bandwidth).

use std::hint::black_box;

use balloon::constraint::two_layer::AxisBox;
use balloon::two_layer::{ExplicitMethod, TwoLayerBody};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Point3;

fn body(level: u32) -> TwoLayerBody {
    let bbox =
        AxisBox::try_new(Point3::new(-2.0, -2.0, -1.3), Point3::new(2.0, 2.0, 2.0)).expect("box");
    // 4^(level+1) + 2 particles per layer; keep the total mass near 5 kg.
    let per_layer = 4f64.powi(level as i32 + 1) + 2.0;
    let mass = 2.6 / per_layer;
    TwoLayerBody::octahedron_sphere(level)
        .with_radii(0.8, 1.0)
        .with_masses(mass, mass)
        .with_damping(0.1)
        .with_pressure(100.0, 50.0)
        .with_box(Some(bbox))
}

fn bench_two_layer(c: &mut Criterion) {
    for level in [3u32, 4] {
        let b = body(level);
        let model = b.build().expect("model");
        let particles = model.num_particles();
        let mut g = c.benchmark_group(format!("two_layer/octa_level{level}_{particles}p"));
        g.throughput(Throughput::Elements(model.springs.len() as u64));
        let mut forces = balloon::two_layer::TwoLayerForces::new(model.clone(), &b);
        let x = model.rest_positions.clone();
        let v = vec![0.01; x.len()];
        let mut f = vec![0.0; x.len()];
        g.bench_function("forces", |bn| {
            bn.iter(|| forces.forces_into(black_box(&x), black_box(&v), &mut f))
        });
        let dt = 1e-3;
        for method in ExplicitMethod::ALL {
            // Symplectic Euler and RK4 are stable at 1 ms; Euler and midpoint get a smaller step
            // (their step cost does not depend on dt).
            let dt = match method {
                ExplicitMethod::Rk4 | ExplicitMethod::Symplectic => dt,
                _ => 2.5e-4,
            };
            let mut sim = b.simulate(method, dt).expect("simulation");
            g.bench_function(format!("step_{method}_dt{dt:e}"), |bn| {
                bn.iter(|| black_box(sim.step().expect("stable step")))
            });
        }
        g.finish();
    }
}

/// RK4 at dt = 0.1 ms on the levels 2 to 5 (132 to 8196 particles): whole steps, with the
/// throughput in springs x 4 evaluations, so the reported rate is spring evaluations per second.
fn bench_two_layer_rk4_small_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("two_layer/rk4_dt1e-4");
    for level in [2u32, 3, 4, 5] {
        let b = body(level);
        let mut sim = b.simulate(ExplicitMethod::Rk4, 1e-4).expect("simulation");
        let springs = sim.model().springs.len();
        g.throughput(Throughput::Elements(4 * springs as u64));
        g.bench_function(format!("level{level}_{springs}springs"), |bn| {
            bn.iter(|| black_box(sim.step().expect("stable step")))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_two_layer, bench_two_layer_rk4_small_step);
criterion_main!(benches);
