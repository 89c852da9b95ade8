//! Material evaluation throughput: `psi + P`, `dP` and the 9x9 tangent for St. Venant-Kirchhoff
//! and neo-Hookean on a batch of seeded random deformation gradients.

use std::hint::black_box;

use balloon_material::{Lame, Material, NeoHookean, StVenantKirchhoff};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Matrix3;

const BATCH: usize = 1024;

/// Seeded, well-conditioned gradients `I + 0.2 G` (xorshift, no RNG crate).
fn gradients() -> Vec<Matrix3<f64>> {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..BATCH)
        .map(|_| Matrix3::identity() + Matrix3::from_fn(|_, _| 0.2 * next()))
        .collect()
}

fn bench_model<M: Material>(c: &mut Criterion, name: &str, m: &M) {
    let fs = gradients();
    let dfs: Vec<_> = fs.iter().rev().map(|f| f - Matrix3::identity()).collect();
    let mut g = c.benchmark_group(format!("material/{name}"));
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("energy_and_piola", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for f in &fs {
                let (psi, p) = m.energy_and_piola(black_box(f));
                acc += psi + p.m11;
            }
            acc
        })
    });
    g.bench_function("piola_differential", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (f, df) in fs.iter().zip(&dfs) {
                acc += m.first_piola_differential(black_box(f), black_box(df)).m12;
            }
            acc
        })
    });
    g.bench_function("tangent", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for f in &fs {
                acc += m.tangent(black_box(f))[(4, 4)];
            }
            acc
        })
    });
    g.finish();
}

fn materials(c: &mut Criterion) {
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).expect("valid rubber parameters");
    bench_model(c, "stvk", &StVenantKirchhoff::new(lame));
    bench_model(c, "neo-hookean", &NeoHookean::new(lame));
}

criterion_group!(benches, materials);
criterion_main!(benches);
