//! The wall-thickness fit (`docs/design.md`, D18): with the rest shape fixed, the rest
//! thickness of every face, within given bounds, that brings the forward equilibrium closest to
//! the target. The objective is the shape optimisation's distance `D` (D11); its gradient with
//! respect to the thickness comes from the same adjoint `lambda` (D12), since the elastic
//! forces are linear in each face's rest thickness.

use std::collections::VecDeque;

use balloon_integrate::newton::cancel_requested;
use balloon_integrate::statics::StaticParams;
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::fallback::{FallbackProgress, FallbackStop};
use crate::forward::Distance;
use crate::gauss_newton::{dot, lbfgs_direction};
use crate::objective::ShapeObjective;
use crate::problem::DesignProblem;

/// Parameters of [`fit_thickness`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ThicknessFitParams {
    /// Whether [`crate::design`] fits the thickness after the rest shape (default `false`).
    pub enabled: bool,
    /// Smallest thickness a face may take, m (default `None`: a quarter of the smallest start
    /// thickness).
    pub lower: Option<f64>,
    /// Largest thickness a face may take, m (default `None`: four times the largest start
    /// thickness).
    pub upper: Option<f64>,
    /// Accepted steps (default 40; each at least one forward static solve).
    pub max_iterations: usize,
    /// Pairs kept by L-BFGS (default 8).
    pub memory: usize,
    /// Stop when the gradient's norm falls below this fraction of the first one (default
    /// `1e-6`).
    pub gradient_tolerance: f64,
    /// Stop when the largest vertex distance falls below this fraction of the target's
    /// bounding-box diagonal (default `1e-8`).
    pub distance_tolerance: f64,
    /// Largest change of one step in the bounded variable `s` of D18 (default 0.5; near the
    /// middle of the bounds a change of 1 moves the thickness by a quarter of their span).
    pub max_move: f64,
    /// Start each forward solve from the last equilibrium instead of from the rest shape with
    /// load continuation, as the forward check does (default `false`; see
    /// [`crate::FallbackParams::warm_start`]).
    pub warm_start: bool,
}

impl Default for ThicknessFitParams {
    fn default() -> Self {
        Self {
            enabled: false,
            lower: None,
            upper: None,
            max_iterations: 40,
            memory: 8,
            gradient_tolerance: 1e-6,
            distance_tolerance: 1e-8,
            max_move: 0.5,
            warm_start: false,
        }
    }
}

impl ThicknessFitParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), DesignError> {
        let bad = |name: &'static str, value: f64, allowed: &'static str| {
            Err(DesignError::InvalidParameter {
                name,
                value,
                allowed,
            })
        };
        for (name, bound) in [("thickness_min", self.lower), ("thickness_max", self.upper)] {
            if let Some(b) = bound
                && !(b.is_finite() && b > 0.0)
            {
                return bad(name, b, "a positive thickness in m");
            }
        }
        if let (Some(lo), Some(hi)) = (self.lower, self.upper)
            && lo >= hi
        {
            return bad("thickness_max", hi, "above thickness_min");
        }
        if self.memory == 0 {
            return bad("memory", 0.0, "at least 1");
        }
        for (name, value) in [
            ("gradient_tolerance", self.gradient_tolerance),
            ("distance_tolerance", self.distance_tolerance),
            ("max_move", self.max_move),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return bad(name, value, "positive and finite");
            }
        }
        Ok(())
    }

    /// The bounds `(lower, upper)` (m) for the start thickness map `start`.
    fn bounds(&self, start: &[f64]) -> Result<(f64, f64), DesignError> {
        let lo = self
            .lower
            .unwrap_or_else(|| 0.25 * start.iter().copied().fold(f64::INFINITY, f64::min));
        let hi = self
            .upper
            .unwrap_or_else(|| 4.0 * start.iter().copied().fold(0.0, f64::max));
        if lo < hi {
            Ok((lo, hi))
        } else {
            Err(DesignError::InvalidParameter {
                name: "thickness_max",
                value: hi,
                allowed: "above thickness_min",
            })
        }
    }
}

/// What [`fit_thickness`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThicknessFitInfo {
    /// Accepted L-BFGS steps.
    pub iterations: usize,
    /// Forward static solves (line-search trials included).
    pub forward_solves: usize,
    /// Distance of the start's forward equilibrium to the target; `None` when it has none.
    pub start: Option<Distance>,
    /// The same for the fitted thickness.
    pub end: Option<Distance>,
    /// The objective `D` (m^2, D11) at the start.
    pub objective_start: f64,
    /// The objective at the end.
    pub objective_end: f64,
    /// Norm of the last gradient (in the bounded variable) over the first one.
    pub gradient_reduction: f64,
    /// Why it stopped (the reasons of the shape optimisation, with this fit's parameters).
    pub stopped: FallbackStop,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// The bounds used, m.
    pub lower: f64,
    /// The upper bound used, m.
    pub upper: f64,
    /// Faces whose fitted thickness is within 1 % of the bounds' span of a bound: where the
    /// bounds, not the target, set the wall.
    pub at_bounds: usize,
}

/// A fitted thickness map and how the fit went.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThicknessFit {
    /// The rest thickness per face (m), within the bounds.
    pub thickness: Vec<f64>,
    /// How the fit went.
    pub info: ThicknessFitInfo,
}

fn sigmoid(s: f64) -> f64 {
    1.0 / (1.0 + (-s).exp())
}

/// Minimises the distance `D` of the forward equilibrium to the target (D11) over the rest
/// thickness of every face, with the rest shape `rest` fixed, from the problem's thickness map
/// (moved inside the bounds), within `[lower, upper]` by the change of variable
/// `H_e = lower + (upper - lower) sigmoid(s_e)` and L-BFGS with a backtracking (Armijo) line
/// search on `s` (D18). The gradient is the adjoint one (D12) with `df_e/dH_e = f_e / H_e`.
/// Every accepted step decreases `D`, so the fit is never worse than the start (clamped to the
/// bounds); `progress` is called after every accepted step and stops the fit when it returns
/// `false`, keeping the best thickness so far.
///
/// # Errors
/// An invalid parameter or `rest` of the wrong length, and those of
/// [`ShapeObjective::evaluate`]. A start with no forward equilibrium is not an error:
/// [`ThicknessFitInfo::stopped`] is [`FallbackStop::NoEquilibrium`] and the start thickness is
/// returned.
pub fn fit_thickness(
    problem: &DesignProblem,
    rest: &[f64],
    params: &ThicknessFitParams,
    forward: &StaticParams,
    mut progress: impl FnMut(&FallbackProgress) -> bool,
) -> Result<ThicknessFit, DesignError> {
    params.validate()?;
    problem.check_length("rest", rest)?;
    let started = std::time::Instant::now();
    let (lower, upper) = params.bounds(problem.thickness())?;
    let span = upper - lower;
    let thickness_of =
        |s: &[f64]| -> Vec<f64> { s.iter().map(|s| lower + span * sigmoid(*s)).collect() };
    // dD/ds_e = dD/dH_e (upper - lower) sigmoid'(s_e).
    let chain = |g: Vec<f64>, s: &[f64]| -> Vec<f64> {
        g.iter()
            .zip(s)
            .map(|(g, s)| {
                let p = sigmoid(*s);
                g * span * p * (1.0 - p)
            })
            .collect()
    };
    let mut s: Vec<f64> = problem
        .thickness()
        .iter()
        .map(|h| {
            let u = ((h - lower) / span).clamp(1e-3, 1.0 - 1e-3);
            (u / (1.0 - u)).ln()
        })
        .collect();
    let mut thickness = thickness_of(&s);
    let mut objective = ShapeObjective::new(problem, forward, forward.tolerance)?;
    objective.set_warm_start(params.warm_start);
    objective.set_thickness(&thickness)?;
    let mut info = ThicknessFitInfo {
        iterations: 0,
        forward_solves: 0,
        start: None,
        end: None,
        objective_start: f64::NAN,
        objective_end: f64::NAN,
        gradient_reduction: f64::NAN,
        stopped: FallbackStop::NoEquilibrium,
        seconds: 0.0,
        lower,
        upper,
        at_bounds: 0,
    };
    let finish = |mut info: ThicknessFitInfo, thickness: Vec<f64>, solves: usize| {
        info.forward_solves = solves;
        info.seconds = started.elapsed().as_secs_f64();
        info.at_bounds = thickness
            .iter()
            .filter(|h| (*h - lower).min(upper - *h) <= 0.01 * span)
            .count();
        ThicknessFit { thickness, info }
    };
    let Some(first) = objective.evaluate(rest, true)? else {
        if cancel_requested() {
            info.stopped = FallbackStop::Interrupted;
        }
        let solves = objective.forward_solves();
        return Ok(finish(info, problem.thickness().to_vec(), solves));
    };
    let mut g = chain(objective.thickness_gradient(rest)?, &s);
    let g0 = dot(&g, &g).sqrt();
    let mut phi = first.objective;
    info.start = Some(first.distance);
    info.end = Some(first.distance);
    info.objective_start = phi;
    info.objective_end = phi;
    info.gradient_reduction = 1.0;
    let mut memory: VecDeque<(Vec<f64>, Vec<f64>, f64)> = VecDeque::new();
    let mut trial = s.clone();
    loop {
        let gn = dot(&g, &g).sqrt();
        info.gradient_reduction = if g0 > 0.0 { gn / g0 } else { 0.0 };
        if info
            .end
            .is_some_and(|d| d.max_relative <= params.distance_tolerance)
        {
            info.stopped = FallbackStop::Distance;
            break;
        }
        if gn <= params.gradient_tolerance * g0 {
            info.stopped = FallbackStop::Gradient;
            break;
        }
        if info.iterations >= params.max_iterations {
            info.stopped = FallbackStop::Iterations;
            break;
        }
        let mut d = lbfgs_direction(&memory, &g);
        let mut slope = dot(&g, &d);
        if slope.is_nan() || slope >= 0.0 {
            memory.clear();
            d = g.iter().map(|v| -v).collect();
            slope = -gn * gn;
        }
        let largest = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut t = if memory.is_empty() || largest > params.max_move {
            params.max_move / largest
        } else {
            1.0
        };
        let kept = objective.equilibrium().map(<[f64]>::to_vec);
        let mut accepted = None;
        for _ in 0..12 {
            for ((y, x), di) in trial.iter_mut().zip(&s).zip(&d) {
                *y = x + t * di;
            }
            let h = thickness_of(&trial);
            objective.set_thickness(&h)?;
            objective.set_equilibrium(kept.clone());
            if let Some(e) = objective.evaluate(rest, true)?
                && e.objective <= phi + 1e-4 * t * slope
            {
                accepted = Some((e, h));
                break;
            }
            t *= 0.5;
        }
        let Some((e, h)) = accepted else {
            objective.set_thickness(&thickness)?;
            objective.set_equilibrium(kept);
            // Every trial's forward solve fails once a stop was asked for (Ctrl-C).
            info.stopped = if cancel_requested() {
                FallbackStop::Interrupted
            } else {
                FallbackStop::LineSearch
            };
            break;
        };
        let g_t = chain(objective.thickness_gradient(rest)?, &trial);
        let step: Vec<f64> = trial.iter().zip(&s).map(|(a, b)| a - b).collect();
        let change: Vec<f64> = g_t.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&step, &change);
        if sy > 1e-12 * dot(&step, &step).sqrt() * dot(&change, &change).sqrt() {
            if memory.len() == params.memory {
                memory.pop_front();
            }
            memory.push_back((step, change, 1.0 / sy));
        }
        s.copy_from_slice(&trial);
        thickness = h;
        g = g_t;
        phi = e.objective;
        info.iterations += 1;
        info.end = Some(e.distance);
        info.objective_end = phi;
        let go = progress(&FallbackProgress {
            iteration: info.iterations,
            objective: phi,
            max_distance: e.distance.max,
            rms_distance: e.distance.rms,
        });
        if !go {
            info.stopped = FallbackStop::Interrupted;
            break;
        }
    }
    let solves = objective.forward_solves();
    Ok(finish(info, thickness, solves))
}
