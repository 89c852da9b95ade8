//! End-to-end: a balloon of edge springs filled with gas, stepped by `balloon-integrate`'s
//! backward Euler through the `ForceSystem` seam with every linear solver (the rank-1 gas term
//! travels as a `LowRankTerm`).

use std::collections::BTreeSet;

use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::linear::{LinearSolverKind, LinearSolverParams};
use balloon_integrate::{ForceSystem, LowRankTerm, SystemError};
use balloon_mesh::generate::icosphere;
use nalgebra::{Matrix3, Vector3};

use balloon_gas::*;

struct SpringBalloon {
    tris: Vec<[usize; 3]>,
    edges: Vec<(usize, usize, f64)>,
    stiffness: f64,
    masses: Vec<f64>,
    gas: PressureLoad,
    x: Vec<f64>,
}

fn v3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

impl SpringBalloon {
    fn new(subdivisions: u32, follower: bool, rest_fraction: f64) -> (Self, Vec<f64>) {
        let mesh = icosphere(0.1, subdivisions).unwrap();
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
            .map(|(a, b)| (a, b, rest_fraction * (v3(&x, a) - v3(&x, b)).norm()))
            .collect();
        let v0 = enclosed_volume(&x, &tris).unwrap();
        let gas = Gas::Ideal(IdealGas::try_from_gauge(3000.0, STANDARD_ATMOSPHERE, v0).unwrap());
        let n = x.len();
        let sys = Self {
            tris,
            edges,
            stiffness: 40.0,
            masses: vec![2e-4; n],
            gas: PressureLoad::new(gas).with_follower_term(follower),
            x: vec![0.0; n],
        };
        (sys, x)
    }

    fn block(&self, i: usize, j: usize, l0: f64) -> Matrix3<f64> {
        let d = v3(&self.x, i) - v3(&self.x, j);
        let l = d.norm();
        let nn = d * d.transpose() / (l * l);
        (nn + (Matrix3::identity() - nn) * (1.0 - l0 / l)) * self.stiffness
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
        Ok(())
    }
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let springs: f64 = self
            .edges
            .iter()
            .map(|&(i, j, l0)| 0.5 * self.stiffness * ((v3(x, i) - v3(x, j)).norm() - l0).powi(2))
            .sum();
        let gas = self
            .gas
            .potential_at(time, x, &self.tris)
            .map_err(|e| SystemError::component("gas", e))?;
        Ok(gas.map(|g| g + springs))
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        for &(i, j, l0) in &self.edges {
            let d = self.block(i, j, l0) * (v3(dx, i) - v3(dx, j));
            for c in 0..3 {
                df[3 * i + c] -= d[c];
                df[3 * j + c] += d[c];
            }
        }
        self.gas
            .add_differential(&self.x, &self.tris, dx, df)
            .unwrap();
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
        self.gas
            .add_follower_triplets(&self.x, &self.tris, t)
            .map_err(|e| SystemError::component("gas", e))?;
        Ok(())
    }
    fn low_rank_terms(&self) -> &[LowRankTerm] {
        std::slice::from_ref(self.gas.low_rank_term())
    }
}

fn run(
    kind: LinearSolverKind,
    follower: bool,
    rest_fraction: f64,
    steps: usize,
) -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
    let (mut sys, mut x) = SpringBalloon::new(2, follower, rest_fraction);
    let mut v = vec![0.0; x.len()];
    let mut be = BackwardEuler::new(BackwardEulerParams {
        newton_iterations: 4,
        newton_tolerance: 0.0,
        linear: LinearSolverParams {
            kind,
            max_iterations: 2000,
            relative_tolerance: 1e-12,
        },
        ..Default::default()
    })
    .expect("valid parameters");
    let mut residuals = Vec::new();
    for s in 0..steps {
        let info = be
            .step(&mut sys, s as f64 * 2e-3, 2e-3, &mut x, &mut v, None)
            .unwrap();
        assert!(info.converged, "{kind}: {info:?}");
        residuals.push(info.newton_residuals);
    }
    (x, v, residuals)
}

#[test]
fn gas_balloon_steps_agree_across_linear_solvers() {
    // The rank-1 gas term reaches CG through the force differential, PCG through the mat-vec and
    // Cholesky through Sherman-Morrison: all three must give the same step.
    let (x_ref, v_ref, _) = run(LinearSolverKind::MatrixFreeCg, false, 1.0, 3);
    for kind in [LinearSolverKind::Pcg, LinearSolverKind::Cholesky] {
        let (x, v, _) = run(kind, false, 1.0, 3);
        for i in 0..x.len() {
            assert!((x[i] - x_ref[i]).abs() < 1e-10, "{kind} x[{i}]");
            assert!((v[i] - v_ref[i]).abs() < 1e-7, "{kind} v[{i}]");
        }
    }
    // With the follower term the matrix-free and assembled paths agree too.
    let (x_f, _, _) = run(LinearSolverKind::MatrixFreeCg, true, 0.8, 3);
    let (x_p, _, _) = run(LinearSolverKind::Pcg, true, 0.8, 3);
    for i in 0..x_f.len() {
        assert!((x_f[i] - x_p[i]).abs() < 1e-10);
    }
    // Over-pressure inflates the balloon: the enclosed volume grows.
    let (_, x0) = SpringBalloon::new(2, false, 1.0);
    let tris = icosphere(0.1, 2).unwrap().triangles;
    assert!(enclosed_volume(&x_ref, &tris).unwrap() > enclosed_volume(&x0, &tris).unwrap());
}

#[test]
fn follower_term_restores_quadratic_newton_convergence() {
    // With the exact tangent (follower term on) Newton converges quadratically; without it the
    // tangent is approximate and the residual falls only linearly. The springs are pre-stressed
    // (rest length 0.8 x edge) so that the follower term, which is indefinite, does not make the
    // system matrix indefinite (on an unstressed sphere CG reports negative curvature).
    let (_, _, with) = run(LinearSolverKind::MatrixFreeCg, true, 0.8, 2);
    let (_, _, without) = run(LinearSolverKind::MatrixFreeCg, false, 0.8, 2);
    for (rw, ro) in with.iter().zip(&without) {
        // Quadratic: r_3 <= C r_2^2 with a modest C; and far below the approximate-tangent run.
        assert!(rw[3] <= 100.0 * rw[2] * rw[2], "{rw:?}");
        assert!(rw[3] < 0.1 * ro[3], "{rw:?} vs {ro:?}");
    }
}

/// A kept-factor solver that records what the Newton core tells it about shift retries.
#[derive(Debug)]
struct RecordingSolver {
    inner: balloon_integrate::linear::FactorizedPcg,
    retries: std::sync::Arc<std::sync::Mutex<Vec<bool>>>,
}

impl balloon_integrate::linear::LinearSolver for RecordingSolver {
    fn name(&self) -> &str {
        "recording"
    }
    fn needs_assembled_matrix(&self) -> bool {
        true
    }
    fn set_shift_retries(&mut self, retries: bool) {
        self.retries.lock().unwrap().push(retries);
        self.inner.set_shift_retries(retries);
    }
    fn solve(
        &mut self,
        problem: &balloon_integrate::linear::LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<balloon_integrate::linear::SolveInfo, balloon_integrate::linear::SolveError> {
        self.inner.solve(problem, b, x)
    }
}

/// The Newton core lets the linear solver call a matrix indefinite from a cheaper test
/// (`LinearSolver::set_shift_retries`) in a time step, whose mass term and shift ladder make a
/// wrong verdict cost only a larger shift, and never in a static solve, whose conditioning is
/// the Levenberg-Marquardt shift alone.
#[test]
fn only_time_steps_let_the_linear_solver_give_a_cheap_indefinite_verdict() {
    use balloon_integrate::statics::{StaticParams, StaticSolver};
    let recorded = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let solver = || {
        Box::new(RecordingSolver {
            inner: balloon_integrate::linear::FactorizedPcg::default(),
            retries: std::sync::Arc::clone(&recorded),
        })
    };
    let (mut sys, mut x) = SpringBalloon::new(1, false, 1.0);
    let mut v = vec![0.0; x.len()];
    let mut be = BackwardEuler::new(BackwardEulerParams::default())
        .expect("valid parameters")
        .with_linear_solver(solver());
    be.step(&mut sys, 0.0, 2e-3, &mut x, &mut v, None)
        .expect("step");
    let dynamic = std::mem::take(&mut *recorded.lock().unwrap());
    assert!(
        !dynamic.is_empty() && dynamic.iter().all(|&r| r),
        "{dynamic:?}"
    );
    let mut statics = StaticSolver::new(StaticParams::default())
        .expect("valid parameters")
        .with_linear_solver(solver());
    statics
        .solve(&mut sys, 0.0, &mut x, None)
        .expect("static solve");
    let fixed = recorded.lock().unwrap().clone();
    assert!(!fixed.is_empty() && fixed.iter().all(|&r| !r), "{fixed:?}");
}
