//! The shape-optimisation fallback where the inverse has no exact answer: the rest shape `X`
//! that minimises the distance of its forward static equilibrium `x(X)` to the target,
//! with the exact adjoint gradient through the static solve and a Gauss-Newton outer loop on
//! the exact sensitivity `dx/dX` (L-BFGS where a Gauss-Newton step fails, or throughout on
//! request) (`docs/design.md`, D11-D15).

use balloon_integrate::newton::cancel_requested;
use balloon_integrate::statics::StaticParams;
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::bending_term::BendingTerm;
use crate::forward::Distance;
use crate::gauss_newton::{conjugate_gradient, dot, lbfgs_direction};
use crate::objective::{Evaluation, ShapeObjective};
use crate::problem::{DesignProblem, point};
use crate::shape_term::ShapeTerm;

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

/// The outer loop of [`optimise_rest_shape`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FallbackMethod {
    /// Levenberg-Marquardt-damped Gauss-Newton steps on the exact sensitivity `dx/dX` of the
    /// equilibrium, solved matrix-free by conjugate gradients (`"gauss-newton"`, default;
    /// `docs/design.md`, D15); an iteration whose Gauss-Newton steps all fail takes an L-BFGS
    /// step instead.
    #[default]
    GaussNewton,
    /// L-BFGS on the adjoint gradient alone (`"lbfgs"`; D13).
    Lbfgs,
}

/// Parameters of [`optimise_rest_shape`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FallbackParams {
    /// When [`crate::design`] runs it (default [`FallbackMode::Unconverged`]).
    pub mode: FallbackMode,
    /// The outer loop (default [`FallbackMethod::GaussNewton`]).
    pub method: FallbackMethod,
    /// Accepted steps (default 60; each costs at least one forward static solve, more when a
    /// trial is refused).
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
    /// Weight `gamma_0` of the rest-mesh shape term (`docs/design.md`, D16; default 0: off):
    /// the conformal energy `gamma/2 l^2 sum_t (a_t / mean a) |r_t|^2` of the rest triangles
    /// against the target's (each free in rotation and uniform scale), added to the distance
    /// in stages `gamma_k = gamma_0 0.1^k`, `k < shape_stages`, each from the last, and then a
    /// last stage without it, so the result is not biased by it.
    #[serde(default)]
    pub shape_weight: f64,
    /// Weight `kappa_0` of the rest-mesh bending term (`docs/design.md`, D17; default 0: off):
    /// the hinge energy `kappa/2 l^2 sum_e (w_e / mean w) (theta_e(X) - theta_e(x*))^2` of the
    /// rest mesh's dihedral angles against the target's (Grinspun et al. 2003), which resists
    /// the bendings of the rest mesh that the equilibrium hardly sees, in the same stages as
    /// the shape term (`kappa_k = kappa_0 0.1^k`, `k < shape_stages`, then a last stage
    /// without either).
    #[serde(default)]
    pub bending_weight: f64,
    /// Stages with the shape or bending term (default 3), each at most
    /// [`FallbackParams::max_iterations`] steps; unused when [`FallbackParams::shape_weight`]
    /// and [`FallbackParams::bending_weight`] are 0.
    #[serde(default = "default_shape_stages")]
    pub shape_stages: usize,
    /// Hand the optimised rest shape to the inverse's Newton solve at the full pressure
    /// ([`crate::design_rest_shape`] without continuation, at most
    /// [`NEWTON_POLISH_ITERATIONS`] iterations) and keep its answer when it converges and its
    /// forward equilibrium is closer to the target (default `false`).
    #[serde(default)]
    pub newton_polish: bool,
}

fn default_shape_stages() -> usize {
    3
}

/// Iterations of the inverse solve started from the optimised rest shape
/// ([`FallbackParams::newton_polish`]).
pub const NEWTON_POLISH_ITERATIONS: usize = 30;

impl Default for FallbackParams {
    fn default() -> Self {
        Self {
            mode: FallbackMode::Unconverged,
            method: FallbackMethod::GaussNewton,
            max_iterations: 60,
            memory: 8,
            gradient_tolerance: 1e-6,
            distance_tolerance: 1e-8,
            tangential_weight: 0.0,
            forward_tolerance: None,
            max_move: 0.25,
            warm_start: false,
            shape_weight: 0.0,
            bending_weight: 0.0,
            shape_stages: default_shape_stages(),
            newton_polish: false,
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
            ("shape_weight", self.shape_weight, self.shape_weight >= 0.0),
            (
                "bending_weight",
                self.bending_weight,
                self.bending_weight >= 0.0,
            ),
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
    /// No step decreased the objective (neither the Gauss-Newton trials nor the L-BFGS line
    /// search, or every trial's forward solve failed): the best rest shape so far is kept.
    LineSearch,
    /// The progress callback asked to stop (Ctrl-C), or a forward solve stopped because the
    /// process asked its solves to stop (`balloon_integrate::newton::cancel_requested`).
    Interrupted,
    /// The forward static solve from the start rest shape found no equilibrium: nothing to
    /// optimise (the start is kept).
    NoEquilibrium,
}

/// What [`optimise_rest_shape`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FallbackInfo {
    /// Accepted steps (Gauss-Newton and L-BFGS).
    pub iterations: usize,
    /// Of those, the Gauss-Newton steps (absent in older summaries: 0).
    #[serde(default)]
    pub gauss_newton_steps: usize,
    /// Conjugate-gradient iterations of the Gauss-Newton steps, refused trials included
    /// (each one product with the damped Gauss-Newton matrix: two sparse triangular solve
    /// pairs with the forward stiffness's factor and two rest-Jacobian products).
    #[serde(default)]
    pub cg_iterations: usize,
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
    /// Stages run with the shape or bending term ([`FallbackParams::shape_weight`],
    /// [`FallbackParams::bending_weight`]; the last, unweighted stage
    /// not counted).
    #[serde(default)]
    pub shape_stages: usize,
    /// Whether the inverse's Newton solve from the optimised rest shape converged and its
    /// answer was kept ([`FallbackParams::newton_polish`]).
    #[serde(default)]
    pub polished: bool,
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
    problem.check_length("rest", rest)?;
    let started = std::time::Instant::now();
    let tolerance = params.forward_tolerance.unwrap_or(forward.tolerance);
    let mut objective = ShapeObjective::new(problem, forward, tolerance)?;
    objective.set_warm_start(params.warm_start);
    let mut info = FallbackInfo {
        iterations: 0,
        gauss_newton_steps: 0,
        cg_iterations: 0,
        forward_solves: 0,
        start: None,
        end: None,
        objective_start: f64::NAN,
        objective_end: f64::NAN,
        gradient_reduction: f64::NAN,
        stopped: FallbackStop::NoEquilibrium,
        seconds: 0.0,
        shape_stages: 0,
        polished: false,
    };
    let Some(first) = objective.evaluate(rest, true)? else {
        if cancel_requested() {
            info.stopped = FallbackStop::Interrupted;
        }
        info.forward_solves = objective.forward_solves();
        info.seconds = started.elapsed().as_secs_f64();
        return Ok(info);
    };
    let beta = params.tangential_weight;
    let projectors = crate::inverse::tangential_weights(problem);
    let reference = rest.to_vec();
    let max_step = params.max_move * problem.mean_edge_length();
    let shape = (params.shape_weight > 0.0).then(|| ShapeTerm::new(problem));
    let bending = (params.bending_weight > 0.0).then(|| BendingTerm::new(problem));
    info.start = Some(first.distance);
    info.end = Some(first.distance);
    info.objective_start = first.objective;
    info.objective_end = first.objective;
    info.gradient_reduction = 1.0;
    let mut trial = rest.to_vec();
    let mut current = first;
    let stages = if shape.is_some() || bending.is_some() {
        params.shape_stages + 1
    } else {
        1
    };
    let mut done = false;
    for stage in 0..stages {
        // gamma_k = gamma_0 0.1^k, the last stage without the shape term (D16).
        let (gamma, kappa) = if stage + 1 < stages {
            (
                crate::stage_weight(params.shape_weight, stage),
                crate::stage_weight(params.bending_weight, stage),
            )
        } else {
            (0.0, 0.0)
        };
        // The regulariser's value and gradient at `x`, and its (Gauss-Newton) product at
        // `x` with `v`.
        let regulariser = |x: &[f64]| -> (f64, Vec<f64>) {
            let mut phi = 0.0;
            let mut g = vec![0.0; x.len()];
            if beta > 0.0 {
                for (v, p) in projectors.iter().enumerate() {
                    let d = point(x, v) - point(&reference, v);
                    let pd = p * d;
                    phi += 0.5 * beta * d.dot(&pd);
                    g[3 * v..3 * v + 3].copy_from_slice((pd * beta).as_slice());
                }
            }
            if let (Some(term), true) = (&shape, gamma > 0.0) {
                let (s, gs) = term.value_gradient(x);
                phi += gamma * s;
                for (a, b) in g.iter_mut().zip(gs) {
                    *a += gamma * b;
                }
            }
            if let (Some(term), true) = (&bending, kappa > 0.0) {
                let (s, gs) = term.value_gradient(x);
                phi += kappa * s;
                for (a, b) in g.iter_mut().zip(gs) {
                    *a += kappa * b;
                }
            }
            (phi, g)
        };
        let regulariser_product = |x: &[f64], u: &[f64]| -> Vec<f64> {
            let mut out = vec![0.0; u.len()];
            if beta > 0.0 {
                for (v, p) in projectors.iter().enumerate() {
                    out[3 * v..3 * v + 3].copy_from_slice((p * point(u, v) * beta).as_slice());
                }
            }
            if let (Some(term), true) = (&shape, gamma > 0.0) {
                for (a, b) in out.iter_mut().zip(term.gauss_newton_product(x, u)) {
                    *a += gamma * b;
                }
            }
            if let (Some(term), true) = (&bending, kappa > 0.0) {
                for (a, b) in out.iter_mut().zip(term.gauss_newton_product(x, u)) {
                    *a += kappa * b;
                }
            }
            out
        };
        let (mut phi, mut g) = total(&regulariser, rest, &current);
        let g0 = dot(&g, &g).sqrt();
        let mut memory: std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)> =
            std::collections::VecDeque::new();
        let mut damping = GaussNewtonDamping::default();
        let mut steps = 0;
        if gamma > 0.0 || kappa > 0.0 {
            info.shape_stages += 1;
        }
        info.stopped = FallbackStop::Iterations;
        loop {
            if current.distance.max_relative <= params.distance_tolerance {
                info.stopped = FallbackStop::Distance;
                done = true;
                break;
            }
            let gn = dot(&g, &g).sqrt();
            if gn <= params.gradient_tolerance * g0 || gn == 0.0 {
                info.stopped = FallbackStop::Gradient;
                break;
            }
            if steps >= params.max_iterations {
                info.stopped = FallbackStop::Iterations;
                break;
            }
            let step = Step {
                rest,
                gradient: &g,
                phi,
                max_step,
                regulariser: &regulariser,
                regulariser_product: &regulariser_product,
            };
            let mut accepted = None;
            if params.method == FallbackMethod::GaussNewton {
                accepted =
                    step.gauss_newton(&mut objective, &mut damping, &mut info, &mut trial)?;
                if accepted.is_some() {
                    info.gauss_newton_steps += 1;
                }
            }
            if accepted.is_none() {
                accepted = step.lbfgs(&mut objective, &mut memory, &mut trial)?;
            }
            let Some((e, phi_t, g_t)) = accepted else {
                // A stop asked for (Ctrl-C) fails every forward solve of the trials: that is
                // an interruption, not a failed search.
                if cancel_requested() {
                    info.stopped = FallbackStop::Interrupted;
                    done = true;
                } else {
                    info.stopped = FallbackStop::LineSearch;
                }
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
            steps += 1;
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
                done = true;
                break;
            }
        }
        if done {
            break;
        }
    }
    if params.newton_polish && info.stopped != FallbackStop::Interrupted {
        // The inverse's Newton solve at the full pressure from the optimised rest shape: its
        // basin is narrow, so it is tried only here (D16).
        let mut polished = rest.to_vec();
        let inverse = crate::design_rest_shape(
            problem,
            &crate::InverseParams {
                max_iterations: NEWTON_POLISH_ITERATIONS,
                max_halvings: 0,
                ..crate::InverseParams::default()
            },
            &mut polished,
            |_| true,
        )?;
        if inverse.converged {
            objective.set_equilibrium(None);
            if let Some(e) = objective.evaluate(&polished, false)?
                && e.distance.max <= current.distance.max
            {
                rest.copy_from_slice(&polished);
                info.polished = true;
                info.end = Some(e.distance);
                info.objective_end = e.objective;
            }
        }
    }
    info.forward_solves = objective.forward_solves();
    info.seconds = started.elapsed().as_secs_f64();
    Ok(info)
}

/// The regularisers' value and gradient at a rest shape.
type Regulariser<'a> = dyn Fn(&[f64]) -> (f64, Vec<f64>) + 'a;

/// The regularisers' (Gauss-Newton) matrix at a rest shape times a direction.
type RegulariserProduct<'a> = dyn Fn(&[f64], &[f64]) -> Vec<f64> + 'a;

/// Phi and its gradient from an evaluation with the gradient.
fn total(regulariser: &Regulariser<'_>, x: &[f64], e: &Evaluation) -> (f64, Vec<f64>) {
    let (mut phi, mut g) = regulariser(x);
    phi += e.objective;
    for (a, b) in g.iter_mut().zip(e.gradient.as_deref().unwrap_or_default()) {
        *a += b;
    }
    (phi, g)
}

/// The largest vertex move of the step `d`.
fn largest_move(d: &[f64]) -> f64 {
    d.chunks(3)
        .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
        .fold(0.0, f64::max)
}

/// Relative tolerance of the conjugate-gradient solve of a Gauss-Newton step.
const CG_TOLERANCE: f64 = 1e-4;
/// Its iteration limit (the truncation regularises the weakly determined directions too).
const CG_ITERATIONS: usize = 200;
/// Refused Gauss-Newton trials (each one forward solve) before the L-BFGS step is tried.
const GN_TRIALS: usize = 4;

/// The Levenberg-Marquardt damping of the Gauss-Newton steps, `mu = factor scale`, `scale`
/// the Gauss-Newton matrix's Rayleigh quotient along the first gradient.
struct GaussNewtonDamping {
    factor: f64,
    scale: Option<f64>,
}

impl Default for GaussNewtonDamping {
    fn default() -> Self {
        Self {
            factor: 1e-3,
            scale: None,
        }
    }
}

/// One outer step from the rest shape `rest` with the objective `phi` and its gradient.
struct Step<'c> {
    rest: &'c [f64],
    gradient: &'c [f64],
    phi: f64,
    max_step: f64,
    regulariser: &'c Regulariser<'c>,
    regulariser_product: &'c RegulariserProduct<'c>,
}

/// An accepted step: the evaluation at the new rest shape (in `trial`), `Phi` and its
/// gradient there.
type Accepted = Option<(Evaluation, f64, Vec<f64>)>;

impl Step<'_> {
    /// The Levenberg-Marquardt-damped Gauss-Newton step (D15): `(S^T R^T W P R S + beta T +
    /// mu I) dX = -grad Phi` by conjugate gradients, at most `max_step` per vertex, accepted on
    /// the same sufficient decrease of the true `Phi` as the L-BFGS line search; a refused
    /// trial multiplies `mu` by 4 and solves again, an accepted one divides it by 3. `None`
    /// when every trial was refused or the linear solve failed (the kept equilibrium is
    /// restored).
    fn gauss_newton(
        &self,
        objective: &mut ShapeObjective<'_>,
        damping: &mut GaussNewtonDamping,
        info: &mut FallbackInfo,
        trial: &mut [f64],
    ) -> Result<Accepted, DesignError> {
        let g = self.gradient;
        let product = |objective: &ShapeObjective<'_>, v: &[f64], mu: f64| -> Option<Vec<f64>> {
            let mut a = objective.gauss_newton_product(v).ok()?;
            for ((a, t), v) in a
                .iter_mut()
                .zip((self.regulariser_product)(self.rest, v))
                .zip(v)
            {
                *a += t + mu * v;
            }
            Some(a)
        };
        let scale = match damping.scale {
            Some(s) => s,
            None => {
                let Some(ag) = product(objective, g, 0.0) else {
                    return Ok(None);
                };
                let s = dot(g, &ag) / dot(g, g);
                if !(s.is_finite() && s > 0.0) {
                    return Ok(None);
                }
                *damping.scale.insert(s)
            }
        };
        let b: Vec<f64> = g.iter().map(|v| -v).collect();
        let kept = objective.equilibrium().map(<[f64]>::to_vec);
        for _ in 0..GN_TRIALS {
            let mu = damping.factor * scale;
            let Some((mut d, iterations)) = conjugate_gradient(
                |v| product(objective, v, mu),
                &b,
                CG_TOLERANCE,
                CG_ITERATIONS,
            ) else {
                break;
            };
            info.cg_iterations += iterations;
            let largest = largest_move(&d);
            let cut = largest > self.max_step;
            if cut {
                for v in &mut d {
                    *v *= self.max_step / largest;
                }
            }
            let slope = dot(g, &d);
            if slope.is_nan() || slope >= 0.0 {
                break;
            }
            for ((y, x), di) in trial.iter_mut().zip(self.rest).zip(&d) {
                *y = x + di;
            }
            objective.set_equilibrium(kept.clone());
            if let Some(e) = objective.evaluate(trial, false)? {
                let phi_t = e.objective + (self.regulariser)(trial).0;
                if phi_t <= self.phi + 1e-4 * slope {
                    let Some(e) = objective.linearise_kept(trial)? else {
                        break;
                    };
                    if !cut {
                        damping.factor = (damping.factor / 3.0).max(1e-9);
                    }
                    let (phi_t, g_t) = total(self.regulariser, trial, &e);
                    return Ok(Some((e, phi_t, g_t)));
                }
            }
            damping.factor *= 4.0;
        }
        objective.set_equilibrium(kept);
        Ok(None)
    }

    /// The L-BFGS step (D13): two-loop recursion on the pairs `memory`, backtracking Armijo
    /// line search, at most `max_step` per vertex. `None` when no trial decreased `Phi` (the
    /// kept equilibrium is restored).
    fn lbfgs(
        &self,
        objective: &mut ShapeObjective<'_>,
        memory: &mut std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)>,
        trial: &mut [f64],
    ) -> Result<Accepted, DesignError> {
        let g = self.gradient;
        let gn = dot(g, g).sqrt();
        let mut d = lbfgs_direction(memory, g);
        let mut slope = dot(g, &d);
        if slope.is_nan() || slope >= 0.0 {
            memory.clear();
            d = g.iter().map(|v| -v).collect();
            slope = -gn * gn;
        }
        // The first step (no curvature pairs yet) and any long one: at most `max_step` per
        // vertex.
        let largest = largest_move(&d);
        let mut t = if memory.is_empty() || largest > self.max_step {
            self.max_step / largest
        } else {
            1.0
        };
        let kept = objective.equilibrium().map(<[f64]>::to_vec);
        for _ in 0..12 {
            for ((y, x), di) in trial.iter_mut().zip(self.rest).zip(&d) {
                *y = x + t * di;
            }
            objective.set_equilibrium(kept.clone());
            if let Some(e) = objective.evaluate(trial, true)? {
                let (phi_t, g_t) = total(self.regulariser, trial, &e);
                if phi_t <= self.phi + 1e-4 * t * slope {
                    return Ok(Some((e, phi_t, g_t)));
                }
            }
            t *= 0.5;
        }
        objective.set_equilibrium(kept);
        Ok(None)
    }
}
