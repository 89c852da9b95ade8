//! The distance objective of the shape optimisation (`docs/design.md`, D11): the forward
//! static equilibrium `x(X)` of a rest shape, its area-weighted distance to the target over the
//! rigid alignment, the adjoint gradient through the static solve (D12), and the exact
//! sensitivity `dx/dX` with its transpose and the Gauss-Newton product (D15).

use balloon_integrate::ForceSystem;
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_shell::statics::{GasTerm, StaticShell};
use nalgebra::{Matrix3, Vector3};

use std::borrow::Cow;

use crate::DesignError;
use crate::forward::{Distance, distance, rigidly_aligned, shell_from_rest};
use crate::gauss_newton::{dot, remove_rigid_motion};
use crate::normal::NormalPattern;
use crate::pinned::{PinnedLu, pinned_unknowns};
use crate::problem::{DesignProblem, point};

/// The objective at one rest shape: [`ShapeObjective::evaluate`].
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// `D = 1/2 sum_v w_v |R x_v + t - x*_v|^2` (m^2), minimised over the rigid motion
    /// `(R, t)`.
    pub objective: f64,
    /// `dD/dX` (m), when asked for.
    pub gradient: Option<Vec<f64>>,
    /// The forward equilibrium, rigidly aligned onto the target (unweighted, as
    /// [`crate::forward_check`] aligns it).
    pub aligned: Vec<f64>,
    /// Its distance to the target.
    pub distance: Distance,
}

/// The distance objective `D(X)` of the shape optimisation and its adjoint gradient, with the
/// forward static solver and the last equilibrium kept between calls (the warm start).
pub struct ShapeObjective<'a> {
    /// Borrowed; owned once the thickness fit changes its wall ([`ShapeObjective::set_thickness`]).
    problem: Cow<'a, DesignProblem>,
    pattern: NormalPattern,
    weights: Vec<f64>,
    solver: StaticSolver,
    /// The last equilibrium (solver frame), the next solve's start.
    equilibrium: Option<Vec<f64>>,
    /// Start from `equilibrium` (else from the rest shape, with continuation).
    warm_start: bool,
    lu: Option<(PinnedLu, [usize; 6])>,
    /// The linearisation at the last evaluation with a gradient.
    linear: Option<Linearisation>,
    /// The gas's volume coupling there (none for a constant pressure).
    gas: Option<GasCoupling>,
    forward_solves: usize,
}

/// The rank-one volume coupling `c u u^T` of a gas whose pressure follows the volume
/// (`c = -dp/dV`, `u = dV/dx`) at the last linearised equilibrium, with `K0^-T u` and `K0^-1 u`
/// on the factor of the assembled stiffness `K0`.
struct GasCoupling {
    coefficient: f64,
    u: Vec<f64>,
    kt_inv_u: Vec<f64>,
    k_inv_u: Vec<f64>,
}

impl GasCoupling {
    /// Turns `y = A^-1 b` into `(A + c u u^T)^-1 b` (Sherman-Morrison), given `a_inv_u =
    /// A^-1 u` (`A` is `K0` or `K0^T`; the coupling is symmetric).
    fn correct(&self, y: &mut [f64], a_inv_u: &[f64]) {
        let c = self.coefficient;
        let s = c * dot(&self.u, y) / (1.0 + c * dot(&self.u, a_inv_u));
        for (yi, wi) in y.iter_mut().zip(a_inv_u) {
            *yi -= s * wi;
        }
    }
}

/// The adjoint solve's results (D12): `dD/dX`, the rest Jacobian `df/dX` and `lambda`.
struct Adjoint {
    gradient: Vec<f64>,
    j: Vec<Matrix3<f64>>,
    lambda: Vec<f64>,
}

/// What the Gauss-Newton products need at one equilibrium: the rest Jacobian `df/dX` there
/// (the forward stiffness's factor is kept in [`ShapeObjective`]'s `lu`), the weighted
/// alignment's rotation and the aligned equilibrium.
struct Linearisation {
    j: Vec<Matrix3<f64>>,
    /// The adjoint `lambda` of D12 (`K^T lambda = dD/dx`).
    lambda: Vec<f64>,
    rotation: Matrix3<f64>,
    aligned: Vec<f64>,
}

impl<'a> ShapeObjective<'a> {
    /// The objective of `problem`, its forward solves with `forward` at the relative
    /// tolerance `tolerance`.
    ///
    /// # Errors
    /// [`DesignError::Forward`] for static parameters out of range.
    pub fn new(
        problem: &'a DesignProblem,
        forward: &StaticParams,
        tolerance: f64,
    ) -> Result<Self, DesignError> {
        let params = StaticParams {
            tolerance,
            // A free body: its rigid motions are kept out of the Newton directions.
            remove_rigid_motions: true,
            ..*forward
        };
        let solver = StaticSolver::new(params).map_err(|e| DesignError::Forward(e.to_string()))?;
        Ok(Self {
            problem: Cow::Borrowed(problem),
            pattern: problem.pattern(),
            weights: vertex_weights(problem),
            solver,
            equilibrium: None,
            warm_start: true,
            lu: None,
            linear: None,
            gas: None,
            forward_solves: 0,
        })
    }

    /// The vertex weights `w_v` (the target's vertex areas over their mean).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// The last equilibrium found (in the solver's frame, not aligned).
    pub fn equilibrium(&self) -> Option<&[f64]> {
        self.equilibrium.as_deref()
    }

    /// Sets the start of the next forward solve.
    pub fn set_equilibrium(&mut self, x: Option<Vec<f64>>) {
        self.equilibrium = x;
    }

    /// Whether a forward solve starts from the last equilibrium (default `true`) or from the
    /// rest shape with load continuation, as [`crate::forward_check`] does.
    pub fn set_warm_start(&mut self, warm_start: bool) {
        self.warm_start = warm_start;
    }

    /// Forward static solves so far.
    pub fn forward_solves(&self) -> usize {
        self.forward_solves
    }

    /// The wall's rest thickness per face (m) in the objective's problem.
    pub fn thickness(&self) -> &[f64] {
        self.problem.thickness()
    }

    /// Gives the wall the rest thickness `thickness` (one per face, m) for the next
    /// evaluations (the thickness fit, `docs/design.md` D18); the kept equilibrium stays the
    /// next warm start, the last linearisation is dropped.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `thickness` (wrong length, not positive and
    /// finite); nothing is changed then.
    pub fn set_thickness(&mut self, thickness: &[f64]) -> Result<(), DesignError> {
        crate::problem::check_thickness(thickness, self.problem.triangles().len())?;
        self.problem.to_mut().set_thickness(thickness);
        self.linear = None;
        Ok(())
    }

    /// `dD/dH_e = sum_a lambda_a . df_a/dH_e` over the corners `a` of face `e` (m^2 per m),
    /// at the last evaluation with a gradient, whose rest shape was `rest` (D18). The elastic
    /// forces of both elements are linear in their rest thickness at fixed rest and deformed
    /// positions (`E = A0 H W(F)` with `F` independent of `H` when the prism's current
    /// thickness is `H`), so `df_e/dH_e = f_e / H_e`; the pressure forces do not depend on
    /// `H`. A bending hinge of the wall ([`DesignProblem::with_wall_bending`]) has
    /// `D ~ h^3` with `h` the mean of its two faces' `H`, so `df/dH = 3 f / (2 h)` for each.
    ///
    /// # Errors
    /// [`DesignError::Linear`] when there is no such evaluation, and the element errors of a
    /// degenerate rest triangle.
    pub fn thickness_gradient(&self, rest: &[f64]) -> Result<Vec<f64>, DesignError> {
        let (linear, _) = self.linearisation()?;
        let x = self.equilibrium.as_deref().ok_or(DesignError::Linear(
            "no equilibrium linearised yet (evaluate with the gradient first)".into(),
        ))?;
        let problem: &DesignProblem = &self.problem;
        let mut g = vec![0.0; problem.triangles().len()];
        for (e, (t, ge)) in problem.triangles().iter().zip(&mut g).enumerate() {
            let (f, _) = problem.element_at(e, x, rest)?;
            let sum: f64 = t
                .iter()
                .zip(&f)
                .map(|(&v, fa)| fa.dot(&point(&linear.lambda, v)))
                .sum();
            *ge = sum / problem.thickness()[e];
        }
        // The wall's bending hinges: `D = s Y h^3 / (12 (1 - nu^2))` with `h = (H_A + H_B) / 2`,
        // so `df/dH_A = df/dH_B = 3 f / (2 h)`.
        for (k, c) in problem.hinge_corners().iter().enumerate() {
            let (f, _) = problem.hinge_at(k, x, rest)?;
            let faces = problem.hinge_faces(k);
            let h = 0.5 * (problem.thickness()[faces[0]] + problem.thickness()[faces[1]]);
            let sum: f64 = c
                .iter()
                .zip(&f)
                .map(|(&v, fa)| fa.dot(&point(&linear.lambda, v)))
                .sum();
            for face in faces {
                g[face] += 1.5 * sum / h;
            }
        }
        Ok(g)
    }

    /// `D(X)` at the rest shape `rest`, and `dD/dX` when `gradient`. The forward solve starts
    /// from the last equilibrium (from `rest` with load continuation when there is none or
    /// that fails). `Ok(None)` when the rest shape has no forward equilibrium the solver finds
    /// (or a degenerate triangle); the kept equilibrium is then unchanged.
    ///
    /// # Errors
    /// [`DesignError::Linear`] when the forward stiffness at the equilibrium cannot be
    /// factorised for the adjoint, [`DesignError::Forward`] for a volume-dependent pressure
    /// (not supported), and the rest Jacobian's errors.
    pub fn evaluate(
        &mut self,
        rest: &[f64],
        gradient: bool,
    ) -> Result<Option<Evaluation>, DesignError> {
        self.evaluate_inner(rest, gradient, true)
    }

    /// [`ShapeObjective::evaluate`] with the gradient at the kept equilibrium, which must be
    /// that of `rest` (the last evaluation's), without solving again.
    pub(crate) fn linearise_kept(
        &mut self,
        rest: &[f64],
    ) -> Result<Option<Evaluation>, DesignError> {
        self.evaluate_inner(rest, true, false)
    }

    fn evaluate_inner(
        &mut self,
        rest: &[f64],
        gradient: bool,
        solve: bool,
    ) -> Result<Option<Evaluation>, DesignError> {
        let Ok(mut shell) = shell_from_rest(&self.problem, rest) else {
            return Ok(None);
        };
        let mut x = self.equilibrium.clone().unwrap_or_else(|| rest.to_vec());
        let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
        if !solve && self.equilibrium.is_some() {
            return self.finish(&mut statics, rest, x, gradient).map(Some);
        }
        self.forward_solves += 1;
        let mut solved = self.warm_start
            && self.equilibrium.is_some()
            && self.solver.solve(&mut statics, 0.0, &mut x, None).is_ok();
        if !solved {
            x.copy_from_slice(rest);
            if !self.warm_start {
                // A fresh solver (no kept factor): the same solve as the forward check's.
                self.solver = StaticSolver::new(*self.solver.params())
                    .map_err(|e| DesignError::Forward(e.to_string()))?;
            }
            solved = self
                .solver
                .solve_with_continuation(&mut statics, 0.0, &mut x, None)
                .is_ok();
        }
        if !solved {
            return Ok(None);
        }
        self.finish(&mut statics, rest, x, gradient).map(Some)
    }

    /// The objective at the equilibrium `x` of `rest` (and its gradient); keeps `x`.
    fn finish(
        &mut self,
        statics: &mut impl ForceSystem,
        rest: &[f64],
        x: Vec<f64>,
        gradient: bool,
    ) -> Result<Evaluation, DesignError> {
        let n = rest.len();
        let target = self.problem.target();
        let (r, t) = weighted_alignment(&x, target, &self.weights);
        let mut objective = 0.0;
        // dD/dx_v = w_v R^T (R x_v + t - x*_v) (the optimal rigid motion is stationary).
        let mut b = vec![0.0; n];
        let mut weighted = vec![0.0; n];
        for (v, w) in self.weights.iter().enumerate() {
            let y = r * point(&x, v) + t;
            let e = y - point(target, v);
            objective += 0.5 * w * e.norm_squared();
            let g = r.transpose() * e * *w;
            b[3 * v..3 * v + 3].copy_from_slice(g.as_slice());
            weighted[3 * v..3 * v + 3].copy_from_slice(y.as_slice());
        }
        let aligned = rigidly_aligned(&x, target);
        let dist = distance(&aligned, target);
        let gradient = if gradient {
            self.linear = None;
            let Adjoint {
                gradient: g,
                j,
                lambda,
            } = self.adjoint(statics, rest, &x, &b)?;
            self.linear = Some(Linearisation {
                j,
                lambda,
                rotation: r,
                aligned: weighted,
            });
            Some(g)
        } else {
            None
        };
        self.equilibrium = Some(x);
        Ok(Evaluation {
            objective,
            gradient,
            aligned,
            distance: dist,
        })
    }

    /// `dD/dX = (df/dX)^T lambda` with `K^T lambda = dD/dx` (D12), `K = -df/dx` the forward
    /// stiffness at the equilibrium `x`, six unknowns of `lambda` pinned for its rigid null
    /// space.
    fn adjoint(
        &mut self,
        statics: &mut impl ForceSystem,
        rest: &[f64],
        x: &[f64],
        b: &[f64],
    ) -> Result<Adjoint, DesignError> {
        let n = x.len();
        let mut f = vec![0.0; n];
        statics
            .forces(0.0, x, &mut f)
            .map_err(|e| DesignError::Forward(e.to_string()))?;
        let coupling: Vec<_> = statics
            .low_rank_terms()
            .iter()
            .filter(|t| t.coefficient != 0.0)
            .cloned()
            .collect();
        if coupling.len() > 1 {
            return Err(DesignError::Forward(
                "the adjoint handles one volume coupling of the gas, not several".into(),
            ));
        }
        let mut triplets = Vec::new();
        statics
            .add_stiffness_triplets(&mut triplets)
            .map_err(|e| DesignError::Forward(e.to_string()))?;
        // K^T in the vertex blocks of the one-ring pattern.
        let mut kt = vec![Matrix3::zeros(); self.pattern.j_blocks()];
        for (i, j, v) in triplets {
            kt[self.pattern.j_slot(j / 3, i / 3)][(j % 3, i % 3)] += v;
        }
        let pins = pinned_unknowns(x);
        if self.lu.as_ref().is_none_or(|(_, p)| *p != pins) {
            self.lu = Some((PinnedLu::new(&self.pattern, x), pins));
        }
        let (lu, _) = self.lu.as_mut().expect("set above");
        if !lu.factorize(&kt) {
            return Err(DesignError::Linear(
                "the forward stiffness at the equilibrium cannot be factorised".into(),
            ));
        }
        // The gas's volume coupling `K = K0 + c u u^T` (Wang et al. 2015, Eq. 16-17) by
        // Sherman-Morrison on the factor of `K0` (`docs/design.md`, "A gas amount as the load").
        self.gas = match coupling.into_iter().next() {
            None => None,
            Some(t) => {
                let non_finite = || {
                    DesignError::Linear("the gas coupling's solve gave a non-finite value".into())
                };
                // The factor solves with the pinned unknowns held at zero and their equations
                // dropped: the same reduced system of `K` keeps `u` without those entries.
                let mut u = t.vector;
                for &i in &pins {
                    u[i] = 0.0;
                }
                // `step` solves `K0^T y = -rhs`.
                let minus_u: Vec<f64> = u.iter().map(|a| -a).collect();
                let kt_inv_u = lu.step(&minus_u).ok_or_else(non_finite)?;
                let k_inv_u = lu.transpose_solve(&u).ok_or_else(non_finite)?;
                Some(GasCoupling {
                    coefficient: t.coefficient,
                    u,
                    kt_inv_u,
                    k_inv_u,
                })
            }
        };
        let minus_b: Vec<f64> = b.iter().map(|v| -v).collect();
        let mut lambda = lu.step(&minus_b).ok_or(DesignError::Linear(
            "the adjoint solve gave a non-finite value".into(),
        ))?;
        if let Some(gas) = &self.gas {
            gas.correct(&mut lambda, &gas.kt_inv_u);
        }
        let mut j = vec![Matrix3::zeros(); self.pattern.j_blocks()];
        self.problem
            .rest_jacobian_at(x, rest, &self.pattern, &mut j)?;
        let mut g = vec![0.0; n];
        self.pattern.transpose_apply(&j, &lambda, &mut g);
        Ok(Adjoint {
            gradient: g,
            j,
            lambda,
        })
    }

    /// `dx/dX v = K^-1 (df/dX) v`: the change of the equilibrium (solver frame) along the
    /// rest-shape direction `v`, at the last evaluation with a gradient (`docs/design.md`,
    /// D15). `K` is singular for the rigid motions of `x`, so the result is one
    /// representative modulo them (six unknowns pinned as in D10); the distance does not see
    /// them.
    ///
    /// # Errors
    /// [`DesignError::Linear`] when there is no such evaluation (or its factor) or the
    /// solve is not finite; [`DesignError::InvalidParameter`] for a `v` of the wrong length.
    pub fn sensitivity(&self, v: &[f64]) -> Result<Vec<f64>, DesignError> {
        self.check_length(v)?;
        let (linear, lu) = self.linearisation()?;
        let mut jv = vec![0.0; v.len()];
        self.pattern.apply(&linear.j, v, &mut jv);
        let mut y = lu.transpose_solve(&jv).ok_or(DesignError::Linear(
            "the sensitivity solve gave a non-finite value".into(),
        ))?;
        if let Some(gas) = &self.gas {
            gas.correct(&mut y, &gas.k_inv_u);
        }
        Ok(y)
    }

    /// `(dx/dX)^T y = (df/dX)^T K^-T y`, the transpose of [`ShapeObjective::sensitivity`]
    /// for a `y` orthogonal to the rigid motions of the equilibrium (as every `dD/dx` is).
    ///
    /// # Errors
    /// As [`ShapeObjective::sensitivity`].
    pub fn sensitivity_transpose(&self, y: &[f64]) -> Result<Vec<f64>, DesignError> {
        self.check_length(y)?;
        let (linear, lu) = self.linearisation()?;
        let minus: Vec<f64> = y.iter().map(|a| -a).collect();
        let mut lambda = lu.step(&minus).ok_or(DesignError::Linear(
            "the adjoint solve gave a non-finite value".into(),
        ))?;
        if let Some(gas) = &self.gas {
            gas.correct(&mut lambda, &gas.kt_inv_u);
        }
        let mut g = vec![0.0; y.len()];
        self.pattern.transpose_apply(&linear.j, &lambda, &mut g);
        Ok(g)
    }

    /// The Gauss-Newton matrix's product `S^T R^T W P R S v` (D15): `S = dx/dX`, `R` the
    /// weighted alignment's rotation, `P` the `W`-orthogonal projection that removes the
    /// rigid motions of the aligned equilibrium, `W` the vertex weights.
    ///
    /// # Errors
    /// As [`ShapeObjective::sensitivity`].
    pub fn gauss_newton_product(&self, v: &[f64]) -> Result<Vec<f64>, DesignError> {
        let (linear, _) = self.linearisation()?;
        let mut u = self.sensitivity(v)?;
        let rt = linear.rotation.transpose();
        for c in u.chunks_mut(3) {
            let y = linear.rotation * Vector3::new(c[0], c[1], c[2]);
            c.copy_from_slice(y.as_slice());
        }
        remove_rigid_motion(&linear.aligned, &self.weights, &mut u);
        for (c, w) in u.chunks_mut(3).zip(&self.weights) {
            let y = rt * Vector3::new(c[0], c[1], c[2]) * *w;
            c.copy_from_slice(y.as_slice());
        }
        self.sensitivity_transpose(&u)
    }

    fn check_length(&self, v: &[f64]) -> Result<(), DesignError> {
        self.problem.check_length("direction", v)
    }

    fn linearisation(&self) -> Result<(&Linearisation, &PinnedLu), DesignError> {
        match (&self.linear, &self.lu) {
            (Some(l), Some((lu, _))) => Ok((l, lu)),
            _ => Err(DesignError::Linear(
                "no equilibrium linearised yet (evaluate with the gradient first)".into(),
            )),
        }
    }
}

/// The target's vertex areas (a third of each adjacent triangle's) over their mean.
fn vertex_weights(problem: &DesignProblem) -> Vec<f64> {
    let x = problem.target();
    let mut a = vec![0.0; x.len() / 3];
    for t in problem.triangles() {
        let [p, q, r] = crate::problem::corners(x, t);
        let area = (q - p).cross(&(r - p)).norm() / 2.0;
        for &v in t {
            a[v] += area / 3.0;
        }
    }
    let mean = a.iter().sum::<f64>() / a.len().max(1) as f64;
    a.iter().map(|v| v / mean).collect()
}

/// The rigid motion `(R, t)` minimising `sum_v w_v |R x_v + t - y_v|^2` (weighted Kabsch).
fn weighted_alignment(x: &[f64], y: &[f64], w: &[f64]) -> (Matrix3<f64>, Vector3<f64>) {
    let total: f64 = w.iter().sum();
    let (mut cx, mut cy) = (Vector3::zeros(), Vector3::zeros());
    for (v, wv) in w.iter().enumerate() {
        cx += point(x, v) * *wv;
        cy += point(y, v) * *wv;
    }
    cx /= total;
    cy /= total;
    let mut h = Matrix3::zeros();
    for (v, wv) in w.iter().enumerate() {
        h += (point(x, v) - cx) * (point(y, v) - cy).transpose() * *wv;
    }
    let svd = h.svd(true, true);
    let r = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => {
            let mut d = Matrix3::identity();
            if (vt.transpose() * u.transpose()).determinant() < 0.0 {
                d[(2, 2)] = -1.0;
            }
            vt.transpose() * d * u.transpose()
        }
        _ => Matrix3::identity(),
    };
    (r, cy - r * cx)
}
