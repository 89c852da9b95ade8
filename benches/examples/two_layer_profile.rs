//! Times two-layer force evaluations or RK4 steps, for comparing variants by hand (wall clock)
//! or under `valgrind --tool=callgrind` (instruction counts).
//!
//! `cargo run --release -p balloon-benches --example two_layer_profile -- LEVEL [STEPS]
//! [step|forces|triad] [DT]`: the octahedron sphere of subdivision LEVEL (radii 0.7 / 1 m,
//! 40 / 20 Pa, default springs and masses, gravity, in a 4 m box), RK4 at dt = DT seconds
//! (default 0.1 ms, the real-time configuration first measured for issue 16; `balloon
//! two-layer` defaults to 0.5 ms). `step` (default) times whole steps, `forces` one force evaluation
//! (springs, gas, gravity) at a perturbed state, `triad` the streaming triad on 3 x 64 MiB
//! (STEPS passes) for the memory bandwidth.

use balloon::constraint::two_layer::AxisBox;
use balloon::two_layer::{ExplicitMethod, TwoLayerBody, TwoLayerForces};
use nalgebra::Point3;
use std::hint::black_box;
use std::time::Instant;

/// FNV-1a over the bits of `values`: equal hashes mean bit-identical results.
fn hash(values: &[f64]) -> u64 {
    values.iter().fold(0xcbf2_9ce4_8422_2325, |h, v| {
        (h ^ v.to_bits()).wrapping_mul(0x0100_0000_01b3)
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let level: u32 = args.first().and_then(|a| a.parse().ok()).unwrap_or(4);
    let steps: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let mode = args.get(2).map(String::as_str).unwrap_or("step");
    let bbox =
        AxisBox::try_new(Point3::new(-2.0, -2.0, -2.0), Point3::new(2.0, 2.0, 2.0)).expect("box");
    let body = TwoLayerBody::octahedron_sphere(level)
        .with_radii(0.7, 1.0)
        .with_pressure(40.0, 20.0)
        .with_box(Some(bbox));
    let dt: f64 = args
        .get(3)
        .and_then(|a| a.parse().ok())
        .filter(|dt: &f64| *dt > 0.0 && dt.is_finite())
        .unwrap_or(1e-4);
    match mode {
        "triad" => {
            // The streaming triad of `benches/benches/triad.rs` on 3 x 64 MiB: GB/s.
            let n = 8usize << 20;
            let (mut a, b, c) = (vec![0.0; n], vec![1.0; n], vec![2.0; n]);
            let t = Instant::now();
            for k in 0..steps {
                for ((ai, bi), ci) in a.iter_mut().zip(&b).zip(&c) {
                    *ai = bi + k as f64 * ci;
                }
                black_box(&mut a);
            }
            let s = t.elapsed().as_secs_f64();
            println!(
                "triad 3 x 64 MiB: {:.2} GB/s ({:.3} ns per element of 24 bytes)",
                24.0 * (n * steps) as f64 / s / 1e9,
                s * 1e9 / (n * steps) as f64
            );
        }
        "forces" => {
            let model = body.build().expect("model");
            let springs = model.springs.len();
            let x: Vec<f64> = model
                .rest_positions
                .iter()
                .enumerate()
                .map(|(k, c)| c * (1.0 + 1e-3 * ((k * 7919) % 13) as f64))
                .collect();
            let v: Vec<f64> = (0..x.len())
                .map(|k| 1e-2 * ((k % 5) as f64 - 2.0))
                .collect();
            let mut f = vec![0.0; x.len()];
            let mut forces = TwoLayerForces::new(model, &body);
            let t = Instant::now();
            for _ in 0..steps {
                forces.forces_into(black_box(&x), black_box(&v), &mut f);
            }
            let s = t.elapsed().as_secs_f64();
            println!(
                "level {level}: {springs} springs, {:.2} us per evaluation, {:.3} ns per spring (hash {:016x})",
                s * 1e6 / steps as f64,
                s * 1e9 / (steps * springs) as f64,
                hash(&f)
            );
        }
        _ => {
            let mut sim = body.simulate(ExplicitMethod::Rk4, dt).expect("simulation");
            let t = Instant::now();
            let (mut contained, mut collisions) = (0, 0);
            for _ in 0..steps {
                let st = sim.step().expect("stable step");
                contained += st.contained;
                collisions += st.collisions;
            }
            let s = t.elapsed().as_secs_f64();
            println!(
                "{collisions} wall contacts, {contained} inner particles put back inside, total energy {:e} J",
                sim.energies().total()
            );
            let ms = s * 1e3 / steps as f64;
            println!(
                "level {level}: {} particles, {:.4} ms per RK4 step, {:.0} steps/s, real-time factor {:.2} (dt = {dt:e} s; state hash {:016x})",
                sim.model().num_particles(),
                ms,
                1e3 / ms,
                dt * 1e3 / ms,
                hash(sim.positions()) ^ hash(sim.velocities()).rotate_left(1)
            );
        }
    }
}
