//! Incompressible rubber membranes: the material kernels (energy and stress, Voigt tangent) of
//! every model on the 2x2 in-plane `C`, and the `HyperMembrane` element's fused forces + 9x9
//! stiffness (the kernel an assembled Newton solve calls once per element and iteration).
//! Throughput is in evaluations (material) or elements, so criterion reports them per second.

use std::hint::black_box;

use balloon_element::HyperMembrane;
use balloon_material::membrane::{
    MembraneGent, MembraneMaterial, MembraneModel, MembraneMooneyRivlin, MembraneNeoHookean,
    MembranePreset, MembraneYeoh,
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Matrix2, Vector3};

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

fn models() -> Vec<(&'static str, MembraneModel)> {
    vec![
        (
            "neo-hookean",
            MembraneNeoHookean::try_new(4.0e5).expect("valid").into(),
        ),
        (
            "mooney-rivlin",
            MembraneMooneyRivlin::try_new(1.6e5, 4.0e4)
                .expect("valid")
                .into(),
        ),
        (
            "gent",
            MembraneGent::try_new(4.0e5, 60.0).expect("valid").into(),
        ),
        ("ogden-3", MembranePreset::NaturalRubber.model()),
        (
            "yeoh",
            MembraneYeoh::try_new(1.1e5, 2.0e4, 5.0e2)
                .expect("valid")
                .into(),
        ),
    ]
}

/// Seeded in-plane stretches between 1 and about 2.5, with shear.
fn states() -> Vec<Matrix2<f64>> {
    let mut r = Next(0x9E37_79B9_7F4A_7C15);
    (0..N)
        .map(|_| {
            let f = Matrix2::new(
                1.7 + 0.7 * r.f(),
                0.3 * r.f(),
                0.3 * r.f(),
                1.7 + 0.7 * r.f(),
            );
            f.transpose() * f
        })
        .collect()
}

fn material(c: &mut Criterion) {
    let cs = states();
    for (name, m) in models() {
        let mut g = c.benchmark_group(format!("membrane/material/{name}"));
        g.throughput(Throughput::Elements(N as u64));
        g.bench_function("energy_and_stress", |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for cc in &cs {
                    let (w, s) = m.energy_and_stress(black_box(cc));
                    acc += w + s[(0, 1)];
                }
                acc
            })
        });
        g.bench_function("tangent", |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for cc in &cs {
                    acc += m.tangent(black_box(cc))[(2, 2)];
                }
                acc
            })
        });
        g.finish();
    }
}

fn element(c: &mut Criterion) {
    let mut r = Next(11);
    let data: Vec<(HyperMembrane, [Vector3<f64>; 3])> = (0..N)
        .map(|_| {
            let p0 = r.v();
            let rest = [
                p0,
                p0 + Vector3::new(0.01, 0.001 * r.f(), 0.0),
                p0 + Vector3::new(0.002 * r.f(), 0.01, 0.001 * r.f()),
            ];
            let el = HyperMembrane::try_new(rest, 1.0e-3).expect("well-shaped rest triangle");
            (el, rest.map(|p| p * 1.3 + r.v() * 5e-4))
        })
        .collect();
    for (name, m) in models() {
        let mut g = c.benchmark_group(format!("membrane/element/{name}"));
        g.throughput(Throughput::Elements(N as u64));
        g.bench_function("forces_and_stiffness", |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for (el, x) in &data {
                    let (f, k) = el.forces_and_stiffness(&m, black_box(x));
                    acc += f[0].x + k[(4, 4)];
                }
                acc
            })
        });
        g.finish();
    }
}

criterion_group!(benches, material, element);
criterion_main!(benches);
