//! The stability of a static equilibrium: the smallest eigenvalues of its stiffness, by
//! shift-and-invert Lanczos on the factorised Newton matrix ([`StaticSolver::stability`]).
//!
//! At an equilibrium `x*` of the static energy `E` the equilibrium is stable when the Hessian
//! `K = d^2E/dx^2` (the stiffness, low-rank gas terms included) is positive definite on the
//! motions that change the shape. The generalised eigenproblem `K y = lambda M y` with the
//! lumped mass matrix `M` gives `lambda` in `1/s^2`: a positive `lambda` is the squared angular
//! frequency of a small oscillation about `x*`, a negative one the squared growth rate of the
//! mode `y` that leaves it. Along a continuation (a volume-controlled balloon, a load raised
//! step by step) the smallest `lambda` crossing zero marks a limit point or a bifurcation (for
//! a sphere, the aspherical inflation of Alexander 1971 and Haughton and Ogden 1978), where the
//! branch followed so far stops being the one a real balloon takes.
//!
//! A free body has six rigid motions with `lambda = 0` (at an equilibrium a rotation costs no
//! energy to second order); [`StabilityParams::rigid_modes`] removes them (they are kept
//! `M`-orthogonal to every Lanczos vector), so the reported eigenvalue is that of the shape.
//!
//! The method: `A = K + sigma M` is factorised once with the solver's own linear solver, for
//! the smallest `sigma = s mu_ref` (`s` from [`StabilityParams::shift`], tenfold while the
//! factorisation meets a non-positive pivot; `mu_ref = |diag K| / |m|`), and Lanczos runs on
//! `T = A^-1 M`, self-adjoint in the `M` inner product, with full reorthogonalisation. The
//! largest eigenvalues `theta` of `T` are `1 / (lambda + sigma)` for the smallest `lambda`,
//! so they converge first. The Ritz pair is checked against the operator itself: the reported
//! [`Stability::residual`] is `|K y - lambda M y|_(M^-1) / (mu_ref |y|_M)`, computed with the
//! system's force differentials, not with the factor.

use balloon_linalg::StiffnessOperator;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

use super::{StaticError, StaticSolver};
use crate::newton::check_parameter;
use crate::newton::convergence::first_non_finite;
use crate::newton::rigid::{m_dot, m_orthogonalize, rigid_basis};
use crate::newton::{NewtonError, SystemStiffness};
use crate::system::ForceSystem;

/// Most tenfold raises of the shift `sigma` while `K + sigma M` is not positive definite.
const MAX_SHIFT_RAISES: usize = 12;

/// How [`StaticSolver::stability`] computes the smallest eigenvalue.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StabilityParams {
    /// Remove the six rigid motions (a free body; `false` when vertices are pinned).
    pub rigid_modes: bool,
    /// Most Lanczos steps (linear solves on the one factor), at least 2.
    pub max_steps: usize,
    /// Relative accuracy of the smallest eigenvalue: the Lanczos estimate of the Ritz residual
    /// below `tolerance` times `|theta|` stops the iteration.
    pub tolerance: f64,
    /// The first shift `sigma` relative to `mu_ref`, > 0.
    pub shift: f64,
}

impl Default for StabilityParams {
    fn default() -> Self {
        Self {
            rigid_modes: true,
            max_steps: 60,
            tolerance: 1e-8,
            shift: 1e-6,
        }
    }
}

/// The smallest eigenvalue of a static equilibrium's stiffness (module docs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Stability {
    /// The smallest eigenvalue `lambda` of `K y = lambda M y`, 1/s^2 (rigid motions removed
    /// when asked); negative when the equilibrium is unstable.
    pub smallest_eigenvalue: f64,
    /// `lambda / mu_ref`: the eigenvalue relative to the stiffness scale
    /// `mu_ref = |diag K| / |m|` (dimensionless; rounding in `K` is about `1e-12` of it).
    pub relative_eigenvalue: f64,
    /// The second smallest eigenvalue, 1/s^2, when Lanczos resolved it (`None` otherwise).
    pub second_eigenvalue: Option<f64>,
    /// `mu_ref`, 1/s^2.
    pub stiffness_scale: f64,
    /// The shift `sigma` the factorisation needed, 1/s^2.
    pub shift: f64,
    /// Relative residual of the eigenpair checked on the operator (module docs).
    pub residual: f64,
    /// Lanczos steps (linear solves).
    pub steps: usize,
    /// Factorisations (one, plus one per raise of the shift).
    pub factorizations: usize,
    /// The mode `y` of the smallest eigenvalue, one entry per degree of freedom, normalised to
    /// `y^T M y = 1`.
    pub mode: Vec<f64>,
}

impl StabilityParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`NewtonError::InvalidParameter`] naming `max_steps`, `tolerance` or `shift`.
    pub fn validate(&self) -> Result<(), StaticError> {
        check_parameter(
            "max_steps",
            self.max_steps as f64,
            self.max_steps >= 2,
            ">= 2",
        )?;
        check_parameter(
            "tolerance",
            self.tolerance,
            self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance < 1.0,
            "in (0, 1)",
        )?;
        check_parameter(
            "shift",
            self.shift,
            self.shift.is_finite() && self.shift > 0.0 && self.shift <= 1.0,
            "in (0, 1]",
        )
    }
}

/// A start vector with a component along every mode (not a multiple of a smooth field).
fn start_vector(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 + 1.0;
            (t * 0.618_033_988_749_895).fract() - 0.5 + 0.1 * (t * 1.324_717_957_244_746).sin()
        })
        .collect()
}

impl StaticSolver {
    /// The smallest eigenvalue of the stiffness of `system` at `x` (an equilibrium, typically
    /// the result of [`StaticSolver::solve`]) relative to its mass matrix, and its mode (module
    /// docs). `fixed`: one flag per degree of freedom held in place (empty: none), left out of
    /// the eigenproblem (a pinned coordinate has no stiffness and would report a zero
    /// eigenvalue). Uses the solver's linear solver and sparse pattern; the next solve
    /// refactorises (its shift differs).
    ///
    /// ```
    /// use balloon_integrate::statics::{StabilityParams, StaticSolver};
    /// use balloon_integrate::{ForceSystem, SystemError};
    ///
    /// /// Two unit masses on a line held by springs of 4 and 9 N/m to the origin.
    /// struct Springs;
    /// impl ForceSystem for Springs {
    ///     fn num_dofs(&self) -> usize { 2 }
    ///     fn masses(&self) -> &[f64] { &[1.0, 1.0] }
    ///     fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
    ///         f[0] = -4.0 * x[0];
    ///         f[1] = -9.0 * x[1];
    ///         Ok(())
    ///     }
    ///     fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
    ///         df[0] -= 4.0 * dx[0];
    ///         df[1] -= 9.0 * dx[1];
    ///     }
    ///     fn add_stiffness_triplets(
    ///         &self,
    ///         t: &mut Vec<(usize, usize, f64)>,
    ///     ) -> Result<(), SystemError> {
    ///         t.extend([(0, 0, 4.0), (1, 1, 9.0)]);
    ///         Ok(())
    ///     }
    /// }
    ///
    /// let mut solver = StaticSolver::default();
    /// let params = StabilityParams { rigid_modes: false, ..StabilityParams::default() };
    /// let s = solver.stability(&mut Springs, 0.0, &[0.0, 0.0], &[], &params)?;
    /// assert!((s.smallest_eigenvalue - 4.0).abs() < 1e-8);
    /// assert!((s.second_eigenvalue.unwrap() - 9.0).abs() < 1e-8);
    /// # Ok::<(), balloon_integrate::statics::StaticError>(())
    /// ```
    ///
    /// # Errors
    /// [`NewtonError::InvalidParameter`] for bad `params` or a `fixed` of the wrong length
    /// (`fixed`), the input errors of
    /// [`StaticSolver::solve`], [`NewtonError::System`] when the system cannot be evaluated at
    /// `x`, and [`NewtonError::Linear`] when `K + sigma M` stays indefinite after
    /// `MAX_SHIFT_RAISES` (12) tenfold raises of `sigma` (or the solve fails otherwise).
    pub fn stability<S: ForceSystem>(
        &mut self,
        system: &mut S,
        time: f64,
        x: &[f64],
        fixed: &[bool],
        params: &StabilityParams,
    ) -> Result<Stability, StaticError> {
        params.validate()?;
        let n = system.num_dofs();
        Self::check_inputs(n, x, None)?;
        check_parameter(
            "fixed",
            fixed.len() as f64,
            fixed.is_empty() || fixed.len() == n,
            "empty or one flag per degree of freedom",
        )?;
        // Vectors live on the free coordinates only.
        let free = |v: &mut [f64]| {
            for (v, &f) in v.iter_mut().zip(fixed) {
                if f {
                    *v = 0.0;
                }
            }
        };
        system
            .set_tangent(self.params().tangent)
            .map_err(|source| NewtonError::System {
                iteration: 0,
                source,
            })?;
        self.core.resize(n);
        self.core.objective.time = time;
        // The stiffness at x (the forces first: the system linearises at its last evaluation).
        self.core.evaluate(system, x, 0, true, false)?;
        let mut times = self.core.times;
        self.core.matrix.linearize(system, 0, &mut times)?;
        let masses = system.masses().to_vec();
        let scale =
            super::solver::stiffness_scale(system, super::solver::stiffness_norm(system, x));
        let rigid = if params.rigid_modes && n.is_multiple_of(3) {
            rigid_basis(&masses, x)
        } else {
            Vec::new()
        };
        let mut sigma = params.shift * scale;
        let factorizations_before = self.core.matrix.solver.factorizations();
        self.core.matrix.solver.set_relative_tolerance(1e-12);
        self.core.matrix.solver.invalidate_factorization();
        let mut q = start_vector(n);
        free(&mut q);
        m_orthogonalize(&masses, &rigid, &mut q);
        let norm = m_dot(&masses, &q, &q).sqrt();
        q.iter_mut().for_each(|v| *v /= norm);
        let mut rhs = vec![0.0; n];
        let mut w = vec![0.0; n];
        // The first solve finds the shift that makes A positive definite.
        let mut raises = 0;
        loop {
            rhs.iter_mut()
                .zip(&masses)
                .zip(&q)
                .for_each(|((r, m), q)| *r = m * q);
            match self
                .core
                .matrix
                .solve(&*system, sigma, 1.0, &rhs, &mut w, false, &mut times)
            {
                Ok(_) => break,
                Err(e) if e.is_indefinite() && raises < MAX_SHIFT_RAISES => {
                    sigma *= 10.0;
                    raises += 1;
                    self.core.matrix.solver.invalidate_factorization();
                }
                Err(source) => {
                    return Err(NewtonError::Linear {
                        iteration: 0,
                        source,
                    });
                }
            }
        }
        // Lanczos on T = A^-1 M in the M inner product (w = T q_0 already).
        let mut basis: Vec<Vec<f64>> = vec![q];
        let (mut alpha, mut beta) = (Vec::<f64>::new(), Vec::<f64>::new());
        let mut ritz = None;
        for j in 0..params.max_steps.min(n.saturating_sub(rigid.len()).max(1)) {
            if j > 0 {
                let qj = &basis[j];
                rhs.iter_mut()
                    .zip(&masses)
                    .zip(qj)
                    .for_each(|((r, m), q)| *r = m * q);
                self.core
                    .matrix
                    .solve(&*system, sigma, 1.0, &rhs, &mut w, true, &mut times)
                    .map_err(|source| NewtonError::Linear {
                        iteration: j,
                        source,
                    })?;
            }
            if let Some(dof) = first_non_finite(&w) {
                return Err(NewtonError::NonFinite {
                    quantity: "eigenvector",
                    dof,
                    vertex: dof / 3,
                    iteration: j,
                });
            }
            free(&mut w);
            m_orthogonalize(&masses, &rigid, &mut w);
            let a = m_dot(&masses, &basis[j], &w);
            alpha.push(a);
            // Full reorthogonalisation against every Lanczos vector.
            m_orthogonalize(&masses, &basis, &mut w);
            let b = m_dot(&masses, &w, &w).sqrt();
            let k = alpha.len();
            let t = DMatrix::from_fn(k, k, |r, c| {
                if r == c {
                    alpha[r]
                } else if r + 1 == c {
                    beta[r]
                } else if c + 1 == r {
                    beta[c]
                } else {
                    0.0
                }
            });
            let eig = SymmetricEigen::new(t);
            let mut order: Vec<usize> = (0..k).collect();
            order.sort_by(|&p, &q| eig.eigenvalues[q].total_cmp(&eig.eigenvalues[p]));
            let top = order[0];
            let theta = eig.eigenvalues[top];
            // Lanczos estimate of the Ritz residual: b |s_k|.
            let estimate = b * eig.eigenvectors[(k - 1, top)].abs();
            let second = order.get(1).map(|&i| {
                (
                    eig.eigenvalues[i],
                    b * eig.eigenvectors[(k - 1, i)].abs() <= 1e-6 * eig.eigenvalues[i].abs(),
                )
            });
            let s: Vec<f64> = (0..k).map(|r| eig.eigenvectors[(r, top)]).collect();
            ritz = Some((theta, s, second));
            let done = estimate <= params.tolerance * theta.abs() || b <= 1e-300;
            if done || j + 1 == params.max_steps {
                break;
            }
            beta.push(b);
            w.iter_mut().for_each(|v| *v /= b);
            basis.push(std::mem::replace(&mut w, vec![0.0; n]));
        }
        let (theta, s, second) = ritz.expect("at least one Lanczos step");
        let steps = alpha.len();
        let mut mode = vec![0.0; n];
        for (c, q) in s.iter().zip(&basis) {
            mode.iter_mut().zip(q).for_each(|(y, q)| *y += c * q);
        }
        let norm = m_dot(&masses, &mode, &mode).sqrt();
        mode.iter_mut().for_each(|y| *y /= norm);
        let lambda = 1.0 / theta - sigma;
        // The residual on the operator itself: |K y - lambda M y|_(M^-1) / (mu_ref |y|_M).
        let mut ky = vec![0.0; n];
        SystemStiffness(&*system).apply(&mode, &mut ky);
        free(&mut ky);
        let r2: f64 = ky
            .iter()
            .zip(&mode)
            .zip(&masses)
            .map(|((k, y), m)| {
                let r = k - lambda * m * y;
                r * r / m
            })
            .sum();
        self.core.times = times;
        // The next solve refactorises at its own shift.
        self.core.matrix.solver.invalidate_factorization();
        self.core.matrix.factored_mass_coefficient = None;
        self.core
            .matrix
            .solver
            .set_relative_tolerance(self.params().solver.linear.relative_tolerance);
        Ok(Stability {
            smallest_eigenvalue: lambda,
            relative_eigenvalue: lambda / scale,
            second_eigenvalue: second.and_then(|(t, ok)| ok.then(|| 1.0 / t - sigma)),
            stiffness_scale: scale,
            shift: sigma,
            residual: r2.sqrt() / scale,
            steps,
            factorizations: (self.core.matrix.solver.factorizations() - factorizations_before)
                as usize,
            mode,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::SystemError;
    use nalgebra::DVector;

    /// Linear forces `f = -K x` of a dense symmetric `K` (N/m) on point masses.
    struct Linear {
        k: DMatrix<f64>,
        masses: Vec<f64>,
    }

    impl ForceSystem for Linear {
        fn num_dofs(&self) -> usize {
            self.masses.len()
        }
        fn masses(&self) -> &[f64] {
            &self.masses
        }
        fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
            let kx = &self.k * DVector::from_column_slice(x);
            f.iter_mut().zip(kx.iter()).for_each(|(f, k)| *f = -k);
            Ok(())
        }
        fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
            let kx = &self.k * DVector::from_column_slice(dx);
            df.iter_mut().zip(kx.iter()).for_each(|(f, k)| *f -= k);
        }
        fn add_stiffness_triplets(
            &self,
            t: &mut Vec<(usize, usize, f64)>,
        ) -> Result<(), SystemError> {
            for r in 0..self.k.nrows() {
                for c in 0..self.k.ncols() {
                    t.push((r, c, self.k[(r, c)]));
                }
            }
            Ok(())
        }
        fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
            diagonal
                .iter_mut()
                .enumerate()
                .for_each(|(i, d)| *d += self.k[(i, i)]);
            Ok(())
        }
        fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
            let x = DVector::from_column_slice(x);
            Ok(Some(0.5 * x.dot(&(&self.k * &x))))
        }
    }

    /// A symmetric matrix with a spread of eigenvalues, some negative, from a fixed seed.
    fn matrix(n: usize, shift: f64) -> DMatrix<f64> {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = DMatrix::from_fn(n, n, |_, _| next());
        let d = DMatrix::from_diagonal(&DVector::from_fn(n, |i, _| (i as f64 + 1.0).powi(2)));
        &a.transpose() * d * &a * 10.0 + DMatrix::identity(n, n) * shift
    }

    /// The generalised eigenvalues of `(K, diag m)`, ascending, by a dense solve.
    fn dense_eigenvalues(k: &DMatrix<f64>, m: &[f64]) -> Vec<f64> {
        let n = m.len();
        let s = DMatrix::from_fn(n, n, |r, c| k[(r, c)] / (m[r] * m[c]).sqrt());
        let mut e: Vec<f64> = SymmetricEigen::new(s).eigenvalues.iter().copied().collect();
        e.sort_by(f64::total_cmp);
        e
    }

    fn masses(n: usize) -> Vec<f64> {
        (0..n).map(|i| 0.5 + (i % 5) as f64 * 0.3).collect()
    }

    /// The smallest and second eigenvalues match a dense generalised eigen-solve, for a
    /// positive definite and for an indefinite stiffness (which needs a raised shift), and the
    /// mode satisfies `K y = lambda M y`.
    #[test]
    fn the_smallest_eigenvalues_match_a_dense_solve() {
        let n = 24;
        let m = masses(n);
        for shift in [0.5, -3.0] {
            let k = matrix(n, shift);
            let expected = dense_eigenvalues(&k, &m);
            let mut system = Linear {
                k: k.clone(),
                masses: m.clone(),
            };
            let mut solver = StaticSolver::default();
            let params = StabilityParams {
                rigid_modes: false,
                ..StabilityParams::default()
            };
            let s = solver
                .stability(&mut system, 0.0, &vec![0.0; n], &[], &params)
                .unwrap();
            let scale = expected.iter().fold(0.0f64, |a, e| a.max(e.abs()));
            assert!(
                (s.smallest_eigenvalue - expected[0]).abs() <= 1e-8 * scale,
                "shift {shift}: {} against {}",
                s.smallest_eigenvalue,
                expected[0]
            );
            if let Some(second) = s.second_eigenvalue {
                assert!(
                    (second - expected[1]).abs() <= 1e-6 * scale,
                    "{second} {expected:?}"
                );
            }
            assert!(s.residual <= 1e-6, "{s:?}");
            assert_eq!(
                s.smallest_eigenvalue < 0.0,
                shift < 0.0 && expected[0] < 0.0
            );
            // K y = lambda M y, checked with the dense matrix.
            let y = DVector::from_column_slice(&s.mode);
            let ky = &k * &y;
            for i in 0..n {
                assert!(
                    (ky[i] - s.smallest_eigenvalue * m[i] * y[i]).abs() <= 1e-6 * scale,
                    "dof {i}"
                );
            }
        }
    }

    /// Four springs of a square frame with one diagonal in the plane z = 0, plus springs to
    /// lift it out of the plane: a free body whose rigid motions are removed leaves the
    /// smallest eigenvalue of the shape, equal to the dense solve's smallest non-zero one.
    #[test]
    fn rigid_motions_are_removed_from_a_free_body() {
        // Six points of a regular octahedron joined by its twelve edges: stable, free.
        let pts = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let n = 18;
        let mut k = DMatrix::zeros(n, n);
        for a in 0..6 {
            for b in (a + 1)..6 {
                if a / 2 == b / 2 {
                    continue; // opposite vertices are not joined
                }
                let d = nalgebra::Vector3::from(pts[b]) - nalgebra::Vector3::from(pts[a]);
                let u = d.normalize();
                let kk = u * u.transpose() * 7.0;
                for r in 0..3 {
                    for c in 0..3 {
                        k[(3 * a + r, 3 * a + c)] += kk[(r, c)];
                        k[(3 * b + r, 3 * b + c)] += kk[(r, c)];
                        k[(3 * a + r, 3 * b + c)] -= kk[(r, c)];
                        k[(3 * b + r, 3 * a + c)] -= kk[(r, c)];
                    }
                }
            }
        }
        let m = vec![2.0; n];
        let expected = dense_eigenvalues(&k, &m);
        // Six (numerically) zero eigenvalues, then the shape's.
        assert!(
            expected[5].abs() < 1e-10 && expected[6] > 1e-3,
            "{expected:?}"
        );
        let x: Vec<f64> = pts.iter().flatten().copied().collect();
        let mut system = Linear { k, masses: m };
        let mut solver = StaticSolver::default();
        let s = solver
            .stability(&mut system, 0.0, &x, &[], &StabilityParams::default())
            .unwrap();
        assert!(
            (s.smallest_eigenvalue - expected[6]).abs() <= 1e-8 * expected[17],
            "{} against {:?}",
            s.smallest_eigenvalue,
            &expected[..8]
        );
        // Without the removal the rigid motions come first.
        let s = solver
            .stability(
                &mut system,
                0.0,
                &x,
                &[],
                &StabilityParams {
                    rigid_modes: false,
                    ..StabilityParams::default()
                },
            )
            .unwrap();
        assert!(s.smallest_eigenvalue.abs() <= 1e-6 * expected[17], "{s:?}");
    }

    /// Held coordinates (zero rows and columns in `K`, as the pins decorator leaves them) would
    /// report a zero eigenvalue; given as `fixed` they are left out, and the eigenvalue is the
    /// free block's.
    #[test]
    fn fixed_coordinates_are_left_out() {
        let n = 12;
        let m = masses(n);
        let mut k = matrix(n, 0.5);
        let fixed: Vec<bool> = (0..n).map(|i| i % 4 == 0).collect();
        for i in (0..n).filter(|&i| fixed[i]) {
            for j in 0..n {
                k[(i, j)] = 0.0;
                k[(j, i)] = 0.0;
            }
        }
        let free: Vec<usize> = (0..n).filter(|&i| !fixed[i]).collect();
        let block = DMatrix::from_fn(free.len(), free.len(), |r, c| k[(free[r], free[c])]);
        let expected = dense_eigenvalues(&block, &free.iter().map(|&i| m[i]).collect::<Vec<_>>());
        let mut system = Linear { k, masses: m };
        let params = StabilityParams {
            rigid_modes: false,
            ..StabilityParams::default()
        };
        let mut solver = StaticSolver::default();
        let s = solver
            .stability(&mut system, 0.0, &vec![0.0; n], &fixed, &params)
            .unwrap();
        assert!(
            (s.smallest_eigenvalue - expected[0]).abs() <= 1e-8 * expected[expected.len() - 1],
            "{} against {expected:?}",
            s.smallest_eigenvalue
        );
        assert!(s.mode.iter().zip(&fixed).all(|(y, f)| !f || *y == 0.0));
        // Without them the held coordinates come first, at zero.
        let s = solver
            .stability(&mut system, 0.0, &vec![0.0; n], &[], &params)
            .unwrap();
        assert!(s.smallest_eigenvalue.abs() < 1e-6, "{s:?}");
        // A wrong length is refused by name.
        match solver.stability(&mut system, 0.0, &vec![0.0; n], &[true], &params) {
            Err(NewtonError::InvalidParameter { name: "fixed", .. }) => {}
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn bad_parameters_are_refused_by_name() {
        for (params, name) in [
            (
                StabilityParams {
                    max_steps: 1,
                    ..StabilityParams::default()
                },
                "max_steps",
            ),
            (
                StabilityParams {
                    tolerance: 0.0,
                    ..StabilityParams::default()
                },
                "tolerance",
            ),
            (
                StabilityParams {
                    shift: f64::NAN,
                    ..StabilityParams::default()
                },
                "shift",
            ),
        ] {
            match params.validate() {
                Err(NewtonError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: {other:?}"),
            }
        }
    }
}
