//! Inverse design of shell balloons: the rest shape whose static equilibrium under a given
//! gauge pressure is a given (target) shape.
//!
//! **What it is for.** Everything else in the workspace runs forward (rest shape in, inflated
//! shape out). This crate runs the static equilibrium backwards: with the deformed positions
//! `x*` fixed to the target, the equilibrium equations `f_el(x*; X) + p dV/dx(x*) = 0` are
//! solved for the rest positions `X` ([`DesignProblem`], [`design_rest_shape`]) with the exact
//! derivatives of the element forces with respect to the rest shape
//! (`balloon_element::ThreePrism::forces_and_rest_jacobian`,
//! `balloon_element::HyperMembrane::forces_and_rest_jacobian`), by Levenberg-Marquardt under
//! pressure continuation. The design is then checked by a forward static solve from the
//! designed rest shape with the shell's own static solver ([`forward_check`]), and the distance
//! of that equilibrium to the target is reported ([`Distance`]: max and RMS, in m and over the
//! bounding-box diagonal). Where no rest shape holds the target exactly (flat faces, targets
//! beyond the pressure maximum), [`design`] goes on with a shape optimisation
//! ([`optimise_rest_shape`]): it minimises the distance of the forward equilibrium to the
//! target over the rest shape, with the adjoint gradient through the static solve and
//! Gauss-Newton steps on the exact sensitivity of the equilibrium (L-BFGS where they fail, or
//! throughout: [`FallbackMethod`]), optionally through stages with a conformal shape term on
//! the rest triangles ([`FallbackParams::shape_weight`]) or a bending term on its dihedral
//! angles ([`FallbackParams::bending_weight`], also in the inverse solve:
//! [`InverseParams::bending_weight`]), and reports the remaining distance
//! ([`FallbackInfo`]) instead of claiming success. Works for the three-prism shell (St.
//! Venant-Kirchhoff, neo-Hookean; Wang et al. 2015, Eq. 4-8) and the incompressible membranes
//! (`docs/membranes.md`). The equations, the regulariser and what the method can and cannot
//! reach are in `docs/design.md`.
//!
//! ```
//! use balloon_design::{DesignParams, DesignProblem, design};
//! use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
//! use balloon_shell::ShellMaterialModel;
//!
//! // A sphere of radius 0.1 m, wanted at 2 kPa, 1 mm rubber (mu = 0.4 MPa).
//! let target = balloon_mesh::generate::icosphere(0.1, 1)?;
//! let rubber = ShellMaterialModel::from(MembraneModel::from(MembraneNeoHookean::try_new(4e5)?));
//! let problem = DesignProblem::try_new(&target, vec![1e-3; target.num_triangles()], rubber, 2e3)?;
//! let result = design(&problem, &DesignParams::default(), |_| true)?;
//! assert!(result.inverse.converged);
//! // The rest shape is smaller than the target, and it inflates back onto it.
//! assert!(balloon_design::bbox_diagonal(&result.rest) < balloon_design::bbox_diagonal(problem.target()));
//! assert!(result.check.distance.max_relative < 1e-4);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Features: none.

mod bending_term;
mod conditioning;
mod error;
mod fallback;
mod forward;
mod gauss_newton;
mod inverse;
mod normal;
mod objective;
mod pinned;
mod problem;
mod shape_term;
#[cfg(test)]
mod test_fixtures;
mod thickness_fit;

pub use conditioning::{
    ConditioningParams, RestConditioning, rest_conditioning, rigid_motions, smallest_eigenpairs,
};
pub use error::DesignError;
pub use fallback::{
    FallbackInfo, FallbackMethod, FallbackMode, FallbackParams, FallbackProgress, FallbackStop,
    NEWTON_POLISH_ITERATIONS, optimise_rest_shape,
};
pub use forward::{
    Distance, ForwardCheck, bbox_diagonal, distance, forward_check, rigidly_aligned,
    vertex_distances,
};
pub use inverse::{
    InverseInfo, InverseParams, InverseProgress, design_rest_shape, relative_residual,
};
pub use objective::{Evaluation, ShapeObjective};
pub use problem::{DesignProblem, GasAmount, enclosed_volume, volume_gradient};
pub use thickness_fit::{ThicknessFit, ThicknessFitInfo, ThicknessFitParams, fit_thickness};

use balloon_integrate::newton::{cancel_requested, without_cancel};
use balloon_integrate::statics::StaticParams;
use serde::{Deserialize, Serialize};

/// Parameters of [`design`]: the inverse solve and the forward check's static solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DesignParams {
    /// The inverse-statics solve.
    pub inverse: InverseParams,
    /// The forward check's static solve (also the shape optimisation's, at its own tolerance).
    pub forward: StaticParams,
    /// The shape optimisation after the inverse solve (by default when the inverse did not
    /// converge).
    pub fallback: FallbackParams,
    /// The wall-thickness fit after the rest shape (off by default).
    pub thickness: ThicknessFitParams,
    /// How well the target determines the rest shape, after the check (off by default;
    /// [`rest_conditioning`]).
    pub conditioning: ConditioningParams,
    /// The factor on the wall's plate bending modulus (`balloon inflate --bending`), `>= 0`:
    /// when positive, [`design`] and [`design_for_rest`] solve, check and report the problem
    /// with that bending wall ([`DesignProblem::with_wall_bending`], replacing the problem's
    /// own factor); 0 (the default) leaves the problem as given.
    pub wall_bending: f64,
    /// A design whose inverse solve has no exact answer still answers its target when its
    /// forward check converged within this distance of the target, as a fraction of the
    /// target's bounding-box diagonal ([`Design::accepted`]); 0 (the default): only an exact
    /// design does. In `[0, 1]`.
    pub accept_distance: f64,
}

impl DesignParams {
    /// [`DesignParams::accept_distance`] in `[0, 1]`.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `accept_distance` otherwise (or not a number).
    fn validate_accept_distance(&self) -> Result<(), DesignError> {
        if (0.0..=1.0).contains(&self.accept_distance) {
            Ok(())
        } else {
            Err(DesignError::InvalidParameter {
                name: "accept_distance",
                value: self.accept_distance,
                allowed: "a fraction of the target's bounding-box diagonal in [0, 1]",
            })
        }
    }

    /// `problem` with the wall of [`DesignParams::wall_bending`] (borrowed when it is 0).
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `bending` for a negative or non-finite factor.
    fn wall<'a>(
        &self,
        problem: &'a DesignProblem,
    ) -> Result<std::borrow::Cow<'a, DesignProblem>, DesignError> {
        if self.wall_bending == 0.0 {
            Ok(std::borrow::Cow::Borrowed(problem))
        } else {
            Ok(std::borrow::Cow::Owned(
                problem.clone().with_wall_bending(self.wall_bending)?,
            ))
        }
    }
}

/// Progress of a [`design`]: the inverse solve's or the shape optimisation's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DesignProgress {
    /// After an accepted iteration of the inverse solve.
    Inverse(InverseProgress),
    /// After an accepted step of the shape optimisation.
    Fallback(FallbackProgress),
    /// After an accepted step of the wall-thickness fit.
    Thickness(FallbackProgress),
}

/// A designed rest shape and its check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Design {
    /// The rest positions (flat, m), same connectivity as the target.
    pub rest: Vec<f64>,
    /// How the inverse solve went.
    pub inverse: InverseInfo,
    /// The forward static solve from the rest shape and its distance to the target (with the
    /// fitted thickness when there is one).
    pub check: ForwardCheck,
    /// The fitted wall thickness ([`ThicknessFitParams::enabled`]; absent otherwise).
    #[serde(default)]
    pub thickness: Option<ThicknessFit>,
    /// The smallest singular values of the inverse's Jacobian at the rest shape
    /// ([`ConditioningParams::enabled`]; absent otherwise).
    #[serde(default)]
    pub conditioning: Option<RestConditioning>,
}

impl Design {
    /// Whether the design answers its target: the inverse solve converged (an exact design),
    /// or its forward check converged and lies within `accept_distance` of the target, as a
    /// fraction of the target's bounding-box diagonal (at most; 0 accepts only an exact design,
    /// [`DesignParams::accept_distance`]).
    pub fn accepted(&self, accept_distance: f64) -> bool {
        self.inverse.converged
            || (accept_distance > 0.0
                && self.check.converged
                && self.check.distance.max_relative <= accept_distance)
    }
}

/// The weight of a regulariser in its stage `k` (from 0): `w0 0.1^k`, the decreasing stages of
/// the shape and bending terms (`docs/design.md` D16, D17).
fn stage_weight(w0: f64, k: usize) -> f64 {
    w0 * 0.1f64.powi(i32::try_from(k).unwrap_or(i32::MAX))
}

/// Designs the rest shape of `problem` (from the target as the start, [`design_rest_shape`]);
/// when the inverse solve does not converge (or always, [`FallbackParams::mode`]) minimises
/// the distance of the forward equilibrium to the target from its best rest shape
/// ([`optimise_rest_shape`], recorded in [`InverseInfo::fallback`]); and checks the result
/// with a forward static solve ([`forward_check`]). With [`ThicknessFitParams::enabled`] it
/// then fits the wall's thickness per face to the target with that rest shape fixed
/// ([`fit_thickness`]), and the check uses the fitted thickness. With
/// [`ConditioningParams::enabled`] it ends with [`rest_conditioning`] at the rest shape found
/// (how well the target determines it). `progress` is called after every accepted
/// step of either; returning `false` stops the design and keeps the best rest shape so far
/// (which is then checked; the shape optimisation does not start after a stopped inverse
/// solve). A stop asked of all the process's solves
/// ([`balloon_integrate::newton::cancel_requested`], which the `balloon` command's Ctrl-C
/// sets) stops it the same way. The check always runs with that request suspended
/// ([`balloon_integrate::newton::without_cancel`]), so that it is a real forward solve and
/// not one stopped at its first iteration. With [`DesignParams::wall_bending`] positive, all
/// of it runs on the problem with that bending wall.
///
/// [`InverseInfo::converged`] stays that of the inverse solve: the shape optimisation
/// reduces the distance but does not make an inexact design exact; the check's distance says
/// how close it is.
///
/// # Errors
/// Those of [`design_rest_shape`], [`optimise_rest_shape`] and [`forward_check`], and
/// [`DesignError::InvalidParameter`] naming `bending` for a bad [`DesignParams::wall_bending`].
pub fn design(
    problem: &DesignProblem,
    params: &DesignParams,
    mut progress: impl FnMut(&DesignProgress) -> bool,
) -> Result<Design, DesignError> {
    params.conditioning.validate()?;
    params.validate_accept_distance()?;
    let problem = &*params.wall(problem)?;
    let mut rest = problem.target().to_vec();
    let mut stopped = false;
    let mut inverse = design_rest_shape(problem, &params.inverse, &mut rest, |p| {
        let go = progress(&DesignProgress::Inverse(*p));
        stopped |= !go;
        go
    })?;
    // A stop asked of the process's solves (Ctrl-C) stops the design as the callback does.
    stopped |= cancel_requested();
    let run = match params.fallback.mode {
        FallbackMode::Off => false,
        FallbackMode::Unconverged => !inverse.converged,
        FallbackMode::Always => true,
    };
    if run && !stopped {
        let info =
            optimise_rest_shape(problem, &params.fallback, &params.forward, &mut rest, |p| {
                let go = progress(&DesignProgress::Fallback(*p));
                stopped |= !go;
                go
            })?;
        stopped |= info.stopped == FallbackStop::Interrupted;
        inverse.fallback = Some(info);
    }
    wall_and_check(problem, rest, inverse, params, !stopped, progress)
}

/// The design for a given rest shape `rest` (flat, m; same connectivity as the target), kept
/// fixed: a mould one already has. No inverse solve and no shape optimisation run;
/// [`InverseInfo`] records the equilibrium residual of `rest` at the full load
/// ([`relative_residual`]; `converged` when it is within [`InverseParams::tolerance`], i.e. the
/// rest shape holds the target exactly), then the wall-thickness fit runs when
/// [`ThicknessFitParams::enabled`], and the forward check from `rest` (with the fitted wall).
///
/// # Errors
/// A `rest` of the wrong length or with a degenerate triangle, and those of [`fit_thickness`]
/// and [`forward_check`].
pub fn design_for_rest(
    problem: &DesignProblem,
    rest: Vec<f64>,
    params: &DesignParams,
    progress: impl FnMut(&DesignProgress) -> bool,
) -> Result<Design, DesignError> {
    params.inverse.validate()?;
    params.conditioning.validate()?;
    params.validate_accept_distance()?;
    let problem = &*params.wall(problem)?;
    let started = std::time::Instant::now();
    let residual = relative_residual(problem, &rest)?;
    let inverse = InverseInfo {
        converged: residual <= params.inverse.tolerance,
        load_reached: 1.0,
        relative_residual: residual,
        iterations: 0,
        damped_steps: 0,
        stages: 0,
        halvings: 0,
        no_easier: false,
        full_attempt_kept: false,
        seconds: started.elapsed().as_secs_f64(),
        fallback: None,
    };
    wall_and_check(problem, rest, inverse, params, true, progress)
}

/// The end of a design: the wall-thickness fit on the rest shape `rest` when `fit` and
/// [`ThicknessFitParams::enabled`], then the forward check (with the fitted wall).
fn wall_and_check(
    problem: &DesignProblem,
    rest: Vec<f64>,
    inverse: InverseInfo,
    params: &DesignParams,
    fit: bool,
    mut progress: impl FnMut(&DesignProgress) -> bool,
) -> Result<Design, DesignError> {
    let fitted = if fit && params.thickness.enabled {
        Some(fit_thickness(
            problem,
            &rest,
            &params.thickness,
            &params.forward,
            |p| progress(&DesignProgress::Thickness(*p)),
        )?)
    } else {
        None
    };
    let check_problem = match &fitted {
        None => std::borrow::Cow::Borrowed(problem),
        Some(fit) => std::borrow::Cow::Owned(problem.with_thickness(fit.thickness.clone())?),
    };
    // The check runs to its end also after a stop was asked for: the best design so far is
    // checked (a second Ctrl-C ends the `balloon` process at once).
    let check = without_cancel(|| forward_check(&check_problem, &rest, &params.forward))?;
    let conditioning = if params.conditioning.enabled {
        let problem = match &fitted {
            None => std::borrow::Cow::Borrowed(problem),
            Some(fit) => std::borrow::Cow::Owned(problem.with_thickness(fit.thickness.clone())?),
        };
        // At the check's equilibrium: its forward solve is not repeated.
        Some(rest_conditioning(
            &problem,
            &rest,
            &params.conditioning,
            &params.forward,
            check.converged.then_some(check.positions.as_slice()),
        )?)
    } else {
        None
    };
    Ok(Design {
        rest,
        inverse,
        check,
        thickness: fitted,
        conditioning,
    })
}
