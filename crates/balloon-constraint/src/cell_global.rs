//! Global (all cells at once) solve of the cell volume constraints of Diziol, Bender and Bayer
//! 2011.
//!
//! The Gauss-Seidel sweeps of [`CellVolumeConstraints::project`] fix one cell at a time; a volume
//! error spreads through the lattice like diffusion, so the number of sweeps grows with the lattice
//! size (measured: cost ~ particles^3 at a 1e-10 tolerance).
//! [`CellSolver::Global`](crate::cell_volume::CellSolver::Global) instead takes Newton steps on all
//! constraints `C_c(x) = V_c(x) - V0_c = 0` together, each the minimal mass-weighted correction of
//! the linearised constraints:
//!
//! ```text
//! (J W J^T) lambda = C,     dx = -W J^T lambda,     J = dC/dx (one row of 8 gradients per cell),
//! ```
//!
//! with `W = diag(1/m_i)`. This is the direction of [`CellCorrection::Gradient`] for every cell
//! at once: the velocity change `dx / h` is the `M`-orthogonal projection of the velocities onto
//! the linearised constraint set, so to first order it removes kinetic energy and never adds it,
//! and since every cell's gradients sum to zero (translation invariance) it conserves momentum
//! for any masses. `J W J^T` is a sparse cells x cells matrix (cells sharing a particle are
//! coupled), assembled with a cached pattern and factorised by sparse Cholesky
//! ([`balloon_linalg::SparseCholesky`], symbolic analysis reused). Convergence is
//! quadratic: a few factorisations per projection whatever the lattice size. A step that would
//! invert a tetrahedron is halved (up to 30 times) before it is taken.

use crate::ConstraintError;
use crate::cell_volume::cells::{CellVolumeConstraints, volume_and_gradient};
use crate::cell_volume::params::{CellCorrection, ProjectionInfo};
use balloon_linalg::{SparseAssembler, SparseCholesky};
use nalgebra::{Point3, Vector3};

/// Reusable state of the global cell-volume solve (see the module docs): particle-to-cell
/// incidence, gradients, the assembled matrix with its pattern and the sparse Cholesky factor.
/// Keep one per simulation and pass it to [`CellVolumeConstraints::project_with`] so that
/// nothing is allocated or analysed again from step to step. Cloning gives an empty workspace
/// (the caches are rebuilt on first use).
#[derive(Debug, Default)]
pub struct CellProjectionWorkspace {
    /// `incidence[incidence_ptr[i]..incidence_ptr[i + 1]]`: the `(cell, corner)` pairs of particle
    /// `i`, built for `built_for` (particle count, cell count).
    incidence_ptr: Vec<usize>,
    incidence: Vec<(usize, usize)>,
    built_for: (usize, usize),
    gradients: Vec<[Vector3<f64>; 8]>,
    residual: Vec<f64>,
    triplets: Vec<(usize, usize, f64)>,
    regularisation: Vec<f64>,
    step: Vec<Vector3<f64>>,
    start: Vec<Point3<f64>>,
    trial: Vec<Point3<f64>>,
    assembler: SparseAssembler,
    cholesky: SparseCholesky,
}

impl Clone for CellProjectionWorkspace {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl CellProjectionWorkspace {
    /// An empty workspace.
    pub fn new() -> Self {
        Self::default()
    }

    fn build_incidence(&mut self, cells: &[[usize; 8]], particles: usize) {
        if self.built_for == (particles, cells.len()) && !self.incidence_ptr.is_empty() {
            return;
        }
        let mut count = vec![0usize; particles + 1];
        for cell in cells {
            for &i in cell {
                count[i + 1] += 1;
            }
        }
        for i in 0..particles {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        self.incidence = vec![(0, 0); count[particles]];
        for (c, cell) in cells.iter().enumerate() {
            for (corner, &i) in cell.iter().enumerate() {
                self.incidence[fill[i]] = (c, corner);
                fill[i] += 1;
            }
        }
        self.incidence_ptr = count;
        self.built_for = (particles, cells.len());
    }
}

impl CellVolumeConstraints {
    /// The global solve of [`CellVolumeConstraints::project_with`] (see the module docs).
    pub(crate) fn project_global(
        &self,
        ws: &mut CellProjectionWorkspace,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        debug_assert_eq!(self.params.correction, CellCorrection::Gradient);
        if let Some(e) = self.find_inverted(preview) {
            return Err(e);
        }
        let (initial_error, initial_cell) = self.max_relative_error(preview);
        let mut info = ProjectionInfo {
            sweeps: 0,
            initial_error,
            final_error: initial_error,
        };
        if initial_error <= tolerance || self.cells.is_empty() {
            return Ok(info);
        }
        let n = preview.len();
        let nc = self.cells.len();
        ws.build_incidence(&self.cells, n);
        ws.gradients.resize(nc, [Vector3::zeros(); 8]);
        ws.residual.resize(nc, 0.0);
        ws.regularisation.resize(nc, 0.0);
        ws.step.resize(n, Vector3::zeros());
        ws.start.clear();
        ws.start.extend_from_slice(preview);
        let result = self.newton_iterations(
            ws,
            preview,
            masses,
            tolerance,
            (initial_error, initial_cell),
            &mut info,
        );
        // Whatever happened, the velocities carry the displacement made so far, so that
        // `p + h v` is the preview again (as after a Gauss-Seidel sweep that stopped early).
        for ((v, x), x0) in velocities.iter_mut().zip(preview.iter()).zip(&ws.start) {
            *v += (x - x0) / h;
        }
        result.map(|()| info)
    }

    /// The Newton iterations of [`CellVolumeConstraints::project_global`], moving `preview`.
    fn newton_iterations(
        &self,
        ws: &mut CellProjectionWorkspace,
        preview: &mut [Point3<f64>],
        masses: &[f64],
        tolerance: f64,
        (mut error, mut worst): (f64, usize),
        info: &mut ProjectionInfo,
    ) -> Result<(), ConstraintError> {
        let n = preview.len();
        for iteration in 1..=self.params.max_sweeps {
            // Linearise: C_c and dC_c/dx at the current preview.
            for (c, cell) in self.cells.iter().enumerate() {
                let v = volume_and_gradient(preview, cell, &self.tets[c], &mut ws.gradients[c]);
                ws.residual[c] = v - self.rest_volumes[c];
            }
            // J W J^T: particle i couples every pair of its cells.
            ws.triplets.clear();
            let mut max_diag = 0.0f64;
            for (i, &m) in masses.iter().enumerate().take(n) {
                let w = 1.0 / m;
                let inc = &ws.incidence[ws.incidence_ptr[i]..ws.incidence_ptr[i + 1]];
                for &(c, a) in inc {
                    for &(d, b) in inc {
                        let value = w * ws.gradients[c][a].dot(&ws.gradients[d][b]);
                        if c == d {
                            max_diag = max_diag.max(value);
                        }
                        ws.triplets.push((c, d, value));
                    }
                }
            }
            // A relative shift far below round-off of the solve keeps a (near-)singular system
            // factorisable without changing the converged point (the residual is re-measured).
            ws.regularisation.fill(1e-14 * max_diag);
            ws.assembler
                .assemble(&ws.regularisation, 1.0, &ws.triplets, 1.0)
                .map_err(|source| ConstraintError::GlobalSolve { iteration, source })?;
            ws.cholesky
                .factorize(ws.assembler.matrix(), ws.assembler.pattern_version())
                .map_err(|source| ConstraintError::GlobalSolve { iteration, source })?;
            ws.cholesky
                .solve_in_place(&mut ws.residual)
                .map_err(|source| ConstraintError::GlobalSolve { iteration, source })?;
            // dx = -W J^T lambda.
            for (i, dx) in ws.step.iter_mut().enumerate() {
                let mut s = Vector3::zeros();
                for &(c, a) in &ws.incidence[ws.incidence_ptr[i]..ws.incidence_ptr[i + 1]] {
                    s -= ws.gradients[c][a] * ws.residual[c];
                }
                *dx = s / masses[i];
            }
            // Take the step, halved while it would invert a tetrahedron or make the error
            // non-finite.
            let mut alpha = 1.0;
            let mut accepted = None;
            for _ in 0..30 {
                ws.trial.clear();
                ws.trial
                    .extend(preview.iter().zip(&ws.step).map(|(x, dx)| x + dx * alpha));
                if self.find_inverted(&ws.trial).is_none() {
                    let (e, cell) = self.max_relative_error(&ws.trial);
                    if e.is_finite() {
                        accepted = Some((e, cell));
                        break;
                    }
                }
                alpha *= 0.5;
            }
            let Some((e, cell)) = accepted else {
                // Report the inversion the full step makes.
                ws.trial.clear();
                ws.trial
                    .extend(preview.iter().zip(&ws.step).map(|(x, dx)| x + dx));
                return Err(self.find_inverted(&ws.trial).unwrap_or(
                    ConstraintError::CellVolumeNotConverged {
                        sweeps: iteration,
                        max_error: error,
                        cell: worst,
                    },
                ));
            };
            preview.copy_from_slice(&ws.trial);
            (error, worst) = (e, cell);
            info.sweeps = iteration;
            info.final_error = e;
            if e <= tolerance {
                return Ok(());
            }
        }
        Err(ConstraintError::CellVolumeNotConverged {
            sweeps: self.params.max_sweeps,
            max_error: error,
            cell: worst,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell_volume::{CellSolver, CellVolumeParams};
    use balloon_test_support::Rng;

    fn cube(n: usize) -> crate::cell_volume::tests::Block {
        crate::cell_volume::tests::block3(n, n, n)
    }

    /// The gradient correction with either solver (`CellVolumeParams::global()` for the global
    /// one).
    fn params(solver: CellSolver) -> CellVolumeParams {
        match solver {
            CellSolver::Global => CellVolumeParams::global(),
            CellSolver::GaussSeidel => CellVolumeParams {
                correction: CellCorrection::Gradient,
                ..CellVolumeParams::default()
            },
        }
    }

    fn random_vectors(n: usize, amp: f64, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = Rng::new(seed);
        (0..n)
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * amp)
            .collect()
    }

    fn momentum(v: &[Vector3<f64>], m: &[f64]) -> Vector3<f64> {
        v.iter()
            .zip(m)
            .fold(Vector3::zeros(), |a, (v, m)| a + v * *m)
    }

    fn kinetic(v: &[Vector3<f64>], m: &[f64]) -> f64 {
        v.iter()
            .zip(m)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum()
    }

    #[test]
    fn global_solve_restores_every_cell_quadratically_and_conserves_momentum() {
        let (x0, cells, tets) = cube(4);
        let c = CellVolumeConstraints::new(cells, tets, &x0, params(CellSolver::Global)).unwrap();
        let mut rng = Rng::new(7);
        let m: Vec<f64> = (0..x0.len()).map(|_| 1.0 + 0.5 * rng.next_f64()).collect();
        let mut v = random_vectors(x0.len(), 1.0, 8);
        let (p0, e0) = (momentum(&v, &m), kinetic(&v, &m));
        let h = 1e-2;
        let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
        let mut ws = CellProjectionWorkspace::new();
        let info = c
            .project_with(&mut ws, &mut x, &mut v, &m, h, 1e-12)
            .unwrap();
        assert!(info.initial_error > 1e-2, "{info:?}");
        assert!(info.final_error <= 1e-12, "{info:?}");
        // Newton: from a 1e-2..1e-1 error to 1e-12 in a handful of iterations.
        assert!(info.sweeps <= 5, "{info:?}");
        assert!(c.max_relative_error(&x).0 <= 1e-12);
        let p1 = momentum(&v, &m);
        assert!((p1 - p0).norm() < 1e-12, "momentum {p0:?} -> {p1:?}");
        assert!(kinetic(&v, &m) <= e0, "{e0} -> {}", kinetic(&v, &m));
        // p + h v is the corrected preview.
        for i in 0..x.len() {
            assert!((x0[i] + v[i] * h - x[i]).norm() < 1e-13);
        }
        // The workspace is reused: a second projection of another state converges too.
        let mut v2 = random_vectors(x0.len(), 0.5, 9);
        let mut x2: Vec<Point3<f64>> = x0.iter().zip(&v2).map(|(p, v)| p + v * h).collect();
        let again = c
            .project_with(&mut ws, &mut x2, &mut v2, &m, h, 1e-12)
            .unwrap();
        assert!(again.final_error <= 1e-12 && again.sweeps <= 5, "{again:?}");
    }

    #[test]
    fn global_solve_lands_where_the_gauss_seidel_gradient_sweeps_land() {
        // Both solve the same dual system J W J^T lambda = C (Gauss-Seidel one row at a time, in
        // the linear limit), so they reach the same corrected point up to terms of second order
        // in the correction; a wrong J, W or sign in the global assembly would not. Checked with
        // unequal masses, at two amplitudes (the gap must shrink like amplitude^2).
        let (x0, cells, tets) = cube(3);
        let global = CellVolumeConstraints::new(
            cells.clone(),
            tets.clone(),
            &x0,
            params(CellSolver::Global),
        )
        .unwrap();
        let sweeps =
            CellVolumeConstraints::new(cells, tets, &x0, params(CellSolver::GaussSeidel)).unwrap();
        let mut rng = Rng::new(4);
        let m: Vec<f64> = (0..x0.len()).map(|_| 1.0 + 0.5 * rng.next_f64()).collect();
        let h = 1e-2;
        for seed in 1..4 {
            let mut gaps = Vec::new();
            for amp in [0.2, 0.1] {
                let v = random_vectors(x0.len(), amp, seed);
                let x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
                let solve = |c: &CellVolumeConstraints| {
                    let (mut xc, mut vc) = (x.clone(), v.clone());
                    c.project_to_tolerance(&mut xc, &mut vc, &m, h, 1e-13)
                        .unwrap();
                    assert!(c.max_relative_error(&xc).0 <= 1e-13);
                    xc
                };
                let (xg, xs) = (solve(&global), solve(&sweeps));
                let norm = |a: &[Point3<f64>], b: &[Point3<f64>]| {
                    a.iter()
                        .zip(b)
                        .map(|(p, q)| (p - q).norm_squared())
                        .sum::<f64>()
                        .sqrt()
                };
                let (gap, moved) = (norm(&xg, &xs), norm(&xg, &x));
                assert!(
                    gap < 0.05 * moved,
                    "seed {seed} amp {amp}: gap {gap}, moved {moved}"
                );
                gaps.push(gap / moved);
            }
            // Relative gap ~ amplitude: halving the amplitude at least roughly halves it.
            assert!(gaps[1] < 0.7 * gaps[0], "seed {seed}: {gaps:?}");
        }
    }

    #[test]
    fn global_iterations_do_not_grow_with_the_lattice() {
        let mut iterations = Vec::new();
        for n in [2, 4, 8] {
            let (x0, cells, tets) = cube(n);
            let c =
                CellVolumeConstraints::new(cells, tets, &x0, params(CellSolver::Global)).unwrap();
            let mut v = random_vectors(x0.len(), 0.5, 3);
            let h = 1e-2;
            let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
            let info = c.project(&mut x, &mut v, &vec![1.0; x0.len()], h).unwrap();
            assert!(info.final_error <= 1e-10);
            iterations.push(info.sweeps);
        }
        assert!(
            iterations.iter().all(|&k| (1..=5).contains(&k)),
            "{iterations:?}"
        );
    }

    #[test]
    fn a_stopped_solve_leaves_velocities_matching_the_preview_and_sizes_are_checked() {
        // One Newton iteration cannot reach 1e-12 from a 1% error: NotConverged, but the
        // velocities carry the displacement made, as the Gauss-Seidel sweeps do.
        let (x0, cells, tets) = cube(3);
        let params = CellVolumeParams {
            max_sweeps: 1,
            ..CellVolumeParams::global()
        };
        let c = CellVolumeConstraints::new(cells, tets, &x0, params).unwrap();
        let mut v = random_vectors(x0.len(), 1.0, 5);
        let h = 1e-2;
        let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
        let m = vec![1.0; x0.len()];
        let e = c
            .project_to_tolerance(&mut x, &mut v, &m, h, 1e-12)
            .unwrap_err();
        assert!(
            matches!(e, ConstraintError::CellVolumeNotConverged { sweeps: 1, .. }),
            "{e}"
        );
        for i in 0..x.len() {
            assert!((x0[i] + v[i] * h - x[i]).norm() < 1e-13);
        }
        // Wrong slice lengths are named, for either solver.
        let e = c.project(&mut x, &mut v, &m[1..], h).unwrap_err();
        assert_eq!(
            e,
            ConstraintError::LengthMismatch {
                name: "masses",
                len: m.len() - 1,
                expected: x.len()
            }
        );
        let e = c
            .project(&mut x, &mut v[1..], &m, h)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`velocities`"), "{e}");
    }

    #[test]
    fn global_solver_rejects_scaling_and_over_relaxation_and_reports_inversion() {
        let (x0, cells, tets) = cube(2);
        let scaling = CellVolumeParams {
            solver: CellSolver::Global,
            ..CellVolumeParams::default()
        };
        let e = CellVolumeConstraints::new(cells.clone(), tets.clone(), &x0, scaling).unwrap_err();
        assert!(e.to_string().contains("`correction`"), "{e}");
        let sor = CellVolumeParams {
            over_relaxation: 1.3,
            ..params(CellSolver::Global)
        };
        let e = CellVolumeConstraints::new(cells.clone(), tets.clone(), &x0, sor).unwrap_err();
        assert!(e.to_string().contains("`over_relaxation`"), "{e}");
        let c = CellVolumeConstraints::new(cells, tets, &x0, params(CellSolver::Global)).unwrap();
        let mut x = x0.clone();
        x[c.cells[0][6]] = Point3::new(-0.05, -0.05, -0.05);
        let mut v = vec![Vector3::zeros(); x.len()];
        let e = c
            .project(&mut x, &mut v, &vec![1.0; x0.len()], 1e-2)
            .unwrap_err();
        assert!(
            matches!(e, ConstraintError::Inverted { cell: 0, .. }),
            "{e}"
        );
    }

    #[test]
    fn a_failed_global_factorisation_keeps_the_linear_solver_error_as_its_source() {
        // Negative masses make J W J^T negative definite: the Cholesky factorisation of the
        // first Newton iteration fails, and the linear solver's own error is the source.
        let (x0, cells, tets) = cube(2);
        let c = CellVolumeConstraints::new(cells, tets, &x0, params(CellSolver::Global)).unwrap();
        let mut x: Vec<Point3<f64>> = x0.iter().map(|p| p * 1.01).collect();
        let mut v = vec![Vector3::zeros(); x.len()];
        let e = c
            .project(&mut x, &mut v, &vec![-1.0; x0.len()], 1e-2)
            .unwrap_err();
        let ConstraintError::GlobalSolve { iteration, source } = &e else {
            panic!("expected a global solve failure, got {e}");
        };
        assert_eq!(*iteration, 1);
        assert!(source.is_indefinite(), "{source}");
        let dyn_source = std::error::Error::source(&e).expect("the solve error is the source");
        assert_eq!(
            dyn_source.downcast_ref::<balloon_linalg::SolveError>(),
            Some(source)
        );
        assert!(e.to_string().contains("Newton iteration 1"), "{e}");
    }
}
