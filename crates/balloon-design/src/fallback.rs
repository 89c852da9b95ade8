//! The shape-optimisation fallback where the inverse has no exact answer: the rest shape `X`
//! that minimises the distance of its forward static equilibrium `x(X)` to the target,
//! with the exact adjoint gradient through the static solve and an L-BFGS outer loop
//! (`docs/design.md`, D11-D14).

use balloon_integrate::ForceSystem;
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_shell::statics::{GasTerm, StaticShell};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::forward::{Distance, distance, rigidly_aligned, shell_from_rest};
use crate::normal::NormalPattern;
use crate::pinned::{PinnedLu, pinned_unknowns};
use crate::problem::DesignProblem;

/// When [`crate::design`] runs the shape optimisation after the inverse solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FallbackMode {
    /// Never (`"off"`).
    Off,
    /// After an inverse solve that did not converge (`"unconverged"`, default), unless it was
    /// stopped from outside.
    #[default]
    Unconverged,
    /// After every inverse solve (`"always"`); after a converged one it stops at once when the
    /// distance is already below [`FallbackParams::distance_tolerance`].
    Always,
}

impl std::str::FromStr for FallbackMode {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "off" => Ok(Self::Off),
            "unconverged" => Ok(Self::Unconverged),
            "always" => Ok(Self::Always),
            _ => Err(format!(
                "unknown fallback `{s}`; expected \"off\", \"unconverged\" or \"always\""
            )),
        }
    }
}

/// Parameters of [`optimise_rest_shape`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FallbackParams {
    /// When [`crate::design`] runs it (default [`FallbackMode::Unconverged`]).
    pub mode: FallbackMode,
    /// L-BFGS iterations (default 60; each costs one forward static solve, warm-started, more
    /// when the line search backtracks).
    pub max_iterations: usize,
    /// Pairs kept by L-BFGS (default 8).
    pub memory: usize,
    /// Stop when the gradient's norm falls below this fraction of the first one (default
    /// `1e-6`).
    pub gradient_tolerance: f64,
    /// Stop when the largest vertex distance falls below this fraction of the target's
    /// bounding-box diagonal (default `1e-8`).
    pub distance_tolerance: f64,
    /// Weight `beta` of the tangential regulariser (default 0): the term
    /// `beta/2 sum_v a_v |(I - n_v n_v^T)(X_v - X_v^start)|^2` added to the distance, with
    /// the inverse's projectors and vertex weights (`InverseParams::tangential_weight`), in the
    /// same units as the distance (m^2).
    pub tangential_weight: f64,
    /// Relative residual of the forward static solves (default `None`: the forward check's
    /// own tolerance, so that the optimised distance is the one the check finds where the
    /// forward problem has several equilibria; the adjoint gradient is exact up to the
    /// equilibrium's residual).
    pub forward_tolerance: Option<f64>,
    /// Largest vertex move of one step, over the target's mean edge length (default 0.25).
    pub max_move: f64,
    /// Start each forward solve from the last equilibrium (`true`) instead of from the rest
    /// shape with load continuation as [`crate::forward_check`] does (default `false`). Faster,
    /// but where the forward problem has several equilibria (compressed, wrinkling regions)
    /// the warm-started path can follow one that the check from the rest shape does not find,
    /// so the check's distance may not be the optimised one (`docs/design.md`).
    pub warm_start: bool,
}

impl Default for FallbackParams {
    fn default() -> Self {
        Self {
            mode: FallbackMode::Unconverged,
            max_iterations: 60,
            memory: 8,
            gradient_tolerance: 1e-6,
            distance_tolerance: 1e-8,
            tangential_weight: 0.0,
            forward_tolerance: None,
            max_move: 0.25,
            warm_start: false,
        }
    }
}

impl FallbackParams {
    /// Checks every parameter; the error names the first one out of range.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), DesignError> {
        for (name, value, ok) in [
            ("memory", self.memory as f64, self.memory > 0),
            (
                "gradient_tolerance",
                self.gradient_tolerance,
                self.gradient_tolerance >= 0.0,
            ),
            (
                "distance_tolerance",
                self.distance_tolerance,
                self.distance_tolerance >= 0.0,
            ),
            (
                "tangential_weight",
                self.tangential_weight,
                self.tangential_weight >= 0.0,
            ),
            (
                "forward_tolerance",
                self.forward_tolerance.unwrap_or(1.0),
                self.forward_tolerance.is_none_or(|t| t > 0.0),
            ),
            ("max_move", self.max_move, self.max_move > 0.0),
        ] {
            if !(value.is_finite() && ok) {
                return Err(DesignError::InvalidParameter {
                    name,
                    value,
                    allowed: "a finite value in range (see FallbackParams)",
                });
            }
        }
        Ok(())
    }
}

/// Why [`optimise_rest_shape`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FallbackStop {
    /// The distance fell below [`FallbackParams::distance_tolerance`].
    Distance,
    /// The gradient fell below [`FallbackParams::gradient_tolerance`]: a local minimum of
    /// the distance.
    Gradient,
    /// [`FallbackParams::max_iterations`] were taken.
    Iterations,
    /// No step along the search direction decreased the objective (or every trial's forward
    /// solve failed): the best rest shape so far is kept.
    LineSearch,
    /// The progress callback asked to stop (Ctrl-C).
    Interrupted,
    /// The forward static solve from the start rest shape found no equilibrium: nothing to
    /// optimise (the start is kept).
    NoEquilibrium,
}

/// What [`optimise_rest_shape`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FallbackInfo {
    /// Accepted L-BFGS steps.
    pub iterations: usize,
    /// Forward static solves (line-search trials included).
    pub forward_solves: usize,
    /// Distance of the start's forward equilibrium to the target (rigidly aligned as the
    /// forward check aligns it); `None` when it has none.
    pub start: Option<Distance>,
    /// The same for the returned rest shape.
    pub end: Option<Distance>,
    /// The objective `D` (area-weighted, m^2; `docs/design.md`, D11) at the start.
    pub objective_start: f64,
    /// The objective at the end.
    pub objective_end: f64,
    /// Norm of the last gradient over the first one.
    pub gradient_reduction: f64,
    /// Why it stopped.
    pub stopped: FallbackStop,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Progress of the shape optimisation, reported after every accepted step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FallbackProgress {
    /// Accepted steps so far.
    pub iteration: usize,
    /// The objective `D` (m^2).
    pub objective: f64,
    /// The largest vertex distance of the forward equilibrium to the target (m).
    pub max_distance: f64,
    /// The RMS vertex distance (m).
    pub rms_distance: f64,
}

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
    problem: &'a DesignProblem,
    pattern: NormalPattern,
    weights: Vec<f64>,
    solver: StaticSolver,
    /// The last equilibrium (solver frame), the next solve's start.
    equilibrium: Option<Vec<f64>>,
    /// Start from `equilibrium` (else from the rest shape, with continuation).
    warm_start: bool,
    lu: Option<(PinnedLu, [usize; 6])>,
    forward_solves: usize,
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
            ..*forward
        };
        let solver = StaticSolver::new(params).map_err(|e| DesignError::Forward(e.to_string()))?;
        Ok(Self {
            problem,
            pattern: NormalPattern::new(problem.num_dofs() / 3, problem.triangles()),
            weights: vertex_weights(problem),
            solver,
            equilibrium: None,
            warm_start: true,
            lu: None,
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
        let Ok(mut shell) = shell_from_rest(self.problem, rest) else {
            return Ok(None);
        };
        let n = rest.len();
        let mut x = self.equilibrium.clone().unwrap_or_else(|| rest.to_vec());
        let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
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
        let target = self.problem.target();
        let (r, t) = weighted_alignment(&x, target, &self.weights);
        let mut objective = 0.0;
        // dD/dx_v = w_v R^T (R x_v + t - x*_v) (the optimal rigid motion is stationary).
        let mut b = vec![0.0; n];
        for (v, w) in self.weights.iter().enumerate() {
            let e = r * point(&x, v) + t - point(target, v);
            objective += 0.5 * w * e.norm_squared();
            let g = r.transpose() * e * *w;
            b[3 * v..3 * v + 3].copy_from_slice(g.as_slice());
        }
        let aligned = rigidly_aligned(&x, target);
        let dist = distance(&aligned, target);
        let gradient = if gradient {
            Some(self.adjoint(&mut statics, rest, &x, &b)?)
        } else {
            None
        };
        drop(statics);
        self.equilibrium = Some(x);
        Ok(Some(Evaluation {
            objective,
            gradient,
            aligned,
            distance: dist,
        }))
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
    ) -> Result<Vec<f64>, DesignError> {
        let n = x.len();
        let mut f = vec![0.0; n];
        statics
            .forces(0.0, x, &mut f)
            .map_err(|e| DesignError::Forward(e.to_string()))?;
        if statics
            .low_rank_terms()
            .iter()
            .any(|t| t.coefficient != 0.0)
        {
            return Err(DesignError::Forward(
                "the adjoint needs a pressure that does not depend on the volume".into(),
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
        let minus_b: Vec<f64> = b.iter().map(|v| -v).collect();
        let lambda = lu.step(&minus_b).ok_or(DesignError::Linear(
            "the adjoint solve gave a non-finite value".into(),
        ))?;
        let mut j = vec![Matrix3::zeros(); self.pattern.j_blocks()];
        self.problem
            .rest_jacobian_at(x, rest, &self.pattern, &mut j)?;
        let mut g = vec![0.0; n];
        self.pattern.transpose_apply(&j, &lambda, &mut g);
        Ok(g)
    }
}

fn point(x: &[f64], v: usize) -> Vector3<f64> {
    Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2])
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

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises `Phi(X) = D(X) + beta/2 sum_v (X_v - X_v^0)^T T_v (X_v - X_v^0)` over the rest
/// shape from `rest` (overwritten with the best rest shape found): `D` the area-weighted
/// squared distance of the forward static equilibrium of `X` under the problem's pressure to
/// the target (D11), its gradient by the adjoint of the static solve (D12), L-BFGS with a
/// backtracking (Armijo) line search, each forward solve from the rest shape as the forward
/// check's, or warm-started from the last equilibrium with [`FallbackParams::warm_start`]
/// (D13). Every accepted step decreases `Phi`, so the returned rest shape is never
/// worse than the start; `progress` is called after every accepted step and stops the
/// optimisation when it returns `false` (the best rest shape so far is kept).
///
/// # Errors
/// An invalid parameter, and those of [`ShapeObjective::evaluate`]. A start with no forward
/// equilibrium is not an error: [`FallbackInfo::stopped`] is [`FallbackStop::NoEquilibrium`].
pub fn optimise_rest_shape(
    problem: &DesignProblem,
    params: &FallbackParams,
    forward: &StaticParams,
    rest: &mut [f64],
    mut progress: impl FnMut(&FallbackProgress) -> bool,
) -> Result<FallbackInfo, DesignError> {
    params.validate()?;
    if rest.len() != problem.num_dofs() {
        return Err(DesignError::InvalidParameter {
            name: "rest",
            value: rest.len() as f64,
            allowed: "three coordinates per target vertex",
        });
    }
    let started = std::time::Instant::now();
    let tolerance = params.forward_tolerance.unwrap_or(forward.tolerance);
    let mut objective = ShapeObjective::new(problem, forward, tolerance)?;
    objective.set_warm_start(params.warm_start);
    let mut info = FallbackInfo {
        iterations: 0,
        forward_solves: 0,
        start: None,
        end: None,
        objective_start: f64::NAN,
        objective_end: f64::NAN,
        gradient_reduction: f64::NAN,
        stopped: FallbackStop::NoEquilibrium,
        seconds: 0.0,
    };
    let Some(first) = objective.evaluate(rest, true)? else {
        info.forward_solves = objective.forward_solves();
        info.seconds = started.elapsed().as_secs_f64();
        return Ok(info);
    };
    let beta = params.tangential_weight;
    let projectors = crate::inverse::tangential_weights(problem);
    let reference = rest.to_vec();
    let max_step = params.max_move * crate::inverse::mean_edge(problem);
    // Phi and its gradient from an evaluation.
    let total = |x: &[f64], e: &Evaluation| -> (f64, Vec<f64>) {
        let mut phi = e.objective;
        let mut g = e.gradient.clone().unwrap_or_default();
        if beta > 0.0 {
            for (v, p) in projectors.iter().enumerate() {
                let d = point(x, v) - point(&reference, v);
                let pd = p * d;
                phi += 0.5 * beta * d.dot(&pd);
                for k in 0..3 {
                    g[3 * v + k] += beta * pd[k];
                }
            }
        }
        (phi, g)
    };
    let (mut phi, mut g) = total(rest, &first);
    let g0 = dot(&g, &g).sqrt();
    info.start = Some(first.distance);
    info.end = Some(first.distance);
    info.objective_start = first.objective;
    info.objective_end = first.objective;
    info.gradient_reduction = 1.0;
    let mut memory: std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)> =
        std::collections::VecDeque::new();
    let mut trial = rest.to_vec();
    let mut current = first;
    info.stopped = FallbackStop::Iterations;
    loop {
        if current.distance.max_relative <= params.distance_tolerance {
            info.stopped = FallbackStop::Distance;
            break;
        }
        let gn = dot(&g, &g).sqrt();
        if gn <= params.gradient_tolerance * g0 || gn == 0.0 {
            info.stopped = FallbackStop::Gradient;
            break;
        }
        if info.iterations >= params.max_iterations {
            info.stopped = FallbackStop::Iterations;
            break;
        }
        // L-BFGS two-loop recursion: d = -H g.
        let mut d: Vec<f64> = g.iter().map(|v| -v).collect();
        let mut alphas = Vec::with_capacity(memory.len());
        for (s, y, rho) in memory.iter().rev() {
            let a = rho * dot(s, &d);
            for (di, yi) in d.iter_mut().zip(y) {
                *di -= a * yi;
            }
            alphas.push(a);
        }
        if let Some((s, y, _)) = memory.back() {
            let gamma = dot(s, y) / dot(y, y);
            for di in d.iter_mut() {
                *di *= gamma;
            }
        }
        for ((s, y, rho), a) in memory.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &d);
            for (di, si) in d.iter_mut().zip(s) {
                *di += (a - b) * si;
            }
        }
        let mut slope = dot(&g, &d);
        if slope.is_nan() || slope >= 0.0 {
            memory.clear();
            d = g.iter().map(|v| -v).collect();
            slope = -gn * gn;
        }
        // The first step (no curvature pairs yet) and any long one: at most `max_step` per
        // vertex.
        let largest = d
            .chunks(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .fold(0.0, f64::max);
        let mut t = if memory.is_empty() || largest > max_step {
            max_step / largest
        } else {
            1.0
        };
        let kept = objective.equilibrium().map(<[f64]>::to_vec);
        let mut accepted = None;
        for _ in 0..12 {
            for ((y, x), di) in trial.iter_mut().zip(rest.iter()).zip(&d) {
                *y = x + t * di;
            }
            objective.set_equilibrium(kept.clone());
            if let Some(e) = objective.evaluate(&trial, true)? {
                let (phi_t, g_t) = total(&trial, &e);
                if phi_t <= phi + 1e-4 * t * slope {
                    accepted = Some((e, phi_t, g_t));
                    break;
                }
            }
            t *= 0.5;
        }
        let Some((e, phi_t, g_t)) = accepted else {
            objective.set_equilibrium(kept);
            info.stopped = FallbackStop::LineSearch;
            break;
        };
        let s: Vec<f64> = trial.iter().zip(rest.iter()).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g_t.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&s, &s).sqrt() * dot(&y, &y).sqrt() {
            if memory.len() == params.memory {
                memory.pop_front();
            }
            memory.push_back((s, y, 1.0 / sy));
        }
        rest.copy_from_slice(&trial);
        phi = phi_t;
        g = g_t;
        current = e;
        info.iterations += 1;
        info.end = Some(current.distance);
        info.objective_end = current.objective;
        info.gradient_reduction = dot(&g, &g).sqrt() / g0;
        let report = FallbackProgress {
            iteration: info.iterations,
            objective: current.objective,
            max_distance: current.distance.max,
            rms_distance: current.distance.rms,
        };
        if !progress(&report) {
            info.stopped = FallbackStop::Interrupted;
            break;
        }
    }
    info.forward_solves = objective.forward_solves();
    info.seconds = started.elapsed().as_secs_f64();
    Ok(info)
}
