//! The streaming triad `a[i] = b[i] + s * c[i]` (McCalpin's STREAM kernel): the memory bandwidth
//! of this machine, the bound the two-layer force evaluation is compared with (issue 16 item 5).
//! Two sizes: 3 x 64 MiB (streams from memory or the last-level cache) and 3 x 256 KiB (stays in
//! the per-core L2 cache, like the level-4 two-layer spring arrays). Throughput is reported in
//! bytes moved (24 per element: two reads, one write).

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn triad(a: &mut [f64], b: &[f64], c: &[f64], s: f64) {
    for ((ai, bi), ci) in a.iter_mut().zip(b).zip(c) {
        *ai = bi + s * ci;
    }
}

fn bench_triad(c: &mut Criterion) {
    let mut g = c.benchmark_group("triad");
    for (label, n) in [("64MiB", 8usize << 20), ("256KiB", 32usize << 10)] {
        let (mut a, b, cc) = (vec![0.0; n], vec![1.0; n], vec![2.0; n]);
        g.throughput(Throughput::Bytes(24 * n as u64));
        g.bench_function(label, |bn| {
            bn.iter(|| triad(black_box(&mut a), black_box(&b), black_box(&cc), 3.0))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_triad);
criterion_main!(benches);
