//! Element kernels: the three-prism's fused forces + 9x9 stiffness (the shell solver's hot path,
//! called once per element per Newton iteration), its force differential (matrix-free CG; direct
//! and from a cached linearisation). Throughput is in elements, so criterion reports
//! elements/s; ns/element = 1e9 / throughput.

use std::hint::black_box;

use balloon_element::ThreePrism;
use balloon_material::{Lame, Material, NeoHookean, StVenantKirchhoff};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;

const N: usize = 4096;

struct Next(u64);
impl Next {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    fn v(&mut self) -> Vector3<f64> {
        Vector3::new(self.f(), self.f(), self.f())
    }
}

/// Seeded prisms (1 cm triangles, 1 mm thick) with stretched, perturbed current states.
fn prisms() -> Vec<(ThreePrism, [Vector3<f64>; 3], f64)> {
    let mut r = Next(0x9E37_79B9_7F4A_7C15);
    (0..N)
        .map(|_| {
            let p0 = r.v();
            let rest = [
                p0,
                p0 + Vector3::new(0.01, 0.001 * r.f(), 0.0),
                p0 + Vector3::new(0.002 * r.f(), 0.01, 0.001 * r.f()),
            ];
            let prism = ThreePrism::try_new(rest, 1.0e-3).expect("well-shaped rest triangle");
            let x = rest.map(|p| p * 1.2 + r.v() * 5e-4);
            (prism, x, 0.8e-3)
        })
        .collect()
}

fn prism_group<M: Material>(c: &mut Criterion, name: &str, m: &M) {
    let data = prisms();
    let dx: Vec<[Vector3<f64>; 3]> = {
        let mut r = Next(7);
        (0..N).map(|_| [r.v(), r.v(), r.v()]).collect()
    };
    let mut g = c.benchmark_group(format!("element/three-prism/{name}"));
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("forces_and_stiffness", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (p, x, h) in &data {
                let (f, k) = p.forces_and_stiffness(m, black_box(x), *h);
                acc += f[0].x + k[(4, 4)];
            }
            acc
        })
    });
    g.bench_function("forces", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (p, x, h) in &data {
                acc += p.forces(m, black_box(x), *h)[0].x;
            }
            acc
        })
    });
    g.bench_function("force_differential", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for ((p, x, h), d) in data.iter().zip(&dx) {
                acc += p.force_differential(m, black_box(x), *h, d)[0].x;
            }
            acc
        })
    });
    let lins: Vec<_> = data.iter().map(|(p, x, h)| p.linearize(m, x, *h)).collect();
    g.bench_function("linearized_force_differential", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (l, d) in lins.iter().zip(&dx) {
                acc += l.force_differential(m, black_box(d))[0].x;
            }
            acc
        })
    });
    g.finish();
}

fn elements(c: &mut Criterion) {
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).expect("valid rubber parameters");
    prism_group(c, "stvk", &StVenantKirchhoff::new(lame));
    prism_group(c, "neo-hookean", &NeoHookean::new(lame));
}

criterion_group!(benches, elements);
criterion_main!(benches);
