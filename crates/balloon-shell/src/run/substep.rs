//! One sub-step of a running shell: the implicit solve (backward Euler, Eq. 18-23, on the
//! shell wrapped by the anchor and pin decorators), the shell-volume projection (Eq. 24-28,
//! Algorithm 2), the velocity update (Algorithm 1, lines 11-12) and the check of the state
//! after it.

use balloon_constraint::projector::ShellProjectionInput;
use balloon_gas::GasModel;
use balloon_integrate::decorators::{Anchored, Pinned};
use balloon_integrate::implicit::StepInfo;

use super::{RUNAWAY_VOLUME_FACTOR, ShellError, ShellSimulation};

/// The largest relative difference, at any element, between the thickness a solve used and
/// the one the projection after it gives, below which a step's solve and projection agree
/// ([`ShellSimulation::step_inner`]); the tighter [`THICKNESS_COUPLING_RELATIVE`] applies
/// where the step changes the thickness little.
pub(crate) const THICKNESS_COUPLING_TOLERANCE: f64 = 1e-3;

/// The disagreement a step's solve and projection may keep, relative to the largest change
/// of the thickness over the step ([`ShellSimulation::step_inner`]): near rest, where a step
/// changes the thickness by little, a fixed tolerance would leave a disagreement as large as
/// the change itself, which the next step's extrapolation then amplifies into a slowly
/// decaying ringing.
pub(crate) const THICKNESS_COUPLING_RELATIVE: f64 = 1e-2;

/// The most solves of one (sub-)step with the thickness coupled to the projection (the first
/// and the corrections; [`ShellSimulation::step_inner`]).
pub(crate) const MAX_THICKNESS_PASSES: usize = 8;

use crate::ShellMaterial;

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// One sub-step of `dt` from `time` (of step `step`, for the errors), from `x_prev`: the
    /// implicit solve, the thickness refresh and the projection, the velocities, the state
    /// check (which sets `gas_volume`). Returns the solve's information (the Newton iterations
    /// of every pass summed) and the projection's iterations; on error the caller restores
    /// the state.
    ///
    /// The thickness the solve uses: the projection after it thins the wall by what the step
    /// stretched it (Eq. 24-28), so a solve with the thickness of `t_n` (Wang et al. 2015,
    /// Algorithm 1) lags one step behind, a splitting error of first order in `dt`. With
    /// [`ShellSimulation::set_thickness_prediction`] the solve uses the thickness extrapolated
    /// to `t_{n+1}` (after a step of the same size; the thickness of `t_n` otherwise), and
    /// when the projection's thickness differs from the one the solve used by more than
    /// [`THICKNESS_COUPLING_TOLERANCE`] or [`THICKNESS_COUPLING_RELATIVE`] times the step's
    /// own change of the thickness (relative, at any element) the step is solved again, at
    /// most [`MAX_THICKNESS_PASSES`] times in all: the solve and the projection then agree on
    /// the thickness at the end of the step. The first correction solves with the
    /// projection's thickness; later ones with a secant step on the fixed point `h = P(S(h))`
    /// (solve `S`, projection `P`; Anderson mixing of depth one), which converges where the
    /// plain iteration crawls (a wall whose thinning nearly balances its stretch, as near a
    /// rubber balloon's pressure maximum). A correction that fails, or that disagrees more
    /// than the pass before it, keeps the pass before it. Each
    /// projection starts from the thickness of `t_n`, as in the paper.
    pub(crate) fn step_inner(
        &mut self,
        step: usize,
        time: f64,
        dt: f64,
    ) -> Result<(StepInfo, usize), ShellError> {
        // `x_prev` holds `x_n`.
        let same_size = self.history.dt.is_some_and(|h| (h - dt).abs() <= 1e-9 * dt);
        self.v_start.copy_from_slice(&self.v);
        self.h_n.clone_from(&self.system.thickness);
        // A membrane's thickness follows its own stretch (nothing to couple).
        let coupled = self.projection.is_some()
            && self.thickness_prediction()
            && !self.system.material().thickness_follows_stretch();
        self.h_used.clone_from(&self.h_n);
        if coupled && same_size && self.history.thickness.len() == self.h_n.len() {
            for ((h, &now), &before) in self
                .h_used
                .iter_mut()
                .zip(&self.h_n)
                .zip(&self.history.thickness)
            {
                *h = (2.0 * now - before).clamp(0.5 * now, 2.0 * now);
            }
        }
        let mut total: Option<StepInfo> = None;
        let mut proj_iters = 0;
        // The last pass's end state (positions, projected thickness) and its disagreement.
        let mut kept: Option<(Vec<f64>, Vec<f64>, f64)> = None;
        // The last correction's thickness used and projected, for the secant step.
        let mut secant: Option<(Vec<f64>, Vec<f64>)> = None;
        for pass in 0..MAX_THICKNESS_PASSES {
            if pass > 0 {
                self.x.copy_from_slice(&self.x_prev);
                self.v.copy_from_slice(&self.v_start);
            }
            if coupled {
                self.system.thickness.clone_from(&self.h_used);
            }
            let solved = self.solve(step, time, dt);
            if coupled {
                self.system.thickness.clone_from(&self.h_n);
            }
            let projected = match solved {
                Ok(info) => self.project(step).map(|iters| (info, iters)),
                Err(e) => Err(e),
            };
            let (mut info, iters) = match (projected, &kept) {
                (Ok(done), _) => done,
                // A correction that fails keeps the pass before it (the step is not lost).
                (Err(_), Some((x, h, _))) => {
                    self.x.clone_from(x);
                    self.system.thickness.clone_from(h);
                    break;
                }
                (Err(e), None) => return Err(e),
            };
            proj_iters += iters;
            if let Some(before) = &total {
                info.newton_iterations += before.newton_iterations;
                info.line_search_cuts += before.line_search_cuts;
                info.regularized_solves += before.regularized_solves;
                info.factorizations += before.factorizations;
                let mut linear = before.linear_iterations.clone();
                linear.append(&mut info.linear_iterations);
                info.linear_iterations = linear;
            }
            total = Some(info);
            if !coupled {
                break;
            }
            let off = largest_relative_difference(&self.system.thickness, &self.h_used);
            if let Some((x, h, before)) = &kept
                && (off.is_nan() || off >= *before)
            {
                // The corrections do not converge here (the thinning feeds the stretch faster
                // than the step resolves): keep the pass before.
                self.x.clone_from(x);
                self.system.thickness.clone_from(h);
                break;
            }
            let change = largest_relative_difference(&self.system.thickness, &self.h_n);
            if off.is_nan()
                || off <= THICKNESS_COUPLING_TOLERANCE.min(THICKNESS_COUPLING_RELATIVE * change)
                || pass + 1 == MAX_THICKNESS_PASSES
            {
                break;
            }
            kept = Some((self.x.clone(), self.system.thickness.clone(), off));
            let next = secant_thickness(
                &self.h_used,
                &self.system.thickness,
                secant.as_ref(),
                &self.h_n,
            );
            secant = Some((
                std::mem::replace(&mut self.h_used, next),
                self.system.thickness.clone(),
            ));
            self.system.thickness.clone_from(&self.h_n);
        }
        let info = total.expect("at least one pass");
        // Algorithm 1, lines 11-12.
        for ((v, x), x0) in self.v.iter_mut().zip(&self.x).zip(&self.x_prev) {
            *v = (x - x0) / dt;
        }
        self.gas_volume = self.check_state(step, time)?;
        // The accepted step's start becomes the history (`h_{n-1}`).
        self.history.thickness.clone_from(&self.h_n);
        self.history.dt = Some(dt);
        Ok((info, proj_iters))
    }

    /// The implicit solve of one (sub-)step of `dt` from `self.x`, `self.v` at `time`, on the
    /// shell wrapped by the anchor and pin decorators (errors name step `step`).
    fn solve(&mut self, step: usize, time: f64, dt: f64) -> Result<StepInfo, ShellError> {
        let gravity = self.integrator.params().gravity;
        let integrator = &mut self.integrator;
        let (x, v) = (&mut self.x, &mut self.v);
        if self.pins.active() {
            let pins = &mut self.pins;
            pins.prepare(v, &self.external_forces, gravity);
            let external = (!pins.external.is_empty()).then_some(&pins.external[..]);
            if self.anchor_springs.is_empty() {
                let mut system = Pinned::new(&mut self.system, &mut pins.dofs)
                    .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            } else {
                let mut anchored = Anchored::new(&mut self.system, &self.anchor_springs)
                    .map_err(|e| ShellError::from_decorator("anchor_springs", e))?;
                let mut system = Pinned::new(&mut anchored, &mut pins.dofs)
                    .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        } else {
            let external = (!self.external_forces.is_empty()).then_some(&self.external_forces[..]);
            if self.anchor_springs.is_empty() {
                integrator.step(&mut self.system, time, dt, x, v, external)
            } else {
                let mut system = Anchored::new(&mut self.system, &self.anchor_springs)
                    .map_err(|e| ShellError::from_decorator("anchor_springs", e))?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        }
        .map_err(|source| ShellError::Integrate { step, time, source })
    }

    /// The thickness refresh and the shell-volume projection (Eq. 24-28, Algorithm 2) after a
    /// solve; returns the projection's iterations.
    fn project(&mut self, step: usize) -> Result<usize, ShellError> {
        // A membrane's thickness is `H / (l1 l2)` of the new positions (a no-op for the
        // three-prism, whose thickness only the projection moves).
        self.system.refresh_thickness(&self.x);
        let Some(proj) = &mut self.projection else {
            return Ok(0);
        };
        let (triangles, thickness) = self.system.triangles_and_thickness_mut();
        let input = ShellProjectionInput {
            triangles,
            vertex_inverse_mass: if self.pins.active() {
                &self.pins.vertex_inverse_mass
            } else {
                &self.vertex_inv_mass
            },
            element_inverse_mass: &self.element_inv_mass,
            rest_shell_volume: self.rest_shell_volume,
            rest_element_volumes: &self.rest_element_volumes,
        };
        let started = std::time::Instant::now();
        let projected = proj.project(&input, &mut self.x, thickness);
        self.projection_ms += started.elapsed().as_secs_f64() * 1e3;
        let pi = projected.map_err(|source| ShellError::Projection { step, source })?;
        self.system.refresh_thickness(&self.x);
        Ok(pi.iterations)
    }

    /// Checks the state after a (sub-)step and returns the enclosed gas volume.
    pub(crate) fn check_state(&self, step: usize, time: f64) -> Result<f64, ShellError> {
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("position of vertex {}", i / 3),
                detail: "became NaN or infinite; reduce `dt`".into(),
            });
        }
        if let Some((e, h)) = self
            .system
            .thickness
            .iter()
            .enumerate()
            .find(|(_, h)| !(h.is_finite() && **h > 0.0))
        {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("thickness of element {e}"),
                detail: format!(
                    "{h:e} m is not positive; the element inverted or degenerated; reduce `dt` or the pressure"
                ),
            });
        }
        let vol =
            balloon_gas::enclosed_volume(&self.x, self.system.triangles()).unwrap_or(f64::NAN);
        // A surface that turned inside out (or a volume that is not a number) is a numerical
        // failure of the step, retried at a smaller sub-step; only growth beyond the runaway
        // factor is the physical runaway, which is not.
        if !(vol.is_finite() && vol > 0.0) {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: "gas volume".into(),
                detail: format!(
                    "{vol:e} m^3 (rest {:e} m^3) is not positive: the surface turned inside out or tangled; reduce `dt`",
                    self.rest_gas_volume
                ),
            });
        }
        if vol >= RUNAWAY_VOLUME_FACTOR * self.rest_gas_volume {
            return Err(ShellError::RunawayVolume {
                step,
                time,
                volume: vol,
                rest_volume: self.rest_gas_volume,
            });
        }
        Ok(vol)
    }
}

/// The largest `|h - u| / h` over the elements (`f64::max` skips a NaN; a non-finite state is
/// caught by the state check after the step).
fn largest_relative_difference(h: &[f64], u: &[f64]) -> f64 {
    h.iter()
        .zip(u)
        .map(|(h, u)| (h - u).abs() / h)
        .fold(0.0, f64::max)
}

/// The thickness the next correction of a step solves with, from the thickness `used` by the
/// last solve and the one `projected` after it (the fixed point `h = P(S(h))`): `projected`
/// itself after the first pass, then a secant step through the pass before, `(u0, p0)`,
/// `projected - gamma (projected - p0)` with `gamma` minimising `|r1 - gamma (r1 - r0)|`
/// over the residuals `r = P(S(u)) - u` (Anderson mixing of depth one), clamped to half and
/// twice the step's start thickness `start` as the extrapolation is.
fn secant_thickness(
    used: &[f64],
    projected: &[f64],
    before: Option<&(Vec<f64>, Vec<f64>)>,
    start: &[f64],
) -> Vec<f64> {
    let Some((u0, p0)) = before else {
        return projected.to_vec();
    };
    let (mut rd, mut dd) = (0.0, 0.0);
    for i in 0..used.len() {
        let r1 = projected[i] - used[i];
        let d = r1 - (p0[i] - u0[i]);
        rd += r1 * d;
        dd += d * d;
    }
    let gamma = if dd > 0.0 && (rd / dd).is_finite() {
        rd / dd
    } else {
        0.0
    };
    projected
        .iter()
        .zip(p0)
        .zip(start)
        .map(|((p1, p0), h)| (p1 - gamma * (p1 - p0)).clamp(0.5 * h, 2.0 * h))
        .collect()
}
