//! Tests of the static solve.

use super::*;
use crate::linear::LinearSolverKind;
use crate::newton::convergence::norm;
use crate::system::SystemError;

/// A free chain of nonlinear springs in 3D (no anchor: six rigid modes), pulled at its ends
/// by external forces `pull` (scaled by the continuation).
#[derive(Debug, Clone)]
struct Chain {
    masses: Vec<f64>,
    springs: Vec<(usize, usize, f64, f64)>,
    x: Vec<f64>,
    pull: Vec<f64>,
    /// The load factor last set (the system itself has no load of its own).
    factor: f64,
}

impl Chain {
    fn new(nv: usize) -> Self {
        let mut springs = Vec::new();
        for i in 0..nv - 1 {
            springs.push((i, i + 1, 50.0 + i as f64, 0.1));
            if i + 2 < nv {
                springs.push((i, i + 2, 20.0, 0.2));
            }
        }
        // Opposite pulls on the ends (no resultant), a force beyond the spring's linear range.
        let mut pull = vec![0.0; 3 * nv];
        pull[0] = -30.0;
        pull[1] = 4.0;
        pull[3 * (nv - 1)] = 30.0;
        pull[3 * (nv - 1) + 1] = -4.0;
        Self {
            masses: vec![0.01; 3 * nv],
            springs,
            x: vec![0.0; 3 * nv],
            pull,
            factor: 1.0,
        }
    }
    fn positions(nv: usize) -> Vec<f64> {
        (0..3 * nv)
            .map(|i| match i % 3 {
                0 => 0.1 * (i / 3) as f64,
                1 => 0.003 * ((i * 7) % 5) as f64,
                _ => 0.002 * ((i * 3) % 4) as f64,
            })
            .collect()
    }
    fn block(&self, i: usize, j: usize, k: f64, l0: f64) -> [[f64; 3]; 3] {
        let d: Vec<f64> = (0..3)
            .map(|c| self.x[3 * i + c] - self.x[3 * j + c])
            .collect();
        let l = norm(&d);
        let mut b = [[0.0; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                let nn = d[r] * d[c] / (l * l);
                let id = if r == c { 1.0 } else { 0.0 };
                b[r][c] = k * (nn + (id - nn) * (1.0 - l0 / l));
            }
        }
        b
    }
}

impl ForceSystem for Chain {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        f.fill(0.0);
        for &(i, j, k, l0) in &self.springs {
            let d: Vec<f64> = (0..3).map(|c| x[3 * i + c] - x[3 * j + c]).collect();
            let l = norm(&d);
            for c in 0..3 {
                let fi = -k * (l - l0) * d[c] / l;
                f[3 * i + c] += fi;
                f[3 * j + c] -= fi;
            }
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        let mut t = Vec::new();
        self.add_stiffness_triplets(&mut t).unwrap();
        for (r, c, v) in t {
            df[r] -= v * dx[c];
        }
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        for &(i, j, k, l0) in &self.springs {
            let b = self.block(i, j, k, l0);
            for r in 0..3 {
                for c in 0..3 {
                    t.push((3 * i + r, 3 * i + c, b[r][c]));
                    t.push((3 * j + r, 3 * j + c, b[r][c]));
                    t.push((3 * i + r, 3 * j + c, -b[r][c]));
                    t.push((3 * j + r, 3 * i + c, -b[r][c]));
                }
            }
        }
        Ok(())
    }
    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let mut e = 0.0;
        for &(i, j, k, l0) in &self.springs {
            let d: Vec<f64> = (0..3).map(|c| x[3 * i + c] - x[3 * j + c]).collect();
            e += 0.5 * k * (norm(&d) - l0).powi(2);
        }
        Ok(Some(e))
    }
}

impl LoadScaling for Chain {
    fn set_load_factor(&mut self, factor: f64) {
        self.factor = factor;
    }
}

fn check_equilibrium(sys: &mut Chain, x: &[f64]) {
    let mut f = vec![0.0; x.len()];
    sys.forces(0.0, x, &mut f).unwrap();
    let r: Vec<f64> = f.iter().zip(&sys.pull).map(|(f, p)| f + p).collect();
    assert!(
        norm(&r) < 1e-5 * norm(&sys.pull),
        "residual force {}",
        norm(&r)
    );
}

#[test]
fn free_chain_reaches_equilibrium_with_every_solver_and_decreasing_energy() {
    let nv = 8;
    for kind in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
    ] {
        let mut params = StaticParams::default();
        params.solver.linear.kind = kind;
        params.solver.linear.relative_tolerance = 1e-10;
        params.tolerance = 1e-9;
        let mut solver = StaticSolver::new(params).unwrap();
        let mut sys = Chain::new(nv);
        let mut x = Chain::positions(nv);
        let pull = sys.pull.clone();
        let info = solver.solve(&mut sys, 0.0, &mut x, Some(&pull)).unwrap();
        assert!(
            info.converged && info.relative_residual <= 1e-9,
            "{kind}: {info:?}"
        );
        assert!(info.energies.len() >= 2);
        for w in info.energies.windows(2) {
            assert!(
                w[1] <= w[0] + 1e-13 * w[0].abs(),
                "{kind}: {:?}",
                info.energies
            );
        }
        check_equilibrium(&mut sys, &x);
        // A rigid body: the chain is stretched (the pulls exceed the linear range).
        let span = x[3 * (nv - 1)] - x[0];
        assert!(span > 0.75, "{kind}: span {span}");
    }
}

/// Any cloneable system made lazy: `residual_forces` evaluates a copy, leaving the
/// linearisation at the earlier point until `refresh_stiffness`; a stale stiffness query
/// panics.
struct Lazy<S> {
    inner: S,
    pending: Option<(f64, Vec<f64>)>,
    trials: usize,
}

impl<S: ForceSystem + Clone> ForceSystem for Lazy<S> {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }
    fn masses(&self) -> &[f64] {
        self.inner.masses()
    }
    fn forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.pending = None;
        self.inner.forces(t, x, f)
    }
    fn residual_forces(&mut self, t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.inner.clone().forces(t, x, f)?;
        self.pending = Some((t, x.to_vec()));
        self.trials += 1;
        Ok(())
    }
    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        if let Some((t, x)) = self.pending.take() {
            let mut f = vec![0.0; x.len()];
            self.inner.forces(t, &x, &mut f)?;
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        assert!(self.pending.is_none(), "stale differential");
        self.inner.add_force_differential(dx, df);
    }
    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        assert!(self.pending.is_none(), "stale stiffness");
        self.inner.add_stiffness_triplets(t)
    }
    fn add_stiffness_diagonal(&self, d: &mut [f64]) -> Result<(), SystemError> {
        assert!(self.pending.is_none(), "stale diagonal");
        self.inner.add_stiffness_diagonal(d)
    }
    fn low_rank_terms(&self) -> &[crate::LowRankTerm] {
        assert!(self.pending.is_none(), "stale low-rank terms");
        self.inner.low_rank_terms()
    }
    fn potential_energy(&mut self, t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        self.inner.potential_energy(t, x)
    }
}

#[test]
fn trials_may_skip_the_stiffness_and_the_solve_is_unchanged() {
    let nv = 8;
    for kind in [
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
    ] {
        let mut params = StaticParams::default();
        params.solver.linear.kind = kind;
        params.solver.linear.relative_tolerance = 1e-10;
        params.tolerance = 1e-9;
        let pull = Chain::new(nv).pull.clone();
        let mut eager = Chain::new(nv);
        let mut xe = Chain::positions(nv);
        let ie = StaticSolver::new(params)
            .unwrap()
            .solve(&mut eager, 0.0, &mut xe, Some(&pull))
            .unwrap();
        let mut lazy = Lazy {
            inner: Chain::new(nv),
            pending: None,
            trials: 0,
        };
        let mut xl = Chain::positions(nv);
        let il = StaticSolver::new(params)
            .unwrap()
            .solve(&mut lazy, 0.0, &mut xl, Some(&pull))
            .unwrap();
        assert!(
            il.converged && lazy.trials >= il.iterations,
            "{kind}: {il:?}"
        );
        assert_eq!(il.iterations, ie.iterations, "{kind}");
        assert!(
            xl.iter().zip(&xe).all(|(a, b)| a.to_bits() == b.to_bits()),
            "{kind}: the lazy solve differs"
        );
    }
}

#[test]
fn continuation_reaches_the_full_load_when_the_direct_solve_cannot() {
    let nv = 8;
    // Too few iterations per stage for the full load from the rest shape.
    let params = StaticParams {
        max_iterations: 4,
        tolerance: 1e-8,
        continuation_tolerance: 1e-2,
        ..Default::default()
    };
    let mut sys = Chain::new(nv);
    for p in sys.pull.iter_mut() {
        *p *= 3.0;
    }
    let mut x = Chain::positions(nv);
    let pull = sys.pull.clone();
    let e = StaticSolver::new(params)
        .unwrap()
        .solve(&mut sys, 0.0, &mut x.clone(), Some(&pull))
        .unwrap_err();
    assert!(matches!(e, StaticError::NotConverged { .. }), "{e}");
    let info = StaticSolver::new(params)
        .unwrap()
        .solve_with_continuation(&mut sys, 0.0, &mut x, Some(&pull))
        .unwrap();
    assert!(info.load_steps > 1, "{info:?}");
    assert!(info.relative_residual <= 1e-8);
    assert_eq!(sys.factor, 1.0);
    check_equilibrium(&mut sys, &x);
}

#[test]
fn bad_input_and_missing_potential_are_typed_errors() {
    struct NoPotential([f64; 3]);
    impl ForceSystem for NoPotential {
        fn num_dofs(&self) -> usize {
            3
        }
        fn masses(&self) -> &[f64] {
            &self.0
        }
        fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            f.iter_mut().zip(x).for_each(|(f, x)| *f = 1.0 - x);
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            df.iter_mut().zip(dx).for_each(|(df, dx)| *df -= dx);
        }
    }
    let mut solver = StaticSolver::default();
    let e = solver
        .solve(&mut NoPotential([1.0; 3]), 0.0, &mut [0.0; 3], None)
        .unwrap_err();
    assert_eq!(e, StaticError::NoPotential);
    let e = solver
        .solve(&mut NoPotential([1.0; 3]), 0.0, &mut [0.0; 2], None)
        .unwrap_err();
    assert!(e.to_string().contains("`x`"), "{e}");
    let e = solver
        .solve(
            &mut NoPotential([1.0; 3]),
            0.0,
            &mut [0.0, f64::NAN, 0.0],
            None,
        )
        .unwrap_err();
    assert!(
        matches!(
            e,
            StaticError::NonFiniteInput {
                what: "x",
                dof: 1,
                ..
            }
        ),
        "{e}"
    );
    // Parameters are checked when set, and a refused set changes nothing.
    let bad = StaticParams {
        tolerance: 0.0,
        ..*solver.params()
    };
    for e in [
        solver.set_params(bad).unwrap_err(),
        StaticSolver::new(bad).unwrap_err(),
    ] {
        assert!(
            matches!(
                e,
                StaticError::InvalidParameter {
                    name: "tolerance",
                    ..
                }
            ),
            "{e}"
        );
    }
    assert_eq!(solver.params().tolerance, StaticParams::default().tolerance);
}

/// A particle on the potential `W(x) = -s ln(1 + |x|^2)` (`s` the load factor): convex for
/// `|x| > 1` but unbounded below, so there is no equilibrium to find; Newton runs outward for
/// ever with a relative residual of 1.
#[derive(Debug, Clone)]
struct Unbounded {
    m: [f64; 3],
    factor: f64,
    x: [f64; 3],
}

impl ForceSystem for Unbounded {
    fn num_dofs(&self) -> usize {
        3
    }
    fn masses(&self) -> &[f64] {
        &self.m
    }
    fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        let q = 1.0 + norm(x).powi(2);
        for i in 0..3 {
            f[i] = 2.0 * self.factor * x[i] / q;
        }
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        // f = 2 s x / q: df = 2 s (dx / q - 2 x (x . dx) / q^2).
        let q = 1.0 + norm(&self.x).powi(2);
        let xdx: f64 = self.x.iter().zip(dx).map(|(a, b)| a * b).sum();
        for i in 0..3 {
            df[i] += 2.0 * self.factor * (dx[i] / q - 2.0 * self.x[i] * xdx / (q * q));
        }
    }
    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        Ok(Some(-self.factor * (1.0 + norm(x).powi(2)).ln()))
    }
}

impl LoadScaling for Unbounded {
    fn set_load_factor(&mut self, factor: f64) {
        self.factor = factor;
    }
}

#[test]
fn a_solve_without_equilibrium_stops_after_its_stalled_stages_with_the_evidence() {
    let mut params = StaticParams::default();
    params.solver.linear.kind = LinearSolverKind::MatrixFreeCg;
    let start = [2.0, 1.0, 0.5];
    let mut sys = Unbounded {
        m: [1.0; 3],
        factor: 1.0,
        x: [0.0; 3],
    };
    let mut solver = StaticSolver::new(params).unwrap();
    let mut x = start.to_vec();
    let e = solver
        .solve_with_continuation(&mut sys, 0.0, &mut x, None)
        .unwrap_err();
    let StaticError::NoEquilibrium(stall) = &e else {
        panic!("expected NoEquilibrium, got {e}");
    };
    let crate::newton::Stall {
        iterations,
        residual,
        load_factor,
        stalled_stages,
        vertex,
        share,
        smallest_eigenvalue,
        ..
    } = **stall;
    // The full load and three increments, one window of `stall_window` iterations each (the
    // residual never halves), instead of 13 stages of 200 iterations.
    assert_eq!(stalled_stages, params.max_stalled_stages);
    assert!(
        iterations <= (1 + params.max_stalled_stages) * params.stall_window,
        "{iterations}"
    );
    assert!((residual - 1.0).abs() < 1e-6, "{residual}");
    assert_eq!((load_factor, vertex, share), (0.0, 0, 1.0));
    assert_eq!(smallest_eigenvalue, None);
    // Left at the last converged point (none: the start) with its load factor.
    assert_eq!(x, start);
    assert_eq!(sys.factor, 0.0);
    assert!(solver.stalled_iterate().is_some_and(|s| norm(s) > 1e3));
    let message = e.to_string();
    assert!(
        message.contains("no smooth equilibrium found") && message.contains("stall_window"),
        "{message}"
    );

    // Without the stall test the same solve runs every stage to its iteration limit.
    let params = StaticParams {
        stall_window: 0,
        max_iterations: 30,
        max_load_halvings: 2,
        ..params
    };
    let mut x = start.to_vec();
    let e = StaticSolver::new(params)
        .unwrap()
        .solve_with_continuation(&mut sys, 0.0, &mut x, None)
        .unwrap_err();
    assert!(
        matches!(e, StaticError::NotConverged { iterations: 90, .. }),
        "{e}"
    );
}
