//! Linear solvers behind Newton (Wang et al. 2015, Eq. 23): one backward-Euler step (3 Newton iterations)
//! of an edge-spring balloon with an ideal gas (rank-1 tangent) on an icosphere, with matrix-free
//! CG (the paper), assembled Jacobi-PCG and sparse Cholesky + Sherman-Morrison.

use std::collections::BTreeSet;
use std::hint::black_box;

use balloon_gas::{IdealGas, PressureLoad, STANDARD_ATMOSPHERE, enclosed_volume};
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::{ForceSystem, SystemError};
use balloon_linalg::{
    CgWorkspace, LinearSolverKind, LinearSolverParams, LowRankTerm, PcgPreconditioner,
    SparseAssembler, SparseCholesky, cg,
};
use balloon_mesh::generate::icosphere;
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix3, Vector3};

/// Edge springs (rest length = rest edge length) plus an isothermal gas on a closed surface.
struct SpringBalloon {
    tris: Vec<[usize; 3]>,
    edges: Vec<(usize, usize, f64)>,
    stiffness: f64,
    masses: Vec<f64>,
    gas: PressureLoad<IdealGas>,
    x: Vec<f64>,
    low_rank: Vec<LowRankTerm>,
}

fn v3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

impl SpringBalloon {
    fn block(&self, i: usize, j: usize, l0: f64) -> Matrix3<f64> {
        let d = v3(&self.x, i) - v3(&self.x, j);
        let l = d.norm();
        let nn = d * d.transpose() / (l * l);
        // Clamp the transverse part at zero so the sparse part stays SPD (as a solver would).
        (nn + (Matrix3::identity() - nn) * (1.0 - l0 / l).max(0.0)) * self.stiffness
    }
}

impl ForceSystem for SpringBalloon {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        f.fill(0.0);
        for &(i, j, l0) in &self.edges {
            let d = v3(x, i) - v3(x, j);
            let l = d.norm();
            let fi = -self.stiffness * (l - l0) * d / l;
            for c in 0..3 {
                f[3 * i + c] += fi[c];
                f[3 * j + c] -= fi[c];
            }
        }
        self.gas
            .evaluate(time, x, &self.tris, f)
            .map_err(|e| SystemError::component("gas", e))?;
        self.low_rank.clear();
        self.low_rank.push(self.gas.low_rank_term().clone());
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        for &(i, j, l0) in &self.edges {
            let k = self.block(i, j, l0);
            let d = k * (v3(dx, i) - v3(dx, j));
            for c in 0..3 {
                df[3 * i + c] -= d[c];
                df[3 * j + c] += d[c];
            }
        }
        self.gas
            .add_differential(&self.x, &self.tris, dx, df)
            .expect("same mesh as forces");
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        for &(i, j, l0) in &self.edges {
            let k = self.block(i, j, l0);
            for r in 0..3 {
                for c in 0..3 {
                    t.push((3 * i + r, 3 * i + c, k[(r, c)]));
                    t.push((3 * j + r, 3 * j + c, k[(r, c)]));
                    t.push((3 * i + r, 3 * j + c, -k[(r, c)]));
                    t.push((3 * j + r, 3 * i + c, -k[(r, c)]));
                }
            }
        }
        Ok(())
    }
    fn low_rank_terms(&self) -> &[LowRankTerm] {
        &self.low_rank
    }
}

fn balloon(subdivisions: u32) -> (SpringBalloon, Vec<f64>) {
    let mesh = icosphere(0.1, subdivisions).expect("icosphere");
    let x = mesh.positions_flat();
    let tris = mesh.triangles.clone();
    let mut set = BTreeSet::new();
    for t in &tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            set.insert((a.min(b), a.max(b)));
        }
    }
    let edges = set
        .into_iter()
        .map(|(a, b)| (a, b, (v3(&x, a) - v3(&x, b)).norm()))
        .collect();
    let v0 = enclosed_volume(&x, &tris).expect("volume");
    let gas = IdealGas::try_from_gauge(3000.0, STANDARD_ATMOSPHERE, v0).expect("gas");
    let n = x.len();
    (
        SpringBalloon {
            tris,
            edges,
            stiffness: 50.0,
            masses: vec![1e-4; n],
            gas: PressureLoad::new(gas),
            x: vec![0.0; n],
            low_rank: Vec::new(),
        },
        x,
    )
}

fn bench_linear(c: &mut Criterion) {
    for subdivisions in [3u32, 4] {
        let (mut sys, x0) = balloon(subdivisions);
        let mut g = c.benchmark_group(format!("linear_solve/icosphere_{}v", x0.len() / 3));
        g.sample_size(10);
        for (kind, pre) in [
            (LinearSolverKind::MatrixFreeCg, PcgPreconditioner::Jacobi),
            (LinearSolverKind::Pcg, PcgPreconditioner::Jacobi),
            (LinearSolverKind::Pcg, PcgPreconditioner::IncompleteCholesky),
            (LinearSolverKind::Cholesky, PcgPreconditioner::Jacobi),
        ] {
            let mut be = BackwardEuler::new(BackwardEulerParams {
                pcg_preconditioner: pre,
                newton_iterations: 3,
                newton_tolerance: 0.0,
                linear: LinearSolverParams {
                    kind,
                    max_iterations: 2000,
                    relative_tolerance: 1e-8,
                },
                ..Default::default()
            })
            .expect("valid parameters");
            let name = match (kind, pre) {
                (LinearSolverKind::Pcg, PcgPreconditioner::IncompleteCholesky) => {
                    "backward_euler_step_pcg_ic0".to_string()
                }
                _ => format!("backward_euler_step_{kind}"),
            };
            g.bench_function(name, |b| {
                b.iter_batched(
                    || (x0.clone(), vec![0.0; x0.len()]),
                    |(mut x, mut v)| {
                        be.step(&mut sys, 0.0, 1e-3, black_box(&mut x), &mut v, None)
                            .expect("step")
                    },
                    BatchSize::LargeInput,
                )
            });
        }
        // Stages alone on A = M + dt^2 K_sparse at the rest state.
        let mut f = vec![0.0; x0.len()];
        sys.forces(0.0, &x0, &mut f).expect("forces");
        let mut triplets = Vec::new();
        sys.add_stiffness_triplets(&mut triplets).expect("triplets");
        let mut asm = SparseAssembler::new();
        asm.assemble(&sys.masses, 1.0, &triplets, 1e-6)
            .expect("assemble");
        g.bench_function("assemble_cached_pattern", |b| {
            b.iter(|| {
                asm.assemble(&sys.masses, 1.0, black_box(&triplets), 1e-6)
                    .expect("assemble")
            })
        });
        let a = asm.matrix().clone();
        let mut chol = SparseCholesky::new();
        chol.factorize(&a, asm.pattern_version())
            .expect("factorize");
        g.bench_function("cholesky_numeric_factorization", |b| {
            b.iter(|| {
                chol.factorize(black_box(&a), asm.pattern_version())
                    .expect("factorize")
            })
        });
        let rhs: Vec<f64> = (0..x0.len()).map(|i| ((i * 31) % 7) as f64 - 3.0).collect();
        g.bench_function("cholesky_solve", |b| {
            b.iter(|| {
                let mut r = rhs.clone();
                chol.solve_in_place(black_box(&mut r)).expect("solve");
                r[0]
            })
        });
        let mut diag = vec![0.0; x0.len()];
        a.diagonal_into(&mut diag);
        let mut ws = CgWorkspace::default();
        g.bench_function("jacobi_pcg_solve_1e-8", |b| {
            b.iter(|| {
                let mut x = vec![0.0; rhs.len()];
                cg(
                    |p, o| a.mul_into(p, o),
                    |r, z| {
                        for i in 0..r.len() {
                            z[i] = r[i] / diag[i];
                        }
                    },
                    black_box(&rhs),
                    &mut x,
                    2000,
                    1e-8,
                    &mut ws,
                )
                .expect("cg")
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench_linear);
criterion_main!(benches);
