//! Volume-conserving impulse-based bodies (Diziol, Bender and Bayer 2011): lattice generation from a soup (Sec. 3),
//! the cell-volume projection alone (Sec. 4, Eq. 2-4; the paper's Gauss-Seidel sweeps and the
//! global Newton solve) and one whole step of the Fig. 4 drop-sphere scene.

use std::hint::black_box;

use balloon::volumetric::{VolumetricBody, VolumetricParams, VolumetricScene, drop_sphere_params};
use balloon_constraint::cell_volume::{CellCorrection, CellProjectionWorkspace, CellSolver};
use balloon_mesh::generate::icosphere;
use balloon_mesh::lattice::{LatticeParams, build_lattice};
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;

fn bench_lattice(c: &mut Criterion) {
    let soup = icosphere(1.0, 3).expect("icosphere");
    let mut g = c.benchmark_group("volumetric/lattice_icosphere_1280t");
    for resolution in [32usize, 64] {
        let params = LatticeParams {
            resolution,
            ..LatticeParams::default()
        };
        g.bench_function(format!("build_res{resolution}"), |b| {
            b.iter(|| build_lattice(black_box(&soup), &params).expect("lattice"))
        });
    }
    g.finish();
}

fn bench_projection(c: &mut Criterion) {
    let soup = icosphere(1.0, 3).expect("icosphere");
    let params = VolumetricParams {
        lattice: LatticeParams {
            resolution: 48,
            ..LatticeParams::default()
        },
        ..VolumetricParams::default()
    };
    let mut body = VolumetricBody::build(&soup, params).expect("body");
    body.constraints.params.max_sweeps = 20_000;
    let rest = body.lattice.tet_mesh.vertices.clone();
    // A deterministic perturbation of 0.5 % of a cell.
    let amp = 0.005 * body.lattice.info.cell_size;
    let perturbed: Vec<_> = rest
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let s = |k: usize| (((i * 7919 + k * 104_729) % 1000) as f64 / 500.0 - 1.0) * amp;
            p + Vector3::new(s(1), s(2), s(3))
        })
        .collect();
    let mut g = c.benchmark_group(format!(
        "volumetric/projection_{}cells",
        body.constraints.len()
    ));
    g.throughput(Throughput::Elements(body.constraints.len() as u64));
    g.bench_function("project_perturbed", |b| {
        b.iter_batched(
            || (perturbed.clone(), vec![Vector3::zeros(); rest.len()]),
            |(mut x, mut v)| {
                body.constraints
                    .project(&mut x, &mut v, &body.masses, 1e-3)
                    .expect("projection")
            },
            BatchSize::SmallInput,
        )
    });
    // The global solver (gradient correction, sparse Cholesky of J W J^T), its workspace kept
    // across calls as a simulation keeps it.
    let mut global = body.constraints.clone();
    global.params.correction = CellCorrection::Gradient;
    global.params.solver = CellSolver::Global;
    let mut workspace = CellProjectionWorkspace::new();
    g.bench_function("project_perturbed_global", |b| {
        b.iter_batched(
            || (perturbed.clone(), vec![Vector3::zeros(); rest.len()]),
            |(mut x, mut v)| {
                global
                    .project_with(&mut workspace, &mut x, &mut v, &body.masses, 1e-3, 1e-10)
                    .expect("projection")
            },
            BatchSize::SmallInput,
        )
    });
    g.finish();
}

fn bench_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("volumetric/drop_sphere_64cells");
    for soft in [false, true] {
        let sim = VolumetricScene::DropSphere {
            soft_diagonals: soft,
        }
        .build(None, drop_sphere_params(soft))
        .expect("scene");
        // Advance to the impact (step ~200) so contacts and deformation are active.
        let mut at_impact = sim.clone();
        for _ in 0..220 {
            at_impact.step().expect("step");
        }
        let name = if soft { "step_soft" } else { "step_stiff" };
        g.bench_function(name, |b| {
            b.iter_batched(
                || at_impact.clone(),
                |mut s| s.step().expect("step"),
                BatchSize::SmallInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench_lattice, bench_projection, bench_step);
criterion_main!(benches);
