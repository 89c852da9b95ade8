//! Gas stage alone: enclosed volume + gradient + pressure forces (`PressureLoad::evaluate`,
//! Wang et al. 2015, Eq. 13-15) and the matrix-free tangent product (Eq. 16-17, rank-1, with and without
//! the follower term) on icospheres of 2562 and 10242 vertices.

use std::hint::black_box;

use balloon_gas::{IdealGas, PressureLoad, STANDARD_ATMOSPHERE, enclosed_volume};
use balloon_mesh::generate::icosphere;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn bench_gas(c: &mut Criterion) {
    for &subdivisions in subdivision_levels() {
        let mesh = icosphere(0.1, subdivisions).expect("icosphere");
        let x = mesh.positions_flat();
        let tris = mesh.triangles.clone();
        let v0 = enclosed_volume(&x, &tris).expect("volume");
        let gas = IdealGas::try_from_gauge(2000.0, STANDARD_ATMOSPHERE, v0).expect("gas");
        let mut g = c.benchmark_group(format!("gas/icosphere_{}v", x.len() / 3));
        g.throughput(Throughput::Elements(tris.len() as u64));
        let mut load = PressureLoad::new(gas);
        let mut f = vec![0.0; x.len()];
        g.bench_function("evaluate", |b| {
            b.iter(|| {
                f.fill(0.0);
                load.evaluate(0.0, black_box(&x), &tris, &mut f)
                    .expect("evaluate")
            })
        });
        let dx: Vec<f64> = (0..x.len())
            .map(|i| ((i * 7919) % 13) as f64 * 1e-3)
            .collect();
        let mut df = vec![0.0; x.len()];
        for follower in [false, true] {
            let load = load.clone().with_follower_term(follower);
            let name = if follower {
                "differential_with_follower"
            } else {
                "differential_rank1"
            };
            g.bench_function(name, |b| {
                b.iter(|| {
                    df.fill(0.0);
                    load.add_differential(&x, &tris, black_box(&dx), &mut df)
                        .expect("differential");
                    df[0]
                })
            });
        }
        g.finish();
    }
}

criterion_group!(benches, bench_gas);
criterion_main!(benches);

/// The icosphere levels measured (2562 and 10242 vertices); level 4 alone in test mode.
fn subdivision_levels() -> &'static [u32] {
    if balloon_benches::test_mode() {
        &[4]
    } else {
        &[4, 5]
    }
}
