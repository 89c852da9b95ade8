//! Tests of the backward Euler step.

use super::*;
use crate::linear::LinearSolverKind;
use crate::linear::{LinearSolverParams, PcgPreconditioner};
use crate::newton::convergence::forcing_tolerance;
use crate::system::LowRankTerm;
use crate::system::{ForceSystem, SystemError, TangentKind};
use crate::timing::{PhaseTimes, ms_since};
use balloon_test_support::{Rng, check_jacobian};
use nalgebra::{DMatrix, DVector};
use std::time::Instant;

/// Chain of 3D springs (nonlinear, with rest lengths) plus a nonlinear rank-1 potential
/// `phi(u . x) = s^4 / 4` (its Hessian `3 s^2 u u^T` plays the role of the gas term), plus
/// an optional linear quadratic part `1/2 x^T K0 x`.
#[derive(Debug, Clone)]
struct Chain {
    masses: Vec<f64>,
    springs: Vec<(usize, usize, f64, f64)>,
    u: Vec<f64>,
    x: Vec<f64>,
    low_rank: Vec<LowRankTerm>,
    nonlinear: bool,
    /// Linear part (dense, small) for the linear tests.
    k0: Option<DMatrix<f64>>,
    poison: bool,
    offers_diagonal: bool,
}

impl Chain {
    fn new(nv: usize, nonlinear: bool, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let n = 3 * nv;
        let masses = (0..n).map(|i| 0.1 + 0.01 * (i / 3) as f64).collect();
        let mut springs = Vec::new();
        for i in 0..nv - 1 {
            springs.push((i, i + 1, 50.0 + 10.0 * rng.next_f64(), 0.1));
            if i + 2 < nv {
                springs.push((i, i + 2, 20.0, 0.2));
            }
        }
        let u = rng.vector(n).iter().map(|v| 0.3 * v).collect();
        Self {
            masses,
            springs,
            u,
            x: vec![0.0; n],
            low_rank: vec![],
            nonlinear,
            k0: None,
            poison: false,
            offers_diagonal: false,
        }
    }

    fn positions(nv: usize, seed: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed);
        (0..3 * nv)
            .map(|i| if i % 3 == 0 { 0.1 * (i / 3) as f64 } else { 0.0 } + 0.02 * rng.next_f64())
            .collect()
    }

    fn s(&self, x: &[f64]) -> f64 {
        self.u.iter().zip(x).map(|(a, b)| a * b).sum()
    }

    fn energy(&self, x: &[f64]) -> f64 {
        let mut e = 0.0;
        if self.nonlinear {
            for &(i, j, k, l0) in &self.springs {
                let d: f64 = (0..3)
                    .map(|c| (x[3 * i + c] - x[3 * j + c]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                e += 0.5 * k * (d - l0).powi(2);
            }
            e += self.s(x).powi(4) / 4.0;
        }
        if let Some(k0) = &self.k0 {
            let xv = DVector::from_column_slice(x);
            e += 0.5 * xv.dot(&(k0 * &xv));
        }
        e
    }

    fn spring_block(
        &self,
        x: &[f64],
        i: usize,
        j: usize,
        k: f64,
        l0: f64,
    ) -> nalgebra::Matrix3<f64> {
        let d = nalgebra::Vector3::from_fn(|c, _| x[3 * i + c] - x[3 * j + c]);
        let l = d.norm();
        let nn = d * d.transpose() / (l * l);
        (nn + (nalgebra::Matrix3::identity() - nn) * (1.0 - l0 / l)) * k
    }
}

impl ForceSystem for Chain {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, _time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        f.fill(0.0);
        self.low_rank.clear();
        if self.nonlinear {
            for &(i, j, k, l0) in &self.springs {
                let d = nalgebra::Vector3::from_fn(|c, _| x[3 * i + c] - x[3 * j + c]);
                let l = d.norm();
                let fi = -k * (l - l0) * d / l;
                for c in 0..3 {
                    f[3 * i + c] += fi[c];
                    f[3 * j + c] -= fi[c];
                }
            }
            let s = self.s(x);
            for (fi, ui) in f.iter_mut().zip(&self.u) {
                *fi -= s.powi(3) * ui;
            }
            self.low_rank.push(LowRankTerm {
                coefficient: 3.0 * s * s,
                vector: self.u.clone(),
            });
        }
        if let Some(k0) = &self.k0 {
            let kx = k0 * DVector::from_column_slice(x);
            for i in 0..f.len() {
                f[i] -= kx[i];
            }
        }
        if self.poison {
            f[7] = f64::NAN;
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        let mut t = Vec::new();
        self.add_stiffness_triplets(&mut t).unwrap();
        for (r, c, v) in t {
            df[r] -= v * dx[c];
        }
        for lr in &self.low_rank {
            let s: f64 = lr.vector.iter().zip(dx).map(|(a, b)| a * b).sum();
            for i in 0..df.len() {
                df[i] -= lr.coefficient * s * lr.vector[i];
            }
        }
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        if self.nonlinear {
            for &(i, j, k, l0) in &self.springs {
                let b = self.spring_block(&self.x, i, j, k, l0);
                for r in 0..3 {
                    for c in 0..3 {
                        t.push((3 * i + r, 3 * i + c, b[(r, c)]));
                        t.push((3 * j + r, 3 * j + c, b[(r, c)]));
                        t.push((3 * i + r, 3 * j + c, -b[(r, c)]));
                        t.push((3 * j + r, 3 * i + c, -b[(r, c)]));
                    }
                }
            }
        }
        if let Some(k0) = &self.k0 {
            for r in 0..k0.nrows() {
                for c in 0..k0.ncols() {
                    if k0[(r, c)] != 0.0 {
                        t.push((r, c, k0[(r, c)]));
                    }
                }
            }
        }
        Ok(())
    }
    fn low_rank_terms(&self) -> &[LowRankTerm] {
        &self.low_rank
    }
    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        Ok(Some(self.energy(x)))
    }
    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        if !self.offers_diagonal {
            return Err(SystemError::AssemblyUnsupported);
        }
        let mut t = Vec::new();
        self.add_stiffness_triplets(&mut t)?;
        for (r, c, v) in t {
            if r == c {
                diagonal[r] += v;
            }
        }
        Ok(())
    }
}

/// Free particles: no forces at all (`.1`: whether it can assemble its (zero) stiffness).
#[derive(Debug)]
struct Free(Vec<f64>, bool);
impl ForceSystem for Free {
    fn num_dofs(&self) -> usize {
        self.0.len()
    }
    fn masses(&self) -> &[f64] {
        &self.0
    }
    fn forces(&mut self, _t: f64, _x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        f.fill(0.0);
        Ok(())
    }
    fn add_force_differential(&self, _dx: &[f64], _df: &mut [f64]) {}
    fn add_stiffness_triplets(&self, _t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        if self.1 {
            Ok(())
        } else {
            Err(SystemError::AssemblyUnsupported)
        }
    }
}

fn linear_chain(nv: usize) -> Chain {
    let mut c = Chain::new(nv, false, 1);
    let n = 3 * nv;
    let mut k0 = DMatrix::zeros(n, n);
    for i in 0..n {
        k0[(i, i)] = 200.0;
        if i + 3 < n {
            k0[(i, i + 3)] = -80.0;
            k0[(i + 3, i)] = -80.0;
        }
    }
    c.k0 = Some(k0);
    c
}

fn params(kind: LinearSolverKind, iters: usize) -> BackwardEulerParams {
    BackwardEulerParams {
        newton_iterations: iters,
        newton_tolerance: 0.0,
        linear: LinearSolverParams {
            kind,
            max_iterations: 1000,
            relative_tolerance: 1e-12,
        },
        ..Default::default()
    }
}

#[test]
fn bad_inputs_are_typed_errors_naming_the_parameter_and_value() {
    let mut sys = Free(vec![1.0; 6], true);
    let (mut x, mut v) = (vec![0.0; 6], vec![0.0; 6]);
    let mut be = BackwardEuler::new(params(LinearSolverKind::Cholesky, 1)).unwrap();
    for dt in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        let err = be
            .step(&mut sys, 0.0, dt, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(err, IntegrateError::InvalidParameter { name: "dt", value, .. }
                if value.to_bits() == dt.to_bits()),
            "{err}"
        );
    }
    // Parameters are checked when set (on construction or by `set_params`), and a refused
    // set leaves the integrator as it was.
    let good = *be.params();
    let err = be
        .set_params(BackwardEulerParams {
            mass_damping: -2.0,
            ..good
        })
        .unwrap_err();
    assert!(
        matches!(err, IntegrateError::InvalidParameter { name: "mass_damping", value, .. } if value == -2.0),
        "{err}"
    );
    assert_eq!(*be.params(), good);
    for bad in [-0.1, 1.5, f64::NAN] {
        let p = BackwardEulerParams {
            inexact_forcing: bad,
            ..good
        };
        for err in [
            be.set_params(p).unwrap_err(),
            BackwardEuler::new(p).unwrap_err(),
        ] {
            assert!(
                matches!(
                    err,
                    IntegrateError::InvalidParameter {
                        name: "inexact_forcing",
                        ..
                    }
                ),
                "{err}"
            );
        }
    }
    be.step(&mut sys, 0.0, 1e-3, &mut x, &mut v, None).unwrap();
    let mut short = vec![0.0; 5];
    let err = be
        .step(&mut sys, 0.0, 1e-3, &mut x, &mut short, None)
        .unwrap_err();
    assert_eq!(
        err,
        IntegrateError::LengthMismatch {
            what: "v",
            len: 5,
            expected: 6
        }
    );
    sys.0[4] = 0.0;
    let err = be
        .step(&mut sys, 0.0, 1e-3, &mut x, &mut v, None)
        .unwrap_err();
    assert_eq!(
        err,
        IntegrateError::InvalidMass {
            dof: 4,
            vertex: 1,
            mass: 0.0
        }
    );
    assert!(err.to_string().contains("dof 4 (vertex 1)"), "{err}");
}

#[test]
fn forcing_tolerance_asks_for_a_tenth_of_the_target_within_bounds() {
    // Residual 1e-3, target 1e-6: a linearised residual of 1e-7, i.e. 1e-4 relative.
    assert!((forcing_tolerance(0.1, 1e-6, 1e-3, 1e-8) - 1e-4).abs() < 1e-18);
    // Near the target the solve may stop at 0.1, never looser.
    assert!((forcing_tolerance(0.1, 1e-6, 2e-6, 1e-8) - 0.05).abs() < 1e-15);
    assert_eq!(forcing_tolerance(0.1, 1e-6, 5e-7, 1e-8), 0.1);
    // Far from it, or with forcing 0, the solver's own tolerance.
    assert_eq!(forcing_tolerance(0.1, 1e-6, 1e3, 1e-8), 1e-8);
    assert_eq!(forcing_tolerance(0.0, 1e-6, 1e-3, 1e-8), 1e-8);
    // A zero residual (nothing to solve) gives the floor, not a NaN.
    assert_eq!(forcing_tolerance(0.1, 1e-6, 0.0, 1e-8), 1e-8);
    // A configured tolerance looser than 0.1 is capped.
    assert_eq!(forcing_tolerance(0.1, 1e-6, 1e-3, 0.5), 0.1);
}

#[test]
fn test_system_differential_and_stiffness_match_finite_differences() {
    let nv = 6;
    let sys = Chain::new(nv, true, 3);
    let x = Chain::positions(nv, 4);
    let f = |x: &[f64]| {
        let mut s = sys.clone();
        let mut f = vec![0.0; x.len()];
        s.forces(0.0, x, &mut f).unwrap();
        f
    };
    check_jacobian(
        f,
        |x, dx| {
            let mut s = sys.clone();
            let mut tmp = vec![0.0; x.len()];
            s.forces(0.0, x, &mut tmp).unwrap();
            let mut df = vec![0.0; x.len()];
            s.add_force_differential(dx, &mut df);
            df
        },
        &x,
        1e-6,
        1e-6,
        5,
    );
    balloon_test_support::check_gradient(
        |x| sys.energy(x),
        |x| {
            let mut s = sys.clone();
            let mut f = vec![0.0; x.len()];
            s.forces(0.0, x, &mut f).unwrap();
            f.iter().map(|v| -v).collect()
        },
        &x,
        1e-6,
        1e-6,
    );
}

#[test]
fn all_solvers_and_preconditioners_agree_on_a_nonlinear_step() {
    let nv = 8;
    let x0 = Chain::positions(nv, 8);
    let v0: Vec<f64> = Rng::new(9).vector(3 * nv);
    let mut results = Vec::new();
    for (kind, pre) in [
        (LinearSolverKind::MatrixFreeCg, PcgPreconditioner::Jacobi),
        (LinearSolverKind::Pcg, PcgPreconditioner::Jacobi),
        (LinearSolverKind::Pcg, PcgPreconditioner::IncompleteCholesky),
        (LinearSolverKind::Cholesky, PcgPreconditioner::Jacobi),
        (LinearSolverKind::FactorizedPcg, PcgPreconditioner::Jacobi),
    ] {
        let mut sys = Chain::new(nv, true, 3);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            mass_damping: 0.5,
            stiffness_damping: 0.001,
            gravity: [0.0, -9.81, 0.0],
            pcg_preconditioner: pre,
            ..params(kind, 4)
        })
        .unwrap();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        for s in 0..3 {
            let info = be
                .step(&mut sys, 0.01 * s as f64, 0.01, &mut x, &mut v, None)
                .unwrap();
            assert_eq!(info.newton_iterations, 4);
            assert!(info.converged, "{kind}: {info:?}");
            // Newton converges quadratically: the residual drops by orders of magnitude.
            let r = &info.newton_residuals;
            assert!(r[3] < 1e-6 * r[0], "{kind}: {r:?}");
        }
        if kind != LinearSolverKind::MatrixFreeCg {
            // 3 steps x 4 Newton iterations, one pattern (and symbolic factorisation) build.
            assert_eq!(be.sparse_pattern_builds(), 1);
        }
        results.push((x, v));
    }
    for (x, v) in &results[1..] {
        for i in 0..x.len() {
            assert!((x[i] - results[0].0[i]).abs() < 1e-9, "x[{i}]");
            assert!((v[i] - results[0].1[i]).abs() < 1e-7, "v[{i}]");
        }
    }
}

#[test]
fn one_newton_iteration_is_exact_on_a_linear_system() {
    let nv = 5;
    let n = 3 * nv;
    let (dt, alpha, beta) = (0.02, 0.3, 0.004);
    let x0 = Chain::positions(nv, 2);
    let v0 = Rng::new(3).vector(n);
    let ext = Rng::new(4).vector(n);
    for kind in [
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
    ] {
        let mut sys = linear_chain(nv);
        let k0 = sys.k0.clone().unwrap();
        let m = DMatrix::from_diagonal(&DVector::from_column_slice(&sys.masses));
        let mut be = BackwardEuler::new(BackwardEulerParams {
            mass_damping: alpha,
            stiffness_damping: beta,
            ..params(kind, 1)
        })
        .unwrap();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        be.step(&mut sys, 0.0, dt, &mut x, &mut v, Some(&ext))
            .unwrap();
        // (M + dt C + dt^2 K) v1 = M v0 + dt (-K x0 + f_ext), C = alpha M + beta K.
        let a = &m + (&m * alpha + &k0 * beta) * dt + &k0 * (dt * dt);
        let rhs = &m * DVector::from_column_slice(&v0)
            + (-(&k0 * DVector::from_column_slice(&x0)) + DVector::from_column_slice(&ext)) * dt;
        let v1 = a.lu().solve(&rhs).unwrap();
        for i in 0..n {
            assert!(
                (v[i] - v1[i]).abs() < 1e-9 * (1.0 + v1[i].abs()),
                "{kind} v[{i}]"
            );
            assert!((x[i] - (x0[i] + dt * v1[i])).abs() < 1e-11, "{kind} x[{i}]");
        }
        // A second iteration finds nothing left to correct.
        let mut sys = linear_chain(nv);
        let mut be = BackwardEuler::new(params(kind, 2)).unwrap();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
        assert!(
            info.newton_residuals[1] < 1e-9 * info.newton_residuals[0],
            "{info:?}"
        );
    }
}

#[test]
fn newton_matrix_round_trips_through_matrix_market_and_equals_the_dense_assembly() {
    let nv = 5;
    let n = 3 * nv;
    let (dt, alpha, beta) = (0.02, 0.3, 0.004);
    let x0 = Chain::positions(nv, 2);
    let mut sys = linear_chain(nv);
    let k0 = sys.k0.clone().unwrap();
    let mut be = BackwardEuler::new(BackwardEulerParams {
        mass_damping: alpha,
        stiffness_damping: beta,
        ..params(LinearSolverKind::Cholesky, 1)
    })
    .unwrap();
    assert!(be.newton_matrix().is_none());
    let (mut x, mut v) = (x0.clone(), Rng::new(3).vector(n));
    be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("newton.mtx");
    be.write_newton_matrix(&path).unwrap();
    let read = crate::linear::read_matrix_market(&path).unwrap();
    assert_eq!(read, be.newton_matrix().unwrap());
    // A = (1 + dt alpha) M + (dt^2 + dt beta) K (Eq. 23).
    let m = DMatrix::from_diagonal(&DVector::from_column_slice(&sys.masses));
    let expected = &m * (1.0 + dt * alpha) + &k0 * (dt * dt + dt * beta);
    let mut dense = DMatrix::<f64>::zeros(n, n);
    for (value, (r, c)) in read.iter() {
        dense[(r, c)] += *value;
    }
    for r in 0..n {
        for c in 0..n {
            approx::assert_relative_eq!(
                dense[(r, c)],
                expected[(r, c)],
                epsilon = 1e-12,
                max_relative = 1e-12
            );
        }
    }
    // The matrix-free solver assembles nothing: no Newton matrix, a typed error.
    let mut be = BackwardEuler::new(params(LinearSolverKind::MatrixFreeCg, 1)).unwrap();
    be.step(&mut sys, 0.0, dt, &mut x0.clone(), &mut vec![0.0; n], None)
        .unwrap();
    assert!(be.newton_matrix().is_none());
    assert_eq!(
        be.write_newton_matrix(&path).unwrap_err(),
        crate::linear::SolveError::NotAssembled
    );
}

#[test]
fn stiffness_diagonal_preconditioner_cuts_cg_iterations_and_keeps_the_answer() {
    // Stiffness varying over four orders of magnitude: the mass-only Jacobi preconditioner is
    // blind to it, diag(A) is not.
    let nv = 20;
    let n = 3 * nv;
    let mut runs = Vec::new();
    for offers in [false, true] {
        let mut sys = linear_chain(nv);
        let k0 = sys.k0.as_mut().unwrap();
        for i in 0..n {
            let s = 10f64.powi((i % 5) as i32);
            k0[(i, i)] *= s;
        }
        sys.offers_diagonal = offers;
        let mut p = params(LinearSolverKind::MatrixFreeCg, 1);
        p.linear.relative_tolerance = 1e-13;
        let mut be = BackwardEuler::new(p).unwrap();
        let (mut x, mut v) = (Chain::positions(nv, 3), Rng::new(6).vector(n));
        let info = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None).unwrap();
        assert!(info.converged);
        assert_eq!(be.stiffness_preconditioned(), offers);
        runs.push((info.linear_iterations[0], v));
    }
    assert!(
        2 * runs[1].0 < runs[0].0,
        "iterations {} vs {}",
        runs[1].0,
        runs[0].0
    );
    for i in 0..n {
        assert!((runs[0].1[i] - runs[1].1[i]).abs() < 1e-7 * (1.0 + runs[0].1[i].abs()));
    }
}

#[test]
fn indefinite_newton_matrix_is_regularized_or_reported() {
    // A negative stiffness (an unstable, buckling-like mode) makes A = M + dt^2 K indefinite.
    // With regularization the solve is retried with a mass shift and the step completes;
    // without it every solver reports the breakdown.
    let nv = 4;
    for kind in [
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
    ] {
        for regularize in [true, false] {
            let mut sys = linear_chain(nv);
            sys.k0.as_mut().unwrap()[(4, 4)] = -2e3;
            let mut be = BackwardEuler::new(BackwardEulerParams {
                regularize_indefinite: regularize,
                ..params(kind, 2)
            })
            .unwrap();
            let (mut x, mut v) = (Chain::positions(nv, 1), Rng::new(2).vector(3 * nv));
            let r = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None);
            if regularize {
                let info = r.unwrap();
                assert!(
                    info.regularized_solves > 0 && info.max_regularization > 0.0,
                    "{kind}"
                );
                assert!(x.iter().chain(&v).all(|a| a.is_finite()));
            } else {
                let e = r.unwrap_err();
                assert!(
                    matches!(e, IntegrateError::Linear { iteration: 0, .. }),
                    "{kind}: {e}"
                );
            }
        }
    }
}

#[test]
fn falling_particle_matches_backward_euler_closed_form() {
    // Free fall: backward Euler gives v_n = v0 + n dt g and x_n = x0 + n dt v0 +
    // dt^2 g n (n + 1) / 2 (it uses the end-of-step velocity); mass damping alpha divides the
    // velocity update by (1 + dt alpha).
    let g = [0.0, 0.0, -9.81];
    let dt = 0.01;
    for kind in [LinearSolverKind::MatrixFreeCg, LinearSolverKind::Cholesky] {
        let mut sys = Free(vec![0.2; 3], true);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            gravity: g,
            ..params(kind, 3)
        })
        .unwrap();
        let (x0, v0) = ([1.0, 2.0, 3.0], [0.5, 0.0, 1.0]);
        let (mut x, mut v) = (x0.to_vec(), v0.to_vec());
        let steps = 20;
        for s in 0..steps {
            let info = be
                .step(&mut sys, s as f64 * dt, dt, &mut x, &mut v, None)
                .unwrap();
            assert!(info.converged);
        }
        let nf = steps as f64;
        for c in 0..3 {
            let ve = v0[c] + nf * dt * g[c];
            let xe = x0[c] + nf * dt * v0[c] + dt * dt * g[c] * nf * (nf + 1.0) / 2.0;
            assert!((v[c] - ve).abs() < 1e-12, "{kind} v{c}");
            assert!((x[c] - xe).abs() < 1e-12, "{kind} x{c}");
        }
    }
    let mut sys = Free(vec![0.2; 3], true);
    let alpha = 2.0;
    let mut be = BackwardEuler::new(BackwardEulerParams {
        gravity: g,
        mass_damping: alpha,
        ..params(LinearSolverKind::MatrixFreeCg, 1)
    })
    .unwrap();
    let (mut x, mut v) = (vec![0.0; 3], vec![0.0, 0.0, 4.0]);
    be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
    let ve = (4.0 + dt * g[2]) / (1.0 + dt * alpha);
    assert!((v[2] - ve).abs() < 1e-12 && (x[2] - dt * ve).abs() < 1e-14);
}

#[test]
fn damping_reduces_energy() {
    // Backward Euler on a convex quadratic energy never creates energy, and Rayleigh damping
    // removes more: the total energy decreases monotonically and ends below the undamped run.
    let nv = 6;
    let run = |alpha: f64, beta: f64| {
        let mut sys = linear_chain(nv);
        let mut be = BackwardEuler::new(BackwardEulerParams {
            mass_damping: alpha,
            stiffness_damping: beta,
            ..params(LinearSolverKind::MatrixFreeCg, 1)
        })
        .unwrap();
        let mut x = Chain::positions(nv, 5);
        let mut v = vec![0.0; 3 * nv];
        let energy = |sys: &Chain, x: &[f64], v: &[f64]| {
            sys.energy(x)
                + 0.5
                    * v.iter()
                        .zip(&sys.masses)
                        .map(|(v, m)| m * v * v)
                        .sum::<f64>()
        };
        let mut e = vec![energy(&sys, &x, &v)];
        for s in 0..30 {
            be.step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                .unwrap();
            e.push(energy(&sys, &x, &v));
        }
        e
    };
    let undamped = run(0.0, 0.0);
    for (a, b) in [(1.0, 0.0), (0.0, 0.01)] {
        let damped = run(a, b);
        assert!(
            damped.windows(2).all(|w| w[1] <= w[0] + 1e-12),
            "{damped:?}"
        );
        assert!(damped.last().unwrap() < undamped.last().unwrap());
    }
    assert!(undamped.windows(2).all(|w| w[1] <= w[0] + 1e-12));
}

/// A chain whose `residual_forces` leaves its linearisation at the previous point (as a
/// lazy system may) until `refresh_stiffness`; every stiffness query panics while stale.
struct LazyChain {
    inner: Chain,
    pending: Vec<f64>,
    pending_low_rank: Vec<LowRankTerm>,
    stale: bool,
    residual_calls: usize,
    refreshes: usize,
    /// Calls of `forces` (each linearises).
    linearizations: usize,
    /// Whether it offers `residual_forces_and_energy` as one fused evaluation.
    fuse: bool,
    /// Calls of `residual_forces_and_energy` and of `potential_energy` alone.
    fused_calls: usize,
    energy_calls: usize,
}

impl LazyChain {
    fn check(&self, what: &str) {
        assert!(!self.stale, "{what} asked while the stiffness is stale");
    }
}

impl ForceSystem for LazyChain {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }
    fn masses(&self) -> &[f64] {
        self.inner.masses()
    }
    fn forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.stale = false;
        self.linearizations += 1;
        self.inner.forces(t, x, f)
    }
    fn residual_forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        let (old_x, old_lr) = (self.inner.x.clone(), self.inner.low_rank.clone());
        self.inner.forces(t, x, f)?;
        self.pending = std::mem::replace(&mut self.inner.x, old_x);
        self.pending_low_rank = std::mem::replace(&mut self.inner.low_rank, old_lr);
        self.stale = true;
        self.residual_calls += 1;
        Ok(())
    }
    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        if self.stale {
            self.inner.x.clone_from(&self.pending);
            self.inner.low_rank.clone_from(&self.pending_low_rank);
            self.stale = false;
            self.refreshes += 1;
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        self.check("the differential");
        self.inner.add_force_differential(dx, df);
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        self.check("the stiffness");
        self.inner.add_stiffness_triplets(t)
    }
    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        self.check("the stiffness diagonal");
        self.inner.add_stiffness_diagonal(diagonal)
    }
    fn low_rank_terms(&self) -> &[LowRankTerm] {
        self.check("the low-rank terms");
        self.inner.low_rank_terms()
    }
    fn potential_energy(&mut self, t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        self.energy_calls += 1;
        self.inner.potential_energy(t, x)
    }
    fn residual_forces_and_energy(
        &mut self,
        t: f64,
        x: &[f64],
        f: &mut [f64],
    ) -> Result<Option<f64>, SystemError> {
        self.fused_calls += 1;
        self.residual_forces(t, x, f)?;
        self.inner.potential_energy(t, x)
    }
    fn fuses_forces_and_energy(&self) -> bool {
        self.fuse
    }
}

fn lazy_chain(nv: usize) -> LazyChain {
    LazyChain {
        inner: Chain::new(nv, true, 7),
        pending: Vec::new(),
        pending_low_rank: Vec::new(),
        stale: false,
        residual_calls: 0,
        refreshes: 0,
        linearizations: 0,
        fuse: false,
        fused_calls: 0,
        energy_calls: 0,
    }
}

/// The settings of the chord tests: a damped chain settling to rest, Newton to 1e-6.
fn chord_params(kind: LinearSolverKind, reuse: usize) -> BackwardEulerParams {
    let mut p = converging(kind, 30, 1e-6);
    p.tangent_reuse_steps = reuse;
    p.mass_damping = 10.0;
    p
}

/// Runs `steps` steps of the lazy chain (whose stale stiffness panics when asked for) with
/// `tangent_reuse_steps = reuse`, calling `between(step, system)` before each; returns the
/// states, whether each step was a chord step, the Newton iterations and the
/// linearisations (`forces` calls and stiffness refreshes).
fn chord_run(
    kind: LinearSolverKind,
    reuse: usize,
    steps: usize,
    mut between: impl FnMut(usize, &mut LazyChain),
) -> (Vec<f64>, Vec<f64>, Vec<bool>, usize, usize) {
    let nv = 10;
    let mut be = BackwardEuler::new(chord_params(kind, reuse)).unwrap();
    let mut sys = lazy_chain(nv);
    let mut x = Chain::positions(nv, 5);
    let mut v: Vec<f64> = Rng::new(4).vector(3 * nv);
    let (mut chords, mut newton) = (Vec::new(), 0);
    for s in 0..steps {
        between(s, &mut sys);
        let info = be
            .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
            .unwrap();
        chords.push(info.reused_tangent);
        newton += info.newton_iterations;
    }
    (x, v, chords, newton, sys.refreshes + sys.linearizations)
}

/// Largest entry-wise difference of `a` and `b` over the largest entry of `b`.
fn relative_gap(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
        / scale
}

#[test]
fn chord_steps_reuse_the_last_matrix_and_reach_the_same_states() {
    // A chord step (the first Newton iteration with the last step's matrix and low-rank
    // terms, after a step one iteration settled) only picks the direction: every step
    // still stops on the residual, so 200 steps of a damped nonlinear chain settling to
    // rest end where the run with a fresh tangent at every iteration does, to the Newton
    // tolerance (1e-6). Chord steps are taken once the chain is near rest, they halve the
    // linearisations for a few more Newton iterations, and they never ask the lazy chain
    // for its stale stiffness or low-rank terms (it panics).
    for kind in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::Pcg,
    ] {
        let (x1, v1, chords, newton1, lin1) = chord_run(kind, 8, 200, |_, _| {});
        let (x0, v0, none, newton0, lin0) = chord_run(kind, 0, 200, |_, _| {});
        let taken = chords.iter().filter(|&&c| c).count();
        assert!(
            !none.contains(&true),
            "{kind}: no chord steps when reuse is off"
        );
        assert!(!chords[0], "{kind}: no chord step without a last matrix");
        assert!(taken >= 100, "{kind}: {taken} chord steps of 200");
        assert!(
            2 * lin1 < lin0 + 20,
            "{kind}: linearisations {lin1} against {lin0}"
        );
        assert!(
            10 * newton1 < 11 * newton0,
            "{kind}: Newton {newton1} against {newton0}"
        );
        let (gx, gv) = (relative_gap(&x1, &x0), relative_gap(&v1, &v0));
        assert!(gx < 1e-6 && gv < 1e-4, "{kind}: gaps {gx:e} {gv:e}");
        // At most 8 chord steps in a row, then a fresh tangent.
        let longest = chords.split(|&c| !c).map(<[bool]>::len).max().unwrap_or(0);
        assert!(longest <= 8, "{kind}: {longest} chord steps in a row");
    }
}

#[test]
fn a_chord_step_the_line_search_would_cut_is_not_taken() {
    // Stiffening the springs a thousandfold and lengthening them by 30 % between two steps
    // of the settled chain makes the last step's matrix a poor one far from the new rest:
    // its full step raises the incremental potential, so that step goes on with a fresh
    // tangent from the same iterate (no chord step counted) and lands where the run without
    // reuse does.
    let stiffen = |s: usize, sys: &mut LazyChain| {
        if s == 150 {
            for spring in &mut sys.inner.springs {
                spring.2 *= 1000.0;
                spring.3 *= 1.3;
            }
        }
    };
    let kind = LinearSolverKind::Cholesky;
    let (x1, v1, chords, _, _) = chord_run(kind, 1000, 152, stiffen);
    let (x0, v0, _, _, _) = chord_run(kind, 0, 152, stiffen);
    assert!(chords[149], "a chord step right before the change");
    assert!(!chords[150], "no chord step across the stiffening");
    let (gx, gv) = (relative_gap(&x1, &x0), relative_gap(&v1, &v0));
    assert!(gx < 1e-6 && gv < 1e-4, "gaps {gx:e} {gv:e}");
}

#[test]
fn a_step_of_another_size_does_not_reuse_the_matrix() {
    let mut be = BackwardEuler::new(chord_params(LinearSolverKind::Cholesky, 1000)).unwrap();
    let mut sys = lazy_chain(10);
    let mut x = Chain::positions(10, 5);
    let mut v: Vec<f64> = Rng::new(4).vector(30);
    let mut last = false;
    for s in 0..150 {
        last = be
            .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
            .unwrap()
            .reused_tangent;
    }
    assert!(last, "chord steps at the settled state");
    let info = be.step(&mut sys, 1.5, 0.005, &mut x, &mut v, None).unwrap();
    assert!(
        !info.reused_tangent,
        "the Newton matrix of dt = 0.005 differs"
    );
}

#[test]
fn fused_trial_energies_and_forces_give_the_same_steps_in_fewer_passes() {
    // A system that evaluates a trial's forces and energy together
    // (`fuses_forces_and_energy`) takes the same Newton iterates, bit for bit, as one whose
    // line search asks for the energy first and the forces of an accepted trial after it;
    // the energy alone is then asked for only where Newton linearises (the first iterate
    // of a step that is not a chord step), never for a trial. With and without chord
    // steps, for every linear solver.
    let nv = 10;
    let x0 = Chain::positions(nv, 5);
    let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
    for kind in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::Pcg,
        LinearSolverKind::MatrixFreeCg,
    ] {
        for reuse in [0, 3] {
            let mut p = converging(kind, 30, 1e-10);
            p.tangent_reuse_steps = reuse;
            let run = |fuse: bool| {
                let mut be = BackwardEuler::new(p).unwrap();
                let mut sys = lazy_chain(nv);
                sys.fuse = fuse;
                let (mut x, mut v) = (x0.clone(), v0.clone());
                let (mut newton, mut cuts, mut linearized_starts) = (0, 0, 0);
                for s in 0..8 {
                    let info = be
                        .step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                        .unwrap();
                    newton += info.newton_iterations;
                    cuts += info.line_search_cuts;
                    linearized_starts += usize::from(!info.reused_tangent);
                }
                (x, v, newton, cuts, linearized_starts, sys)
            };
            let (xf, vf, nf, cf, starts, fused) = run(true);
            let (xs, vs, ns, cs, _, split) = run(false);
            assert_eq!((nf, cf), (ns, cs), "{kind}, reuse {reuse}");
            assert!(
                xf.iter().zip(&xs).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{kind}, reuse {reuse}"
            );
            assert!(
                vf.iter().zip(&vs).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{kind}, reuse {reuse}"
            );
            // Every trial is fused: at least one per Newton iteration.
            assert!(fused.fused_calls >= nf, "{kind}: {}", fused.fused_calls);
            assert_eq!(split.fused_calls, 0, "{kind}");
            assert_eq!(fused.energy_calls, starts, "{kind}, reuse {reuse}");
            assert!(
                split.energy_calls >= nf + 8,
                "{kind}: {} energies",
                split.energy_calls
            );
        }
    }
}

#[test]
fn line_search_trials_may_skip_the_stiffness_and_the_step_is_unchanged() {
    // The trials of the line search use `residual_forces`; before Newton goes on from one,
    // the integrator refreshes the stiffness (a stale query would panic). The states are
    // bit-identical to those of the same chain linearised at every evaluation, for every
    // linear solver, with and without stiffness damping (which needs `K v` at once).
    let nv = 10;
    let x0 = Chain::positions(nv, 5);
    let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
    for kind in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::Pcg,
        LinearSolverKind::MatrixFreeCg,
    ] {
        for beta in [0.0, 0.01] {
            let mut p = converging(kind, 30, 1e-10);
            p.stiffness_damping = beta;
            let run = |lazy: bool| {
                let mut be = BackwardEuler::new(p).unwrap();
                let mut sys = lazy_chain(nv);
                let (mut x, mut v) = (x0.clone(), v0.clone());
                let mut newton = 0;
                for s in 0..6 {
                    let info = if lazy {
                        be.step(&mut sys, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                    } else {
                        be.step(&mut sys.inner, s as f64 * 0.01, 0.01, &mut x, &mut v, None)
                    }
                    .unwrap();
                    newton += info.newton_iterations;
                }
                (x, v, newton, sys.residual_calls, sys.refreshes)
            };
            let (xl, vl, nl, calls, refreshes) = run(true);
            let (xe, ve, ne, _, _) = run(false);
            assert_eq!(nl, ne, "{kind}, beta {beta}");
            assert!(
                xl.iter().zip(&xe).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{kind}"
            );
            assert!(
                vl.iter().zip(&ve).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{kind}"
            );
            if beta == 0.0 {
                // One trial per Newton iteration at least; a refresh only where Newton went
                // on from a trial (not after the last one of each step).
                assert!(
                    calls >= nl,
                    "{kind}: {calls} trials, {nl} Newton iterations"
                );
                assert!(
                    refreshes < calls && refreshes >= nl - 6,
                    "{kind}: {refreshes}"
                );
            } else {
                assert_eq!(
                    calls, 0,
                    "{kind}: stiffness damping linearises every evaluation"
                );
            }
        }
    }
}

#[test]
fn phase_times_account_for_the_step_without_double_counting() {
    // The phases are timed separately: per step they add up to at most the step's wall
    // time, a step without a factorisation has no factorisation time, a matrix-free solve
    // no assembly, and the running total is the sum of the steps'.
    let nv = 12;
    let x0 = Chain::positions(nv, 5);
    let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
    for kind in [
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::MatrixFreeCg,
    ] {
        let mut sys = Chain::new(nv, true, 7);
        let mut p = converging(kind, 30, 1e-9);
        p.refactor_iterations = 6;
        let mut be = BackwardEuler::new(p).unwrap();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        let mut sum = PhaseTimes::default();
        let mut factorized_steps = 0;
        for s in 0..8 {
            let started = Instant::now();
            let info = be
                .step(&mut sys, s as f64 * 0.002, 0.002, &mut x, &mut v, None)
                .unwrap();
            let wall = ms_since(started);
            let t = info.times;
            assert!(t.total_ms() <= wall + 1e-9, "{kind}: {t} in {wall} ms");
            assert!(t.forces_ms > 0.0 && t.energy_ms > 0.0, "{kind}: {t}");
            assert!(t.solve_ms > 0.0 && t.projection_ms == 0.0, "{kind}: {t}");
            assert_eq!(
                t.factorization_ms > 0.0,
                info.factorizations > 0,
                "{kind}: {t}"
            );
            if kind == LinearSolverKind::MatrixFreeCg {
                assert_eq!(t.assembly_ms, 0.0, "{t}");
            } else {
                assert!(t.assembly_ms > 0.0, "{t}");
            }
            factorized_steps += usize::from(info.factorizations > 0);
            sum += t;
        }
        let total = be.phase_times();
        assert!(
            (total.total_ms() - sum.total_ms()).abs() < 1e-9,
            "{total} vs {sum}"
        );
        if kind == LinearSolverKind::FactorizedPcg {
            // The lagged factor is reused: some steps factorise, some do not.
            assert!((1..8).contains(&factorized_steps), "{factorized_steps}");
        }
    }
}

#[test]
fn factorized_pcg_reuses_its_factor_and_refreshes_it_when_stale() {
    // A chain whose stiffness barely changes: the factor of the first Newton matrix
    // preconditions all later solves, and the answer is the Cholesky one.
    let nv = 12;
    let x0 = Chain::positions(nv, 5);
    let v0: Vec<f64> = Rng::new(4).vector(3 * nv);
    let run = |kind: LinearSolverKind, dts: &[f64]| {
        let mut sys = Chain::new(nv, true, 7);
        let mut p = params(kind, 3);
        p.linear.relative_tolerance = 1e-11;
        p.refactor_iterations = 6;
        let mut be = BackwardEuler::new(p).unwrap();
        let (mut x, mut v) = (x0.clone(), v0.clone());
        let mut infos = Vec::new();
        let mut t = 0.0;
        for &dt in dts {
            let info = be.step(&mut sys, t, dt, &mut x, &mut v, None).unwrap();
            assert!(info.converged, "{kind}: {info:?}");
            t += dt;
            infos.push(info);
        }
        (x, v, infos)
    };
    let dts = [0.002; 8];
    let (xc, vc, ic) = run(LinearSolverKind::Cholesky, &dts);
    let (xf, vf, inf) = run(LinearSolverKind::FactorizedPcg, &dts);
    assert!(ic.iter().all(|i| i.factorizations == 3));
    let total: usize = inf.iter().map(|i| i.factorizations).sum();
    assert!(inf[0].factorizations >= 1);
    assert!(total <= 2, "factorisations {total} of 24 solves");
    for i in 0..xc.len() {
        assert!((xf[i] - xc[i]).abs() < 1e-10, "x[{i}]");
        assert!((vf[i] - vc[i]).abs() < 1e-8 * (1.0 + vc[i].abs()), "v[{i}]");
    }
    // The time step jumps 100-fold: the old factor (of M + dt^2 K at the small dt) is a poor
    // preconditioner, so the solver refactorises and still converges.
    let (_, _, jumped) = run(
        LinearSolverKind::FactorizedPcg,
        &[0.0005, 0.0005, 0.05, 0.05, 0.05, 0.05],
    );
    assert!(jumped[1].factorizations == 0, "{:?}", jumped[1]);
    // After the slow solve the next six solves (the rest of step 2 and all of step 3)
    // refactorise first; then the lagged factor is tried again.
    let f: Vec<usize> = jumped.iter().map(|i| i.factorizations).collect();
    assert!(f[2] == 3 && f[3] == 3 && f[4] < 3, "{f:?}");
}

#[test]
fn projected_tangent_is_passed_to_the_system_or_refused() {
    // The test chain only has the exact tangent: asking for the projected one is a clear
    // error before any work, not a silent fallback.
    let nv = 4;
    let mut sys = Chain::new(nv, true, 3);
    let mut be = BackwardEuler::new(BackwardEulerParams {
        tangent: TangentKind::Projected,
        ..params(LinearSolverKind::Cholesky, 2)
    })
    .unwrap();
    let (mut x, mut v) = (Chain::positions(nv, 1), vec![0.0; 3 * nv]);
    let e = be
        .step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
        .unwrap_err();
    assert!(
        matches!(
            e,
            IntegrateError::System {
                source: SystemError::TangentUnsupported(TangentKind::Projected),
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("projected"), "{e}");
    assert_eq!(
        "Projected ".parse::<TangentKind>(),
        Ok(TangentKind::Projected)
    );
    assert_eq!(TangentKind::Exact.to_string(), "exact");
    assert!("psd".parse::<TangentKind>().unwrap_err().contains("psd"));
}

#[test]
fn errors_are_reported_with_context() {
    let nv = 4;
    let x0 = Chain::positions(nv, 1);
    let mut sys = Chain::new(nv, true, 3);
    sys.poison = true;
    let mut be = BackwardEuler::new(params(LinearSolverKind::MatrixFreeCg, 3)).unwrap();
    let (mut x, mut v) = (x0.clone(), vec![0.0; 3 * nv]);
    let e = be
        .step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
        .unwrap_err();
    assert!(
        matches!(
            e,
            IntegrateError::NonFinite {
                dof: 7,
                vertex: 2,
                ..
            }
        ),
        "{e}"
    );
    let mut free = Free(vec![1.0; 3], false);
    let mut be = BackwardEuler::new(BackwardEulerParams {
        gravity: [0.0, 0.0, -1.0],
        ..params(LinearSolverKind::Pcg, 1)
    })
    .unwrap();
    let e = be
        .step(&mut free, 0.0, 0.01, &mut [0.0; 3], &mut [0.0; 3], None)
        .unwrap_err();
    assert!(
        matches!(
            e,
            IntegrateError::System {
                source: SystemError::AssemblyUnsupported,
                ..
            }
        ),
        "{e}"
    );
    let e = be
        .step(&mut free, 0.0, -0.01, &mut [0.0; 3], &mut [0.0; 3], None)
        .unwrap_err();
    assert!(e.to_string().contains("dt"), "{e}");
    let e = be
        .step(&mut free, 0.0, 0.01, &mut [0.0; 2], &mut [0.0; 3], None)
        .unwrap_err();
    assert!(e.to_string().contains("`x`"), "{e}");
    // Too few CG iterations: the step still returns but says it did not converge.
    let mut sys = Chain::new(8, true, 3);
    let mut p = params(LinearSolverKind::MatrixFreeCg, 1);
    p.linear.max_iterations = 1;
    let mut be = BackwardEuler::new(p).unwrap();
    let (mut x, mut v) = (Chain::positions(8, 2), Rng::new(1).vector(24));
    let info = be.step(&mut sys, 0.0, 0.01, &mut x, &mut v, None).unwrap();
    assert!(!info.converged && info.linear_residuals[0] > 1e-12);
}

/// Particles on stiff saturating springs to the origin, per coordinate
/// `W = k l^2 (sqrt(1 + (x/l)^2) - 1)`: the force saturates at `k l` far from rest, so the
/// quadratic model of Newton overshoots there (a full step from `x` lands near `-x^3/l^2`).
/// `.potential` says whether it reports its energy.
#[derive(Debug, Clone)]
struct Saturating {
    masses: Vec<f64>,
    k: f64,
    l: f64,
    x: Vec<f64>,
    potential: bool,
}

impl Saturating {
    fn new(potential: bool) -> Self {
        Self {
            masses: vec![1e-3; 3],
            k: 1e4,
            l: 0.01,
            x: vec![0.0; 3],
            potential,
        }
    }
}

impl ForceSystem for Saturating {
    fn num_dofs(&self) -> usize {
        3
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        for (f, x) in f.iter_mut().zip(x) {
            *f = -self.k * x / (1.0 + (x / self.l).powi(2)).sqrt();
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        for ((df, dx), x) in df.iter_mut().zip(dx).zip(&self.x) {
            *df -= self.k / (1.0 + (x / self.l).powi(2)).powf(1.5) * dx;
        }
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        for (i, x) in self.x.iter().enumerate() {
            t.push((i, i, self.k / (1.0 + (x / self.l).powi(2)).powf(1.5)));
        }
        Ok(())
    }
    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        Ok(self.potential.then(|| {
            x.iter()
                .map(|x| self.k * self.l * self.l * ((1.0 + (x / self.l).powi(2)).sqrt() - 1.0))
                .sum()
        }))
    }
}

fn converging(kind: LinearSolverKind, iters: usize, tol: f64) -> BackwardEulerParams {
    BackwardEulerParams {
        newton_tolerance: tol,
        ..params(kind, iters)
    }
}

#[test]
fn saturating_spring_potential_matches_its_forces() {
    let mut sys = Saturating::new(true);
    let x = vec![0.03, -0.002, 0.011];
    balloon_test_support::check_gradient(
        |x| sys.clone().potential_energy(0.0, x).unwrap().unwrap(),
        |x| {
            let mut f = vec![0.0; 3];
            sys.clone().forces(0.0, x, &mut f).unwrap();
            f.iter().map(|v| -v).collect()
        },
        &x,
        1e-7,
        1e-6,
    );
    let mut f = vec![0.0; 3];
    sys.forces(0.0, &x, &mut f).unwrap();
}

/// A solve that makes no headway stops after the stall window instead of spending every
/// allowed iteration (the caller's step halving is the remedy), and says how far it got.
#[test]
fn a_stalled_newton_solve_stops_after_the_stall_window() {
    let (dt, x0) = (0.01, vec![0.3, -0.2, 0.25]);
    for kind in [LinearSolverKind::Cholesky, LinearSolverKind::MatrixFreeCg] {
        // No potential: the residual line search only asks for a small decrease.
        let mut sys = Saturating::new(false);
        let mut be = BackwardEuler::new(converging(kind, 500, 1e-10)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        match be.step(&mut sys, 0.0, dt, &mut x, &mut v, None) {
            Err(IntegrateError::NotConverged {
                iterations,
                residual,
                ..
            }) => {
                assert!(
                    (NEWTON_STALL_WINDOW..3 * NEWTON_STALL_WINDOW).contains(&iterations),
                    "{kind}: stopped after {iterations} iterations"
                );
                assert!(residual > 1e-10, "{kind}: {residual}");
            }
            other => panic!("{kind}: expected NotConverged, got {other:?}"),
        }
    }
}

#[test]
fn line_search_converges_where_full_newton_steps_overshoot() {
    // Far out on the saturating spring (30 l) with a large step (k dt^2 / m = 1e3): the
    // full Newton step flies to the other side, farther out each time.
    let dt = 0.01;
    let x0 = vec![0.3, -0.2, 0.25];
    for kind in [LinearSolverKind::Cholesky, LinearSolverKind::MatrixFreeCg] {
        // With the energy line search: converged, every accepted iterate lowers E.
        let mut sys = Saturating::new(true);
        let mut be = BackwardEuler::new(converging(kind, 100, 1e-10)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
        assert!(
            info.converged && info.relative_residual <= 1e-10,
            "{info:?}"
        );
        assert!(
            info.line_search_cuts > 0,
            "{kind}: no cut was needed: {info:?}"
        );
        assert_eq!(info.energies.len(), info.newton_iterations + 1, "{info:?}");
        for w in info.energies.windows(2) {
            assert!(w[1] < w[0], "{kind}: energy rose: {:?}", info.energies);
        }
        // The result is the backward Euler solution: m (x - x0) / dt^2 = f(x).
        let mut f = vec![0.0; 3];
        sys.forces(0.0, &x, &mut f).unwrap();
        for c in 0..3 {
            let r = 1e-3 * (x[c] - x0[c]) / (dt * dt) - f[c];
            assert!(r.abs() < 1e-8 * sys.k * sys.l, "{kind}: residual {r}");
        }
        // Without a potential (full Newton steps) it does not converge at all.
        let mut sys = Saturating::new(false);
        let mut be = BackwardEuler::new(converging(kind, 100, 1e-10)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        let e = be
            .step(&mut sys, 0.0, dt, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(
                e,
                IntegrateError::NotConverged { .. } | IntegrateError::NonFinite { .. }
            ),
            "{kind}: {e}"
        );
        // Nor does the paper's mode: its residual after many full steps is large.
        let mut sys = Saturating::new(true);
        let mut be = BackwardEuler::new(params(kind, 8)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        match be.step(&mut sys, 0.0, dt, &mut x, &mut v, None) {
            Ok(info) => assert!(
                info.relative_residual.is_nan() || info.relative_residual >= 1e-2,
                "{kind}: {info:?}"
            ),
            Err(e) => assert!(matches!(e, IntegrateError::NonFinite { .. }), "{e}"),
        }
    }
}

#[test]
fn line_searched_newton_decreases_the_incremental_potential_on_the_chain() {
    // The nonlinear chain with gravity, mass damping and external forces, with the exact
    // incremental potential recomputed independently here.
    let nv = 8;
    let (dt, alpha) = (0.05, 3.0);
    let g = [0.0, -9.81, 0.0];
    let ext = Rng::new(12).vector(3 * nv);
    let mut sys = Chain::new(nv, true, 5);
    let mut be = BackwardEuler::new(BackwardEulerParams {
        mass_damping: alpha,
        gravity: g,
        ..converging(LinearSolverKind::Cholesky, 50, 1e-9)
    })
    .unwrap();
    let x0: Vec<f64> = Chain::positions(nv, 6).iter().map(|v| 1.5 * v).collect();
    let v0: Vec<f64> = Rng::new(7).vector(3 * nv).iter().map(|v| 3.0 * v).collect();
    let (mut x, mut v) = (x0.clone(), v0.clone());
    let info = be
        .step(&mut sys, 0.0, dt, &mut x, &mut v, Some(&ext))
        .unwrap();
    assert!(info.converged && info.relative_residual <= 1e-9, "{info:?}");
    // Non-increasing up to the round-off of E (the last iterates agree to ~1e-16).
    assert!(
        info.energies
            .windows(2)
            .all(|w| w[1] <= w[0] + 1e-14 * w[0].abs()),
        "{info:?}"
    );
    assert!(info.energies[1] < info.energies[0]);
    // E(x) of the module docs at the result is the minimum along random directions.
    let m_coef = 1.0 + dt * alpha;
    let e = |x: &[f64]| {
        let mut total = sys.energy(x);
        for i in 0..x.len() {
            let m = sys.masses[i];
            let d = x[i] - x0[i] - dt * v0[i] / m_coef;
            total += m_coef / (2.0 * dt * dt) * m * d * d;
            total -= (m * g[i % 3] + ext[i]) * x[i];
        }
        total
    };
    let e_min = e(&x);
    for seed in 0..4 {
        let d = Rng::new(100 + seed).vector(x.len());
        for h in [1e-4, -1e-4] {
            let xs: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + h * b).collect();
            assert!(e(&xs) > e_min, "not a minimum along direction {seed}");
        }
    }
    // The recorded energies differ from E(x) by a constant: their drop is E's drop.
    let e_first = e(&x0
        .iter()
        .zip(&v0)
        .map(|(x, v)| x + dt * v)
        .collect::<Vec<_>>());
    let drop = info.energies[0] - info.energies.last().unwrap();
    assert!(
        (drop - (e_first - e_min)).abs() < 1e-8 * drop.abs().max(1e-12),
        "{drop} vs {}",
        e_first - e_min
    );
}

#[test]
fn too_few_iterations_are_not_converged_and_bounds_are_checked() {
    let nv = 6;
    let mut sys = Chain::new(nv, true, 3);
    let mut be = BackwardEuler::new(converging(LinearSolverKind::Cholesky, 1, 1e-12)).unwrap();
    let (mut x, mut v) = (Chain::positions(nv, 4), Rng::new(5).vector(3 * nv));
    let e = be
        .step(&mut sys, 0.0, 0.05, &mut x, &mut v, None)
        .unwrap_err();
    match e {
        IntegrateError::NotConverged {
            iterations,
            residual,
            tolerance,
            load_factor: None,
        } => {
            assert_eq!(iterations, 1);
            assert!(residual > tolerance && residual.is_finite());
        }
        e => panic!("{e}"),
    }
    assert!(e.to_string().contains("did not converge"), "{e}");
    // Stiffness damping (no potential): the residual search still converges.
    let mut be = BackwardEuler::new(BackwardEulerParams {
        stiffness_damping: 0.01,
        ..converging(LinearSolverKind::Cholesky, 30, 1e-10)
    })
    .unwrap();
    let (mut x, mut v) = (Chain::positions(nv, 4), Rng::new(5).vector(3 * nv));
    let info = be.step(&mut sys, 0.0, 0.05, &mut x, &mut v, None).unwrap();
    assert!(info.energies.is_empty() && info.relative_residual <= 1e-10);
    for bad in [0, MAX_NEWTON_ITERATIONS + 1] {
        let e = BackwardEuler::new(converging(LinearSolverKind::Cholesky, bad, 1e-8)).unwrap_err();
        assert!(e.to_string().contains("newton_iterations"), "{e}");
    }
}

#[test]
fn the_relative_residual_does_not_depend_on_units() {
    // The same step in metres and in millimetres (forces scale with the length, masses
    // stay): the relative residuals agree.
    let run = |scale: f64| {
        let mut sys = Saturating::new(true);
        sys.l *= scale;
        let mut be =
            BackwardEuler::new(converging(LinearSolverKind::Cholesky, 100, 1e-10)).unwrap();
        let mut x: Vec<f64> = [0.03, -0.02, 0.025].iter().map(|v| v * scale).collect();
        let mut v = vec![0.0; 3];
        be.step(&mut sys, 0.0, 0.01, &mut x, &mut v, None)
            .unwrap()
            .relative_residuals
    };
    let (a, b) = (run(1.0), run(1e3));
    assert_eq!(a.len(), b.len());
    // Equal down to where round-off takes over.
    for (a, b) in a.iter().zip(&b).filter(|(a, _)| **a > 1e-10) {
        assert!((a - b).abs() <= 1e-6 * a, "{a} vs {b}");
    }
}

/// Three line-searched iterations accepted whatever their residual
/// (`accept_unconverged`) lower the incremental potential where three full Newton steps (the
/// paper's mode) raise it, far out on the saturating spring; without `accept_unconverged` the
/// same step is not converged.
#[test]
fn accepted_unconverged_steps_lower_the_potential_where_full_steps_raise_it() {
    let (dt, m) = (0.01, 1e-3);
    let x0 = vec![0.3, -0.2, 0.25];
    // The incremental potential of a step from rest at x0, computed here from its definition.
    let potential = |sys: &mut Saturating, x: &[f64]| {
        let inertia: f64 = x.iter().zip(&x0).map(|(x, x0)| (x - x0).powi(2)).sum();
        m / (2.0 * dt * dt) * inertia + sys.potential_energy(0.0, x).unwrap().unwrap()
    };
    for kind in [LinearSolverKind::Cholesky, LinearSolverKind::MatrixFreeCg] {
        let start = potential(&mut Saturating::new(true), &x0);
        let live = BackwardEulerParams {
            accept_unconverged: true,
            ..converging(kind, 3, 1e-10)
        };
        let mut sys = Saturating::new(true);
        let mut be = BackwardEuler::new(live).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
        assert!(
            !info.converged && info.newton_iterations == 3,
            "{kind}: {info:?}"
        );
        assert!(info.relative_residual > 1e-10, "{kind}: {info:?}");
        for w in info.energies.windows(2) {
            assert!(w[1] < w[0], "{kind}: energy rose: {:?}", info.energies);
        }
        let accepted = potential(&mut sys, &x);
        assert!(accepted < start, "{kind}: E {accepted} from {start}");
        // The velocity is the one of the positions.
        for c in 0..3 {
            assert!((v[c] - (x[c] - x0[c]) / dt).abs() < 1e-9 * v[c].abs().max(1.0));
        }

        // The paper's three full steps overshoot: the potential rises (or the state blows up).
        let mut sys = Saturating::new(true);
        let mut be = BackwardEuler::new(params(kind, 3)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        if be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).is_ok() {
            let full = potential(&mut sys, &x);
            assert!(
                full > start,
                "{kind}: full steps gave E {full} from {start}"
            );
        }

        // The same three iterations without accepting: not converged.
        let mut be = BackwardEuler::new(converging(kind, 3, 1e-10)).unwrap();
        let (mut x, mut v) = (x0.clone(), vec![0.0; 3]);
        let e = be
            .step(&mut Saturating::new(true), 0.0, dt, &mut x, &mut v, None)
            .unwrap_err();
        assert!(
            matches!(e, IntegrateError::NotConverged { .. }),
            "{kind}: {e}"
        );
    }
}

/// A linear spring `f = -k x` (one dof per particle) that refuses to be evaluated beyond a wall
/// at `x < wall`, as a shell refuses a surface turned inside out.
#[derive(Debug)]
struct Walled {
    masses: Vec<f64>,
    k: f64,
    wall: f64,
}

#[derive(Debug, thiserror::Error)]
#[error("beyond the wall")]
struct BeyondTheWall;

impl ForceSystem for Walled {
    fn num_dofs(&self) -> usize {
        3
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        if x.iter().any(|&x| x < self.wall) {
            return Err(SystemError::component("wall", BeyondTheWall));
        }
        f.iter_mut().zip(x).for_each(|(f, x)| *f = -self.k * x);
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        df.iter_mut()
            .zip(dx)
            .for_each(|(df, dx)| *df -= self.k * dx);
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        t.extend((0..3).map(|i| (i, i, self.k)));
        Ok(())
    }
    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        if x.iter().any(|&x| x < self.wall) {
            return Err(SystemError::component("wall", BeyondTheWall));
        }
        Ok(Some(0.5 * self.k * x.iter().map(|x| x * x).sum::<f64>()))
    }
}

/// Where the predictor `x^n + dt v^n` is beyond what the system can evaluate, Newton starts
/// from the step's start positions and reaches the backward Euler solution (closed form for a
/// linear spring), in every mode; a predictor the system accepts is used as before.
#[test]
fn a_predictor_the_system_refuses_starts_newton_at_rest() {
    let (dt, m, k) = (0.01, 1.0, 1e4);
    let x0 = vec![0.1; 3];
    for (v0, refused) in [(-100.0, true), (-10.0, false)] {
        // Backward Euler on the spring: v1 = (m v0 - dt k x0) / (m + dt^2 k).
        let v1 = (m * v0 - dt * k * x0[0]) / (m + dt * dt * k);
        // Predictor 0.1 - 1.0 = -0.9 (refused) or 0.0; the solution -0.45 or 0.0 is valid.
        assert!(x0[0] + dt * v1 > -0.5);
        for p in [
            converging(LinearSolverKind::Cholesky, 10, 1e-10),
            params(LinearSolverKind::Cholesky, 2),
            BackwardEulerParams {
                accept_unconverged: true,
                ..converging(LinearSolverKind::MatrixFreeCg, 3, 1e-10)
            },
        ] {
            let mut sys = Walled {
                masses: vec![m; 3],
                k,
                wall: -0.5,
            };
            let mut be = BackwardEuler::new(p).unwrap();
            let (mut x, mut v) = (x0.clone(), vec![v0; 3]);
            let info = be.step(&mut sys, 0.0, dt, &mut x, &mut v, None).unwrap();
            assert_eq!(info.started_at_rest, refused, "v0 {v0}: {info:?}");
            for c in 0..3 {
                assert!(
                    (v[c] - v1).abs() < 1e-8 * v1.abs().max(1.0),
                    "v0 {v0}: v {v:?}, want {v1}"
                );
                assert!((x[c] - (x0[c] + dt * v1)).abs() < 1e-10);
            }
        }
    }
}
