//! The line search of the Newton core: backtracking along the Newton direction.
//!
//! With a potential, Armijo backtracking on the objective `E`: the step length `s` halves from
//! 1 until `E(u + s du) <= E(u) - 1e-4 s r . du` (`r . du` is minus the directional derivative
//! of `E`); a state where `E` is undefined (an inverted element, a non-positive gas volume)
//! counts as `E = inf`. Close to convergence the decrease falls below what `f64` resolves in
//! `E`; a trial within round-off of `E` ([`ENERGY_ROUNDOFF`] of the magnitude of its parts) is
//! then accepted when it lowers `|r|`. Without a potential (stiffness damping) or along a
//! direction that is not a descent direction, the search backtracks on the residual norm,
//! `|r(u + s du)| <= (1 - 1e-4 s) |r(u)|`, taking the shortest step if none decreases it.

use super::convergence::{Residual, first_non_finite};
use super::{NewtonCore, NewtonError};
use crate::system::ForceSystem;

/// Sufficient-decrease constant of the Armijo line search: a step of length `s` along `du` is
/// accepted when `E(u + s du) <= E(u) - ARMIJO s (r . du)` (or, for the residual-norm search,
/// `|r(u + s du)| <= (1 - ARMIJO s) |r(u)|`).
pub const ARMIJO: f64 = 1e-4;

/// Halvings of the Newton step the line search tries before giving up (shortest step
/// `2^-20`).
pub const MAX_LINE_SEARCH_CUTS: usize = 20;

/// Relative round-off of the objective: energy changes below this times the magnitude of its
/// parts are not resolved, and the residual decides instead.
pub const ENERGY_ROUNDOFF: f64 = 1e-12;

/// How the Newton step is shortened in one iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LineSearch {
    /// Armijo backtracking on the objective.
    Energy,
    /// Backtracking on the norm of the residual (no potential with stiffness damping, or a
    /// direction that is not a descent direction of the potential).
    Residual,
    /// Full Newton steps (a system without a potential).
    Off,
}

/// The current iterate as the line search sees it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Current {
    /// Its objective, when there is one.
    pub(crate) energy: Option<f64>,
    /// `r . du`: minus the directional derivative of the objective along `du`.
    pub(crate) slope: f64,
    /// Its residual.
    pub(crate) residual: Residual,
}

impl NewtonCore {
    /// One trial of the line search at `trial = u + step du` (`iteration`: the Newton
    /// iteration the trial would start). Returns the accepted iterate's objective (energy
    /// search) and residual, `None` to cut the step, or an error that ends the solve. On
    /// acceptance the system's last force evaluation is at the trial point.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn try_step<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        mode: LineSearch,
        trial: &[f64],
        current: &Current,
        step: f64,
        iteration: usize,
        last_cut: bool,
    ) -> Result<Option<(Option<f64>, Residual)>, NewtonError> {
        if first_non_finite(trial).is_some() {
            return Ok(None);
        }
        match (mode, current.energy) {
            (LineSearch::Energy, Some(e0)) => {
                // An undefined energy (inverted element, non-positive volume) counts as
                // infinite: cut. With a fused evaluation the trial's forces come with its
                // energy, and a failure of either is a cut.
                let (e1, fused) = if self.fuses_energy(system) {
                    match self.objective.evaluate(
                        system,
                        trial,
                        iteration,
                        false,
                        true,
                        &mut self.times,
                    ) {
                        Ok((r, Some(e))) if e.is_finite() => (e, Some(r)),
                        _ => return Ok(None),
                    }
                } else {
                    match self.objective.energy(system, trial, &mut self.times) {
                        Ok(Some(e)) if e.is_finite() => (e, None),
                        _ => return Ok(None),
                    }
                };
                let armijo = e1 <= e0 - ARMIJO * step * current.slope;
                // Within round-off of the energy (close to convergence the decrease is below
                // what f64 resolves in E): accept if the residual falls instead.
                let roundoff =
                    !armijo && e1 <= e0 + ENERGY_ROUNDOFF * self.objective.energy_magnitude;
                if !(armijo || roundoff) {
                    return Ok(None);
                }
                let r = match fused {
                    Some(r) => Ok(r),
                    None => self
                        .objective
                        .evaluate(system, trial, iteration, false, false, &mut self.times)
                        .map(|(r, _)| r),
                };
                Ok(match r {
                    // A state with an energy but no forces (should not happen): cut.
                    Ok(r) if armijo || r.norm < current.residual.norm => Some((Some(e1), r)),
                    _ => None,
                })
            }
            (LineSearch::Off, _) => self
                .objective
                .evaluate(system, trial, iteration, false, false, &mut self.times)
                .map(|(r, _)| Some((None, r))),
            _ => Ok(
                match self.objective.evaluate(
                    system,
                    trial,
                    iteration,
                    false,
                    false,
                    &mut self.times,
                ) {
                    Ok((r, _)) if r.norm <= (1.0 - ARMIJO * step) * current.residual.norm => {
                        Some((None, r))
                    }
                    // The residual search found no decrease: take the shortest step and let the
                    // iteration limit decide.
                    Ok((r, _)) if last_cut => Some((None, r)),
                    _ => None,
                },
            ),
        }
    }

    /// Whether trials evaluate their energy and forces in one pass over the system.
    pub(crate) fn fuses_energy<S: ForceSystem + ?Sized>(&self, system: &S) -> bool {
        !self.objective.stiffness_damped() && system.fuses_forces_and_energy()
    }
}
