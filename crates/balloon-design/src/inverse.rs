//! The inverse-statics solve: Levenberg-Marquardt (regularised Gauss-Newton) on the rest
//! positions with the exact Jacobian, under pressure continuation (`docs/design.md`).

use balloon_linalg::SparseCholesky;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::normal::NormalPattern;
use crate::pinned::PinnedLu;
use crate::problem::DesignProblem;

/// Parameters of [`design_rest_shape`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InverseParams {
    /// Relative residual `|r| / |p g|` at which the full-pressure stage stops (default `1e-9`).
    pub tolerance: f64,
    /// Relative residual at which an intermediate continuation stage stops (default `1e-4`).
    pub stage_tolerance: f64,
    /// Gauss-Newton iterations allowed per stage (default 60).
    pub max_iterations: usize,
    /// Halvings of the pressure increment before the solve gives up (default 12).
    pub max_halvings: usize,
    /// First Levenberg-Marquardt damping relative to the mean diagonal of `J^T J` (default
    /// `1e-6`).
    pub initial_damping: f64,
    /// Weight `beta` of the tangential regulariser relative to the mean diagonal of `J^T J`
    /// (default `0`): the term `beta/2 sum_v a_v |(I - n_v n_v^T)(X_v - X_v^ref)|^2`, `n_v` the
    /// target's vertex normal, `a_v` its vertex area over the mean, `X^ref` the rest shape at
    /// the start of the stage. Zero keeps the design exact; a positive value keeps the rest
    /// mesh's tangential spacing close to the target's where the equations leave it free (flat
    /// regions) at the price of a residual of order `beta`.
    pub tangential_weight: f64,
    /// Geodesic acceleration of the Levenberg-Marquardt steps (default `true`; Transtrum and
    /// Sethna 2012): one more residual evaluation and back-substitution per step, for fewer
    /// steps where the near-isometric motions of the rest mesh curve the valleys of `|r|^2`.
    pub acceleration: bool,
    /// Newton steps on the square system `r(X) = 0` with a sparse LU factorisation of `J`
    /// bordered by the rigid motions (default `true`; `docs/design.md`, D10), each accepted
    /// when a backtracking line search decreases `|r|^2`; a refused or singular step falls
    /// back to one Levenberg-Marquardt step. Used only when `tangential_weight` is zero (the
    /// tangential term makes the problem a least-squares one).
    pub newton: bool,
    /// Weight `kappa_0` of the rest-mesh bending term in the inverse solve relative to the
    /// mean diagonal of `J^T J` (`docs/design.md`, D17; default `0`: off). When positive the
    /// solve first runs the pressure continuation on the regularised least-squares problem
    /// `|r|^2/2 + kappa m/2 sum_e w_e (theta_e(X) - theta_e(x*))^2` (Levenberg-Marquardt, no
    /// Newton steps; a stage ends when a step decreases the objective by less than `1e-8` of
    /// it), then repeats it at the full pressure with `kappa_k = kappa_0 0.1^k`,
    /// `k < bending_stages`, and ends with the unregularised solve (Newton steps as usual)
    /// from the result, so that an exact design is not biased by the term.
    #[serde(default)]
    pub bending_weight: f64,
    /// Stages with the bending term (default 3); unused when `bending_weight` is 0.
    #[serde(default = "default_bending_stages")]
    pub bending_stages: usize,
}

fn default_bending_stages() -> usize {
    3
}

impl Default for InverseParams {
    fn default() -> Self {
        Self {
            tolerance: 1e-9,
            stage_tolerance: 1e-4,
            max_iterations: 60,
            max_halvings: 12,
            initial_damping: 1e-6,
            tangential_weight: 0.0,
            acceleration: true,
            newton: true,
            bending_weight: 0.0,
            bending_stages: default_bending_stages(),
        }
    }
}

impl InverseParams {
    /// Checks every parameter; the error names the first one out of range.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), DesignError> {
        for (name, value, ok) in [
            ("tolerance", self.tolerance, self.tolerance > 0.0),
            (
                "stage_tolerance",
                self.stage_tolerance,
                self.stage_tolerance > 0.0,
            ),
            (
                "initial_damping",
                self.initial_damping,
                self.initial_damping > 0.0,
            ),
            (
                "tangential_weight",
                self.tangential_weight,
                self.tangential_weight >= 0.0,
            ),
            (
                "bending_weight",
                self.bending_weight,
                self.bending_weight >= 0.0,
            ),
            (
                "max_iterations",
                self.max_iterations as f64,
                self.max_iterations > 0,
            ),
        ] {
            if !(value.is_finite() && ok) {
                return Err(DesignError::InvalidParameter {
                    name,
                    value,
                    allowed: "a finite value in range (see InverseParams)",
                });
            }
        }
        Ok(())
    }
}

/// What [`design_rest_shape`] found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InverseInfo {
    /// Whether the full pressure was reached with the residual below the tolerance.
    pub converged: bool,
    /// The load factor reached (1 = the full pressure).
    pub load_reached: f64,
    /// `|r| / |p g|` at the end.
    pub relative_residual: f64,
    /// Iterations (Newton and Levenberg-Marquardt), all stages.
    pub iterations: usize,
    /// Of those, Levenberg-Marquardt steps taken because a Newton step was refused or
    /// singular (all of them when [`InverseParams::newton`] is off). Named `fallback_steps`
    /// before the shape optimisation ([`InverseInfo::fallback`]) took that word; older
    /// summaries are still read.
    #[serde(default, alias = "fallback_steps")]
    pub damped_steps: usize,
    /// Continuation stages solved.
    pub stages: usize,
    /// Halvings of the pressure increment.
    pub halvings: usize,
    /// Whether the continuation ended before its halvings ran out because halving the
    /// increment did not make a failed stage easier: three failed stages in a row from the same
    /// rest shape each left at least half the share of its residual that the one before left
    /// (`docs/design.md`, "The solve and the regulariser").
    #[serde(default)]
    pub no_easier: bool,
    /// Whether the rest shape kept is a failed stage at the full pressure, not the last
    /// converged stage: it ended with a smaller residual at the full pressure.
    #[serde(default)]
    pub full_attempt_kept: bool,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// The shape optimisation that followed (`None` when it did not run): its distances
    /// before and after, iterations and why it stopped ([`crate::design`]).
    #[serde(default)]
    pub fallback: Option<crate::FallbackInfo>,
}

/// Progress of a design, reported after every accepted iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseProgress {
    /// The stage's load factor (the one being solved for).
    pub load: f64,
    /// The load factor of the last converged stage (0 before the first).
    pub reached: f64,
    /// The relative residual.
    pub relative_residual: f64,
    /// Iterations so far.
    pub iterations: usize,
}

struct Solver<'a> {
    problem: &'a DesignProblem,
    params: InverseParams,
    scale: f64,
    /// Tangential projectors times vertex area weights (`docs/design.md`, D11), per vertex.
    tangential: Vec<nalgebra::Matrix3<f64>>,
    chol: SparseCholesky,
    /// The bordered Newton matrix and its LU factor.
    lu: PinnedLu,
    /// The fixed layout of `J` and `J^T J`.
    pattern: NormalPattern,
    damping: f64,
    /// The target's mean edge length (m).
    edge: f64,
    /// Damped steps still to take before the next Newton step.
    newton_wait: usize,
    /// Damped steps taken after the last refused Newton step (doubles per refusal in a row).
    newton_backoff: usize,
    /// The bending term of D17 and its weight relative to the mean diagonal of `J^T J`
    /// (`None` or 0: off).
    bending: Option<(crate::bending_term::BendingTerm, f64)>,
}

/// Finds the rest shape `X` whose static equilibrium under the problem's pressure is the
/// target, starting from `start` (flat, m; the target itself is the natural start: it is the
/// exact answer at zero pressure), and overwrites `start` with it.
///
/// The pressure is applied in full first and, when a stage does not converge, in increments
/// halved as needed (a continuation from the zero-pressure answer `X = x*`). Each stage runs
/// Levenberg-Marquardt on `|r(X)|^2 / 2` with the exact Jacobian (`docs/design.md`). The
/// continuation ends early when halving does not make a failed stage easier
/// ([`InverseInfo::no_easier`]). On return `start` holds the last converged stage's rest
/// shape, or the end of a failed stage at the full pressure when that one is nearer its
/// equilibrium ([`InverseInfo::full_attempt_kept`]); `progress` is called after every accepted
/// iteration and stops the solve when it returns `false` (the best shape so far is kept).
///
/// # Errors
/// An invalid parameter, a linear solve that fails outright. Non-convergence is not an error:
/// [`InverseInfo::converged`] is `false` and [`InverseInfo::load_reached`] says how far it got.
pub fn design_rest_shape(
    problem: &DesignProblem,
    params: &InverseParams,
    start: &mut [f64],
    mut progress: impl FnMut(&InverseProgress) -> bool,
) -> Result<InverseInfo, DesignError> {
    params.validate()?;
    problem.check_length("start", start)?;
    let started = std::time::Instant::now();
    let scale = norm(problem.pressure_forces());
    let pattern = problem.pattern();
    let mut solver = Solver {
        problem,
        params: *params,
        scale,
        tangential: tangential_weights(problem),
        chol: SparseCholesky::new(),
        lu: PinnedLu::new(&pattern, problem.target()),
        pattern,
        damping: params.initial_damping,
        edge: problem.mean_edge_length(),
        newton_wait: 0,
        newton_backoff: 0,
        bending: None,
    };
    let mut info = InverseInfo {
        converged: false,
        load_reached: 0.0,
        relative_residual: f64::INFINITY,
        iterations: 0,
        damped_steps: 0,
        stages: 0,
        halvings: 0,
        no_easier: false,
        full_attempt_kept: false,
        seconds: 0.0,
        fallback: None,
    };
    let mut stopped = false;
    let mut load;
    if params.bending_weight > 0.0 {
        // D17: the regularised continuation, then the full pressure with smaller weights.
        let term = crate::bending_term::BendingTerm::new(problem);
        solver.bending = Some((term, params.bending_weight));
        load = solver.continuation(start, 0.0, &mut info, &mut stopped, &mut progress)?;
        for k in 1..params.bending_stages {
            if stopped || load < 1.0 {
                break;
            }
            if let Some((_, kappa)) = solver.bending.as_mut() {
                *kappa = crate::stage_weight(params.bending_weight, k);
            }
            solver.damping = params.initial_damping;
            let mut trial = start.to_vec();
            match solver.stage(
                &mut trial,
                1.0,
                params.stage_tolerance,
                &mut info,
                &mut progress,
            )? {
                Stage::Converged(_) => start.copy_from_slice(&trial),
                Stage::Stopped => stopped = true,
                Stage::Failed { .. } => break,
            }
        }
        solver.bending = None;
        solver.damping = params.initial_damping;
        if !stopped && load >= 1.0 {
            // The unregularised solve at the full pressure from the regularised design.
            let mut trial = start.to_vec();
            match solver.stage(&mut trial, 1.0, params.tolerance, &mut info, &mut progress)? {
                Stage::Converged(res) => {
                    start.copy_from_slice(&trial);
                    info.stages += 1;
                    info.relative_residual = res;
                }
                Stage::Stopped | Stage::Failed { .. } => {}
            }
            if info.relative_residual > params.tolerance {
                info.relative_residual = match problem.residual(start, 1.0) {
                    Ok(r) => norm(&r) / scale,
                    Err(_) => f64::INFINITY,
                };
            }
        } else if !stopped {
            // The regularised continuation stalled: the unregularised one from there.
            load = solver.continuation(start, load, &mut info, &mut stopped, &mut progress)?;
        }
    } else {
        load = solver.continuation(start, 0.0, &mut info, &mut stopped, &mut progress)?;
    }
    if load < 1.0 {
        // Report the residual of the kept shape at the full pressure.
        info.relative_residual = match problem.residual(start, 1.0) {
            Ok(r) => norm(&r) / scale,
            Err(_) => f64::INFINITY,
        };
    }
    info.converged = load >= 1.0 && info.relative_residual <= params.tolerance;
    info.seconds = started.elapsed().as_secs_f64();
    Ok(info)
}

/// Step halvings of a Newton step's line search before it falls back to Levenberg-Marquardt.
const NEWTON_BACKTRACKS: usize = 4;

/// Newton steps are tried only below this relative residual: from farther away a full Newton
/// step on a fine mesh lands on another root of `r(X) = 0` (rest vertices popped through their
/// neighbours' plane leave every edge length, hence every force, unchanged) or far off along
/// the near-isometric motions of the rest mesh (`docs/design.md`).
const NEWTON_RESIDUAL: f64 = 1e-2;

/// Largest vertex displacement of a Newton step, over the target's mean edge length.
const NEWTON_MAX_MOVE: f64 = 0.1;

/// Most damped steps taken after refused Newton steps before the next Newton step is tried.
const NEWTON_MAX_WAIT: usize = 16;

enum Stage {
    Converged(f64),
    /// Not converged within the stage's iterations.
    Failed {
        /// The residual at the end over the one at the start of the stage (`None` when the
        /// stage could not be evaluated).
        share: Option<f64>,
        /// The relative residual at the end (infinite when the stage could not be evaluated).
        residual: f64,
    },
    Stopped,
}

/// Failed stages in a row, each from the same converged rest shape with half the increment of
/// the one before, after which the continuation ends when none of them made the stage easier.
const HOPELESS_FAILURES: usize = 3;

/// A halved stage is "no easier" when the share of its residual left at its end is at least
/// this fraction of the share the stage before it left.
const NO_EASIER: f64 = 0.5;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// The relative equilibrium residual `|r(X)| / |p g|` of the rest shape `rest` at the full
/// load: the measure [`design_rest_shape`] stops on ([`InverseParams::tolerance`]); 0 when
/// `rest` holds the target exactly.
///
/// # Errors
/// [`DesignError::InvalidParameter`] for a `rest` of the wrong length, and
/// [`DesignError::RestElement`] for a degenerate rest triangle.
pub fn relative_residual(problem: &DesignProblem, rest: &[f64]) -> Result<f64, DesignError> {
    let scale = norm(problem.pressure_forces());
    Ok(norm(&problem.residual(rest, 1.0)?) / scale)
}

/// Per vertex `a_v (I - n_v n_v^T)` with `n_v` the area-weighted unit normal of the target and
/// `a_v` the vertex area over the mean vertex area.
pub(crate) fn tangential_weights(problem: &DesignProblem) -> Vec<nalgebra::Matrix3<f64>> {
    let x = problem.target();
    let nv = x.len() / 3;
    let mut normals = vec![nalgebra::Vector3::zeros(); nv];
    for t in problem.triangles() {
        let [a, b, c] = crate::problem::corners(x, t);
        let n = (b - a).cross(&(c - a));
        for &v in t {
            normals[v] += n;
        }
    }
    let mean = normals.iter().map(|n| n.norm()).sum::<f64>() / nv as f64;
    normals
        .iter()
        .map(|n| {
            let a = n.norm();
            let u = n / a;
            (nalgebra::Matrix3::identity() - u * u.transpose()) * (a / mean)
        })
        .collect()
}

impl Solver<'_> {
    /// The pressure continuation from the load factor `from` (its rest shape in `start`) to
    /// the full pressure, halving the increment on a failed stage; returns the load factor
    /// reached (`start` holds that stage's rest shape).
    fn continuation(
        &mut self,
        start: &mut [f64],
        from: f64,
        info: &mut InverseInfo,
        stopped: &mut bool,
        progress: &mut impl FnMut(&InverseProgress) -> bool,
    ) -> Result<f64, DesignError> {
        let params = self.params;
        let mut load = from;
        let mut step = 1.0f64;
        // Every halving of this continuation counts against `max_halvings`.
        let mut halvings = 0;
        // The failed stages in a row from `load` that halving did not make easier, and the
        // share of its residual the last one left.
        let mut no_easier = 0;
        let mut last_share: Option<f64> = None;
        let mut best_full: Option<(Vec<f64>, f64)> = None;
        while load < 1.0 && !*stopped {
            let next = (load + step).min(1.0);
            let tol = if next >= 1.0 {
                params.tolerance
            } else {
                params.stage_tolerance.max(params.tolerance)
            };
            let mut trial = start.to_vec();
            let outcome = self.stage(&mut trial, next, tol, info, progress)?;
            match outcome {
                Stage::Converged(res) => {
                    start.copy_from_slice(&trial);
                    load = next;
                    info.stages += 1;
                    info.load_reached = load;
                    info.relative_residual = res;
                    // Grow the increment again after an easy stage, no further than the full
                    // pressure (a larger one would be tried again unchanged after a halving).
                    step = (step * 2.0).min(1.0 - load);
                    no_easier = 0;
                    last_share = None;
                }
                Stage::Stopped => {
                    *stopped = true;
                }
                Stage::Failed { share, residual } => {
                    // The full pressure's best attempt so far, kept when it ends closer to
                    // equilibrium than any before it.
                    if next >= 1.0 && best_full.as_ref().is_none_or(|(_, b)| residual < *b) {
                        best_full = Some((std::mem::take(&mut trial), residual));
                    }
                    // A smaller increment makes a stage that fails by its nonlinearity more
                    // nearly linear, so it leaves a smaller share of its residual. Where each
                    // halving leaves about the same share, the residual is proportional to
                    // the load: no fraction of the pressure is held (a flat face, a
                    // crease), and further halvings only spend iterations.
                    no_easier = match (share, last_share) {
                        (Some(q), Some(q_before)) if q >= NO_EASIER * q_before => no_easier + 1,
                        (Some(_), _) => 1,
                        (None, _) => 0,
                    };
                    last_share = share;
                    if no_easier >= HOPELESS_FAILURES {
                        info.no_easier = true;
                        break;
                    }
                    if halvings >= params.max_halvings {
                        break;
                    }
                    halvings += 1;
                    info.halvings += 1;
                    step *= 0.5;
                }
            }
        }
        if load < 1.0
            && let Some((x, residual)) = best_full
        {
            // A failed stage at the full pressure can still end nearer its equilibrium than
            // the last converged stage's rest shape is (a creep to a residual of 5e-8 against
            // a tolerance of 1e-9); the design keeps the nearer one.
            let kept = match self.problem.residual(start, 1.0) {
                Ok(r) => norm(&r) / self.scale,
                Err(_) => f64::INFINITY,
            };
            if residual < kept {
                start.copy_from_slice(&x);
                info.full_attempt_kept = true;
            }
        }
        Ok(load)
    }

    /// The progress report after an accepted iteration of the stage to `load` with residual
    /// `r`.
    fn report(&self, load: f64, r: &[f64], info: &InverseInfo) -> InverseProgress {
        InverseProgress {
            load,
            reached: info.load_reached,
            relative_residual: norm(r) / self.scale,
            iterations: info.iterations,
        }
    }

    /// Whether the next step is a Newton step (counts down the damped steps that follow a
    /// refused one).
    fn newton_ready(&mut self) -> bool {
        if self.newton_wait == 0 {
            return true;
        }
        self.newton_wait -= 1;
        false
    }

    /// One Newton step on `r(X) = 0` from `x` with the bordered LU factor of `J` (D10) and a
    /// backtracking line search on `|r|^2` (Armijo); on success `x`, `r` and `j` hold the new
    /// point. `false` when the factorisation or the step fails or no step length decreases
    /// `|r|^2` enough.
    #[allow(clippy::too_many_arguments)]
    fn newton_step(
        &mut self,
        x: &mut [f64],
        load: f64,
        r: &mut Vec<f64>,
        j: &mut Vec<Matrix3<f64>>,
        r_trial: &mut Vec<f64>,
        j_trial: &mut Vec<Matrix3<f64>>,
        trial: &mut [f64],
    ) -> bool {
        if !self.lu.factorize(j) {
            return false;
        }
        let Some(dx) = self.lu.step(r) else {
            return false;
        };
        let largest = dx
            .chunks(3)
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0, f64::max);
        if largest > NEWTON_MAX_MOVE * self.edge {
            self.refuse_newton();
            return false;
        }
        let m0 = r.iter().map(|v| v * v).sum::<f64>();
        let mut t = 1.0;
        for _ in 0..NEWTON_BACKTRACKS {
            for ((y, a), d) in trial.iter_mut().zip(x.iter()).zip(&dx) {
                *y = a + t * d;
            }
            if self
                .problem
                .evaluate_blocks(trial, load, &self.pattern, r_trial, j_trial)
                .is_ok()
            {
                let m = r_trial.iter().map(|v| v * v).sum::<f64>();
                // Armijo on |r|^2, whose slope along the Newton step is -2 |r|^2.
                if m <= (1.0 - 2e-4 * t) * m0 {
                    self.newton_backoff = 0;
                    x.copy_from_slice(trial);
                    std::mem::swap(r, r_trial);
                    std::mem::swap(j, j_trial);
                    return true;
                }
            }
            t *= 0.5;
        }
        self.refuse_newton();
        false
    }

    /// Damped steps take over for a while, longer after every refused Newton step in a row.
    fn refuse_newton(&mut self) {
        self.newton_backoff = (2 * self.newton_backoff).clamp(1, NEWTON_MAX_WAIT);
        self.newton_wait = self.newton_backoff;
    }

    /// One continuation stage at load factor `load`: Levenberg-Marquardt from `x` until the
    /// relative residual is below `tol`.
    fn stage(
        &mut self,
        x: &mut [f64],
        load: f64,
        tol: f64,
        info: &mut InverseInfo,
        progress: &mut impl FnMut(&InverseProgress) -> bool,
    ) -> Result<Stage, DesignError> {
        let reference = x.to_vec();
        let beta = self.params.tangential_weight;
        let n = x.len();
        let objective = |s: &Self, x: &[f64], r: &[f64], mean_diag: f64| -> f64 {
            let mut phi = 0.5 * r.iter().map(|v| v * v).sum::<f64>();
            if beta > 0.0 {
                for (v, w) in s.tangential.iter().enumerate() {
                    let d = nalgebra::Vector3::from_fn(|k, _| x[3 * v + k] - reference[3 * v + k]);
                    phi += 0.5 * beta * mean_diag * d.dot(&(w * d));
                }
            }
            if let Some((term, kappa)) = &s.bending {
                phi += kappa * mean_diag * term.value_gradient(x).0;
            }
            phi
        };
        let mut r = vec![0.0; n];
        let mut j = vec![Matrix3::zeros(); self.pattern.j_blocks()];
        if self
            .problem
            .evaluate_blocks(x, load, &self.pattern, &mut r, &mut j)
            .is_err()
        {
            return Ok(Stage::Failed {
                share: None,
                residual: f64::INFINITY,
            });
        }
        let first = norm(&r);
        // The trial point's residual and Jacobian, kept when the step is accepted.
        let mut r_trial = r.clone();
        let mut j_trial = j.clone();
        let mut trial = x.to_vec();
        let mut jtj = Vec::new();
        let mut g = vec![0.0; n];
        let (mut jdx, mut rvv, mut acc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut mean_diag = 0.0;
        let newton = self.params.newton && beta == 0.0 && self.bending.is_none();
        let mut phi_last = f64::INFINITY;
        for _ in 0..self.params.max_iterations {
            let res = norm(&r) / self.scale;
            if res <= tol {
                return Ok(Stage::Converged(res));
            }
            if newton
                && res <= NEWTON_RESIDUAL
                && self.newton_ready()
                && self.newton_step(
                    x,
                    load,
                    &mut r,
                    &mut j,
                    &mut r_trial,
                    &mut j_trial,
                    &mut trial,
                )
            {
                info.iterations += 1;
                if !progress(&self.report(load, &r, info)) {
                    return Ok(Stage::Stopped);
                }
                continue;
            }
            info.damped_steps += 1;
            // Normal equations (J^T J + beta T + mu I) dX = -(J^T r + beta T (X - X_ref)).
            self.pattern.normal(&j, &r, &mut jtj, &mut g);
            if mean_diag == 0.0 {
                mean_diag = self.pattern.trace(&jtj) / n as f64;
            }
            if let Some((term, kappa)) = &self.bending {
                // D17: the bending term's gradient and Gauss-Newton matrix.
                let (_, gb) = term.value_gradient(x);
                for (a, b) in g.iter_mut().zip(gb) {
                    *a += kappa * mean_diag * b;
                }
                term.add_gauss_newton_blocks(x, kappa * mean_diag, &self.pattern, &mut jtj);
            }
            if beta > 0.0 {
                for (v, w) in self.tangential.iter().enumerate() {
                    let d = nalgebra::Vector3::from_fn(|k, _| x[3 * v + k] - reference[3 * v + k]);
                    let wd = w * d * (beta * mean_diag);
                    for k in 0..3 {
                        g[3 * v + k] += wd[k];
                    }
                }
            }
            let phi0 = objective(self, x, &r, mean_diag);
            let mut accepted = false;
            for _ in 0..30 {
                let (b, mu) = (beta * mean_diag, self.damping * mean_diag);
                let tangential = &self.tangential;
                let a = self
                    .pattern
                    .write_csr(&jtj, |v| tangential[v] * b + Matrix3::identity() * mu);
                // The pattern is the mesh's: one symbolic analysis for the whole design. With a
                // vanishing damping `J^T J` is singular in round-off (the rigid motions, and the
                // normal directions near a pressure maximum): a failed factorisation or solve
                // asks for more damping, as a refused step does, instead of ending the design.
                if self.chol.factorize(a, 1).is_err() {
                    self.damping = (4.0 * self.damping).max(1e-9);
                    continue;
                }
                let mut dx: Vec<f64> = g.iter().map(|v| -v).collect();
                if self.chol.solve_in_place(&mut dx).is_err() {
                    self.damping = (4.0 * self.damping).max(1e-9);
                    continue;
                }
                // Geodesic acceleration (Transtrum and Sethna 2012): the second directional
                // derivative of r along dx by a finite difference, and the correction `a` it
                // asks for, solved with the same factor; the step `dx + a/2` follows the
                // curved valleys of |r|^2 that the near-isometric rest motions make.
                let mut step = dx.clone();
                if self.params.acceleration {
                    let h = 0.1;
                    for ((t, a), b) in trial.iter_mut().zip(x.iter()).zip(&dx) {
                        *t = a + h * b;
                    }
                    if let Ok(rh) = self.problem.residual(&trial, load) {
                        self.pattern.apply(&j, &dx, &mut jdx);
                        for (((w, a), b), c) in rvv.iter_mut().zip(&rh).zip(&r).zip(&jdx) {
                            *w = 2.0 / h * ((a - b) / h - c);
                        }
                        self.pattern.transpose_apply(&j, &rvv, &mut acc);
                        for v in acc.iter_mut() {
                            *v = -*v;
                        }
                        self.chol
                            .solve_in_place(&mut acc)
                            .map_err(|e| DesignError::Linear(e.to_string()))?;
                        if norm(&acc) <= 0.75 * norm(&dx) {
                            for (s, a) in step.iter_mut().zip(&acc) {
                                *s += 0.5 * a;
                            }
                        } else {
                            self.damping *= 4.0;
                            continue;
                        }
                    }
                }
                for ((t, a), b) in trial.iter_mut().zip(x.iter()).zip(&step) {
                    *t = a + b;
                }
                if self
                    .problem
                    .evaluate_blocks(&trial, load, &self.pattern, &mut r_trial, &mut j_trial)
                    .is_ok()
                {
                    let phi = objective(self, &trial, &r_trial, mean_diag);
                    if phi < phi0 {
                        x.copy_from_slice(&trial);
                        std::mem::swap(&mut r, &mut r_trial);
                        std::mem::swap(&mut j, &mut j_trial);
                        self.damping = (self.damping / 3.0).max(1e-12);
                        accepted = true;
                        break;
                    }
                }
                self.damping *= 4.0;
            }
            info.iterations += 1;
            if !accepted {
                return Ok(Stage::Failed {
                    share: Some(norm(&r) / first),
                    residual: norm(&r) / self.scale,
                });
            }
            if self.bending.is_some() {
                // The regularised problem has no zero residual: a stage ends where a step no
                // longer decreases its objective (D17).
                let phi = objective(self, x, &r, mean_diag);
                if phi0 - phi <= 1e-8 * phi0 || (phi_last - phi).abs() <= 1e-10 * phi0 {
                    return Ok(Stage::Converged(norm(&r) / self.scale));
                }
                phi_last = phi;
            }
            if !progress(&self.report(load, &r, info)) {
                return Ok(Stage::Stopped);
            }
        }
        let res = norm(&r) / self.scale;
        Ok(if res <= tol {
            Stage::Converged(res)
        } else {
            Stage::Failed {
                share: Some(norm(&r) / first),
                residual: res,
            }
        })
    }
}
