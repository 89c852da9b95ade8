//! Shell-volume projection alone (Wang et al. 2015, Eq. 24-28, Algorithm 2): an icosphere shell stretched
//! by 1.3 and perturbed is projected back to its rest material volume (tolerance 1e-9), on 2562
//! and 10242 vertices.

use std::hint::black_box;

use balloon_constraint::shell_volume::{
    ShellVolumeParams, ShellVolumeProjection, projection_inverse_masses, shell_volume,
};
use balloon_mesh::generate::icosphere;
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};

fn bench_projection(c: &mut Criterion) {
    for &subdivisions in subdivision_levels() {
        let mesh = icosphere(0.1, subdivisions).expect("icosphere");
        let x0 = mesh.positions_flat();
        let tris = mesh.triangles.clone();
        let h0 = vec![2e-4; tris.len()];
        let rest = shell_volume(&tris, &x0, &h0);
        let ve: Vec<f64> = tris
            .iter()
            .enumerate()
            .map(|(e, _)| {
                let one = [tris[e]];
                shell_volume(&one, &x0, &h0[e..=e])
            })
            .collect();
        let (wv, we) = projection_inverse_masses(&tris, x0.len() / 3, &ve, 950.0).expect("masses");
        let stretched: Vec<f64> = x0
            .iter()
            .enumerate()
            .map(|(i, v)| 1.3 * v + 1e-4 * (((i * 7919) % 17) as f64 / 17.0 - 0.5))
            .collect();
        let mut proj = ShellVolumeProjection::new(ShellVolumeParams::default());
        let mut g = c.benchmark_group(format!("projection/icosphere_{}v", x0.len() / 3));
        g.throughput(Throughput::Elements(tris.len() as u64));
        g.bench_function("project_stretched", |b| {
            b.iter_batched(
                || (stretched.clone(), h0.clone()),
                |(mut x, mut h)| {
                    proj.project(&tris, black_box(&mut x), &mut h, &wv, &we, rest)
                        .expect("projection")
                },
                BatchSize::LargeInput,
            )
        });
        g.finish();
    }
}

criterion_group!(benches, bench_projection);
criterion_main!(benches);

/// The icosphere levels measured (2562 and 10242 vertices); level 4 alone in test mode.
fn subdivision_levels() -> &'static [u32] {
    if balloon_benches::test_mode() {
        &[4]
    } else {
        &[4, 5]
    }
}
