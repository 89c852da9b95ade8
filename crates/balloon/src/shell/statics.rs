//! The static rest shape of a shell balloon: [`ShellSimulation::solve_static`].
//!
//! The equilibrium minimises the static energy `W_elastic(x) + W_gas(x) - f_ext . x` (seed 000,
//! elastic energy Eq. 6-8, gas Eq. 12-17) with the generic
//! [`balloon_integrate::statics::StaticSolver`] (Newton, Levenberg-Marquardt mass shift, Armijo
//! line search, load continuation). Three ways to hold the gas ([`StaticControl`]):
//!
//! * **given amount** (the simulation's ideal gas or pump, the amount at the current time):
//!   `W_gas = -p0 V0 ln V + p_ambient V` (Eq. 14 integrated);
//! * **given pressure** (the simulation's constant-pressure gas): `W_gas = -(p - p_ambient) V`;
//! * **given volume** ([`StaticControl::Volume`]): the constraint `V(x) = V_target` with the
//!   gauge pressure as its Lagrange multiplier `lambda`, by an augmented Lagrangian
//!   `W_elastic - lambda (V - V_t) + rho/2 (V - V_t)^2`: each inner solve is the energy of a
//!   gas with `p_gauge(V) = lambda - rho (V - V_t)` and `dp/dV = -rho` (the rank-1 tangent of
//!   Eq. 16-17, solved by Sherman-Morrison like any gas), followed by the multiplier update
//!   `lambda <- lambda - rho (V - V_t)`. `rho` starts at 100 times the shell's own volume
//!   stiffness along `dV/dx` (`g^T K g / |g|^4` at the start shape), so the multiplier gains
//!   about two digits per update; it grows tenfold when an update gains less than one.
//!   `lambda` starts at the gauge pressure that balances the elastic forces of the start shape
//!   (`-f_e . g / |g|^2`): along a continuation the previous point's pressure, so the first
//!   inner solve starts on the branch (the target volume is then reached by load continuation
//!   from the start volume). The reported pressure is `lambda` at the converged volume. Past a
//!   pressure maximum (a limit point of the membrane) this control stays on the branch, where
//!   pressure control snaps (`docs/membranes.md` section 9).
//!
//! The pressure tangent includes the follower term `-(p - p_ambient) d^2V/dx^2` by default, so
//! the Hessian is exact and Newton converges quadratically (the shift absorbs its
//! indefiniteness).
//!
//! # Thickness at rest
//!
//! The rule that holds at the returned equilibrium: **the shape is a static equilibrium at the
//! thickness `h*`, and `h*` is what the simulation's shell-volume projection (Algorithm 2,
//! Eq. 24-28, or the projector set on the builder) gives for that shape**, i.e. projecting the
//! result again changes the thickness by less than [`StaticOptions::thickness_tolerance`]
//! (relative). It is reached by a fixed-point iteration on `h = G(h)`, `G` = solve at `h`,
//! project the solution (keeping the projection's thickness and discarding its small position
//! correction, so the shape stays an exact equilibrium). The multiplier update of the volume
//! control shares this loop. Without a projector the thickness stays the current one.
//!
//! The loop is made cheap three ways, none of which weakens the rule above:
//!
//! * **Inexact outer iterations.** A solve at a thickness that is still moving need not be
//!   exact: the first solve is asked for a relative residual of `1e-3` (or the final tolerance
//!   if looser), each later one for `0.1` times the relative thickness change of the previous
//!   projection, clamped to `[0.1 thickness_tolerance, 1e-3]` (under volume control never looser
//!   than the final tolerance). The loop stops only after a solve at least as tight as
//!   [`StaticParams::tolerance`] whose projection changes the thickness by at most
//!   `thickness_tolerance`: the returned shape is that solve's equilibrium, the returned
//!   thickness that projection's.
//! * **Anderson acceleration** (type II, depth 3) of the thickness fixed point, in the
//!   thickness relative to its first value, with safeguards (the plain update `G(h)` when the
//!   fixed-point residual grew, the least-squares problem is singular, or the extrapolation
//!   would move a thickness by more than half its plain update's value): the map is nearly
//!   one-dimensional (the global projection moves every thickness along one pattern), so it
//!   converges in a few iterations where the plain iteration contracts by about 3 per
//!   iteration (15 iterations on the peer sphere).
//! * **Warm starts.** Each solve starts from the previous equilibrium with the previous solve's
//!   final Levenberg-Marquardt shift ([`StaticSolver::set_warm_start`]) and keeps the linear
//!   solver's factorisation (`balloon_integrate::statics`, "Reused factorisations"). After an
//!   extrapolated thickness it starts instead from the kept equilibria combined with the
//!   extrapolation's own weights (to first order the equilibrium at that thickness; the last
//!   equilibrium if the combination inverts an element): on the peer sphere the solves of
//!   outer iterations 3-5 then end 100-6000 times below their residuals without it after their
//!   one Newton iteration each, and the last solve needs none (7 outer iterations and 11
//!   Newton iterations instead of 8 and 14; `OUTER_LOG=1 cargo run --release -p
//!   balloon-benches --example static_profile`).
//!
//! With the follower term the Newton matrix is assembled from blocks only: each triangle's
//! block of `-(p - p_ambient) d^2V/dx^2` is added to its element stiffness block (no triplet
//! list).
//!
//! Anchor springs are not part of the static energy: a simulation with anchor springs set is
//! refused. External forces ([`ShellSimulation::set_external_forces`]) are included, scaled
//! with the gas load during continuation.

use std::time::Instant;

use super::ShellMaterial;
use balloon_gas::GasModel;
use balloon_integrate::ForceSystem;
use balloon_integrate::decorators::Pinned;
use balloon_integrate::statics::{PhaseTimes, StaticError, StaticInfo, StaticParams, StaticSolver};
use balloon_shell::statics::{GasTerm, StaticShell};
use serde::{Deserialize, Serialize};

use super::{ShellError, ShellSimulation};
use balloon_constraint::projector::ShellProjectionInput;

/// How the gas is held in a static solve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StaticControl {
    /// The simulation's own gas model at the current time: a given amount (ideal gas, pump)
    /// or a given pressure (constant pressure).
    #[default]
    Gas,
    /// A given enclosed volume, m^3; the gauge pressure is its Lagrange multiplier.
    Volume {
        /// The target gas volume, m^3 (positive).
        target: f64,
    },
}

/// Options of [`ShellSimulation::solve_static`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StaticOptions {
    /// How the gas is held.
    pub control: StaticControl,
    /// The Newton solver's parameters (tolerance, iterations per load stage, linear solver,
    /// shifts, continuation).
    pub solver: StaticParams,
    /// Include the pressure follower term in the tangent (default `true`: the exact Hessian).
    pub follower_term: bool,
    /// Most outer iterations (thickness fixed point and multiplier updates; default 60).
    pub max_outer_iterations: usize,
    /// Relative thickness change of one projection below which the thickness is at its fixed
    /// point (default `1e-8`).
    pub thickness_tolerance: f64,
    /// Relative volume error `|V - V_t| / V_t` at which the volume control is met (default
    /// `1e-8`).
    pub volume_tolerance: f64,
}

impl Default for StaticOptions {
    fn default() -> Self {
        Self {
            control: StaticControl::Gas,
            solver: StaticParams::default(),
            follower_term: true,
            max_outer_iterations: 60,
            thickness_tolerance: 1e-8,
            volume_tolerance: 1e-8,
        }
    }
}

/// What [`ShellSimulation::solve_static`] found.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticReport {
    /// Whether the equilibrium, the thickness fixed point and the volume target were all met
    /// (always `true` for a returned report; failures are errors).
    pub converged: bool,
    /// Relative Newton residual of the last solve (the dynamic Newton's measure).
    pub relative_residual: f64,
    /// Newton iterations over all solves.
    pub newton_iterations: usize,
    /// Outer iterations (solves).
    pub outer_iterations: usize,
    /// Load-continuation stages over all solves (1 per solve when no continuation was
    /// needed).
    pub load_steps: usize,
    /// Line-search cuts over all solves.
    pub line_search_cuts: usize,
    /// Enclosed gas volume, m^3.
    pub gas_volume: f64,
    /// Gauge pressure, Pa (the multiplier under volume control).
    pub gauge_pressure: f64,
    /// `|V - V_t| / V_t` under volume control (0 otherwise).
    pub volume_error: f64,
    /// Relative thickness change of the last projection.
    pub thickness_change: f64,
    /// Smallest element area over its rest area.
    pub min_area_stretch: f64,
    /// Largest element area over its rest area.
    pub max_area_stretch: f64,
    /// Mean thickness, m.
    pub thickness_mean: f64,
    /// Smallest thickness, m.
    pub thickness_min: f64,
    /// Largest thickness, m.
    pub thickness_max: f64,
    /// Shell material volume over its rest value.
    pub shell_volume_ratio: f64,
    /// Wall-clock time, ms.
    pub solve_ms: f64,
    /// Numeric factorisations over all solves.
    #[serde(default)]
    pub factorizations: usize,
    /// Linear-solver iterations over all solves.
    #[serde(default)]
    pub linear_iterations: usize,
    /// Wall-clock time per phase over all solves and projections.
    #[serde(default)]
    pub times: PhaseTimes,
    /// One record per outer iteration.
    #[serde(default)]
    pub outer: Vec<OuterRecord>,
    /// The last solve's details (energies, residuals, shift, factorisations).
    pub last_solve: StaticInfo,
}

/// One outer iteration of [`ShellSimulation::solve_static`] (module docs, "Thickness at
/// rest").
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OuterRecord {
    /// The relative residual the Newton solve was asked for.
    pub tolerance: f64,
    /// The relative residual it reached.
    pub relative_residual: f64,
    /// Newton iterations of the solve.
    pub newton_iterations: usize,
    /// Linear solves of the solve retried with a larger shift (indefinite matrix).
    pub regularized_solves: usize,
    /// Numeric factorisations of the solve.
    pub factorizations: usize,
    /// Relative thickness change of the projection of its result.
    pub thickness_change: f64,
    /// Whether the next thickness was extrapolated (Anderson) rather than the projection's.
    pub accelerated: bool,
}

/// The loosest relative residual an outer solve is asked for (the first one, and any while the
/// thickness changes by more than `LOOSE_TOLERANCE / INEXACT_FACTOR`).
const LOOSE_TOLERANCE: f64 = 1e-3;

/// An outer solve is asked for the relative residual `INEXACT_FACTOR` times the relative
/// thickness change of the previous projection (no tighter than `INEXACT_FACTOR` times the
/// thickness tolerance or the final tolerance, whichever is smaller; no looser than
/// [`LOOSE_TOLERANCE`] or the final tolerance, whichever is larger).
const INEXACT_FACTOR: f64 = 0.1;

/// Depth (previous iterates kept) of the Anderson acceleration of the thickness fixed point.
const ANDERSON_DEPTH: usize = 3;

/// Anderson acceleration (type II, depth [`ANDERSON_DEPTH`]) of the thickness fixed point
/// `h = G(h)`, `G` = solve at `h`, project, keep the projection's thickness (module docs). In the
/// scaled variables `y_e = h_e / s_e` (`s` the first thickness seen), with `g_k = G(y_k)` and
/// `f_k = g_k - y_k`, the next iterate is `y_{k+1} = g_k - dG gamma`, `gamma` minimising
/// `|f_k - dF gamma|` over the differences `dF`, `dG` of the kept iterates. Safeguards: the plain
/// update `g_k` (and a fresh history) when the residual grew, when the least-squares problem is
/// singular, or when the extrapolation would move any thickness by more than half the plain
/// update's value from it.
#[derive(Debug, Default)]
struct ThicknessAcceleration {
    scale: Vec<f64>,
    /// `(y_j, g_j, x_j)`, oldest first, at most `ANDERSON_DEPTH + 1`; `x_j` the equilibrium
    /// solved at `y_j` (whose projection gave `g_j`).
    history: std::collections::VecDeque<Iterate>,
}

/// One iterate of [`ThicknessAcceleration`]: scaled thickness, its scaled image, equilibrium.
type Iterate = (Vec<f64>, Vec<f64>, Vec<f64>);

impl ThicknessAcceleration {
    /// Sets `h` (the thickness the last solve, at equilibrium `x`, was at) to the next
    /// thickness to solve at, from `projected = G(h)`; returns whether the update was
    /// extrapolated. An extrapolated update also moves `x` to the same combination of the
    /// kept equilibria, `x_k - sum_j gamma_j (x_{j+1} - x_j)`: to first order the equilibrium
    /// at the extrapolated thickness, the next solve's start (a plain update keeps `x`).
    fn next(&mut self, h: &mut [f64], projected: Vec<f64>, x: &mut [f64]) -> bool {
        if self.scale.len() != h.len() {
            self.scale = h.iter().map(|v| v.abs().max(f64::MIN_POSITIVE)).collect();
            self.history.clear();
        }
        let y: Vec<f64> = h.iter().zip(&self.scale).map(|(h, s)| h / s).collect();
        let g: Vec<f64> = projected
            .iter()
            .zip(&self.scale)
            .map(|(h, s)| h / s)
            .collect();
        let residual =
            |y: &[f64], g: &[f64]| -> Vec<f64> { g.iter().zip(y).map(|(g, y)| g - y).collect() };
        let f = residual(&y, &g);
        if let Some(last) = self.history.back()
            && norm(&f) >= norm(&residual(&last.0, &last.1))
        {
            self.history.clear();
        }
        self.history.push_back((y, g, x.to_vec()));
        if self.history.len() > ANDERSON_DEPTH + 1 {
            self.history.pop_front();
        }
        if self.history.len() < 2 {
            h.copy_from_slice(&projected);
            return false;
        }
        match self.extrapolate() {
            Some((next, gamma)) => {
                for ((h, y), s) in h.iter_mut().zip(&next).zip(&self.scale) {
                    *h = y * s;
                }
                let predicted = self.predict_shape(&gamma);
                if predicted.iter().all(|v| v.is_finite()) {
                    x.copy_from_slice(&predicted);
                }
                true
            }
            None => {
                // Safeguard: the plain update, which starts a new history.
                self.history.drain(..self.history.len() - 1);
                h.copy_from_slice(&projected);
                false
            }
        }
    }

    /// `x_k - dX gamma`: the equilibria combined with the weights of [`Self::extrapolate`].
    fn predict_shape(&self, gamma: &nalgebra::DVector<f64>) -> Vec<f64> {
        let m = self.history.len() - 1;
        let mut x = self.history[m].2.clone();
        for (j, c) in gamma.iter().enumerate() {
            let (a, b) = (&self.history[j].2, &self.history[j + 1].2);
            for ((x, a), b) in x.iter_mut().zip(a).zip(b) {
                *x -= c * (b - a);
            }
        }
        x
    }

    /// `g_k - dG gamma` and `gamma` from the history (at least two entries; the last is
    /// iterate `k`), or `None` (safeguards).
    fn extrapolate(&self) -> Option<(Vec<f64>, nalgebra::DVector<f64>)> {
        let m = self.history.len().checked_sub(1).filter(|m| *m > 0)?;
        let k = &self.history[m];
        let fk: Vec<f64> = k.1.iter().zip(&k.0).map(|(g, y)| g - y).collect();
        // Columns j: f_{j+1} - f_j and g_{j+1} - g_j.
        let mut df = Vec::with_capacity(m);
        let mut dg = Vec::with_capacity(m);
        for j in 0..m {
            let (a, b) = (&self.history[j], &self.history[j + 1]);
            df.push(
                (0..fk.len())
                    .map(|i| (b.1[i] - b.0[i]) - (a.1[i] - a.0[i]))
                    .collect::<Vec<f64>>(),
            );
            dg.push((0..fk.len()).map(|i| b.1[i] - a.1[i]).collect::<Vec<f64>>());
        }
        let ata = nalgebra::DMatrix::from_fn(m, m, |a, b| dot(&df[a], &df[b]));
        let atb = nalgebra::DVector::from_fn(m, |a, _| dot(&df[a], &fk));
        let largest = ata.diagonal().max();
        if !(largest > 0.0 && largest.is_finite()) {
            return None;
        }
        let gamma = ata.svd(true, true).solve(&atb, 1e-12 * largest).ok()?;
        if !gamma.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut next = k.1.clone();
        for (c, col) in gamma.iter().zip(&dg) {
            for (n, d) in next.iter_mut().zip(col) {
                *n -= c * d;
            }
        }
        let safe = next
            .iter()
            .zip(&k.1)
            .all(|(n, g)| n.is_finite() && *n > 0.0 && (n - g).abs() <= 0.5 * g.abs());
        safe.then_some((next, gamma))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// The relative change `max_e |a_e - b_e| / b_e`.
fn max_relative_change(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).abs() / b.abs().max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max)
}

fn triangle_area(x: &[f64], t: &[usize; 3]) -> f64 {
    let p = |v: usize| nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
    0.5 * (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0]))).norm()
}

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Solves for the static rest shape directly (module docs of `balloon::shell::statics`)
    /// from the current shape and leaves the simulation there: positions at the equilibrium,
    /// velocities zero, thickness at the projection's fixed point; time and the gas model are
    /// unchanged. On error the simulation is left as it was.
    ///
    /// ```
    /// use balloon::gas::GasKind;
    /// use balloon::shell::ShellBalloon;
    /// use balloon::shell::statics::StaticOptions;
    /// let mesh = balloon::mesh::generate::icosphere(0.1, 2).unwrap();
    /// let mut sim = ShellBalloon::new(mesh)
    ///     .with_gas(GasKind::Ideal)
    ///     .with_gauge_pressure(3000.0)
    ///     .build()
    ///     .unwrap();
    /// let report = sim.solve_static(&StaticOptions::default())?;
    /// assert!(report.converged && report.relative_residual <= 1e-6);
    /// assert!(sim.gas_volume() > sim.rest_gas_volume());
    /// # Ok::<(), balloon::shell::ShellError>(())
    /// ```
    pub fn solve_static(&mut self, options: &StaticOptions) -> Result<StaticReport, ShellError> {
        let started = Instant::now();
        if !self.anchor_springs.is_empty() {
            return Err(ShellError::InvalidParameter {
                name: "anchor springs",
                value: format!("{} springs", self.anchor_springs.len()),
                reason: "the static solve has no energy for anchor springs; remove them first"
                    .into(),
            });
        }
        for (name, v) in [
            ("thickness tolerance", options.thickness_tolerance),
            ("volume tolerance", options.volume_tolerance),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ShellError::InvalidParameter {
                    name,
                    value: v.to_string(),
                    reason: "must be positive and finite".into(),
                });
            }
        }
        let saved = (self.x.clone(), self.system.thickness.clone());
        let result = self.static_loop(options, started);
        if result.is_err() {
            (self.x, self.system.thickness) = saved;
        }
        result
    }

    fn static_loop(
        &mut self,
        options: &StaticOptions,
        started: Instant,
    ) -> Result<StaticReport, ShellError> {
        let time = self.time;
        // Pinned vertices: their external forces are dropped and their forces cancelled (no
        // gravity in the static solve), so they stay where they are (`pins.rs`).
        let pinned = self.pins.active();
        if pinned {
            let mut v = vec![0.0; self.x.len()];
            self.pins.prepare(&mut v, &self.external_forces, [0.0; 3]);
        }
        let external = if pinned {
            (!self.pins.external.is_empty()).then(|| self.pins.external.clone())
        } else {
            (!self.external_forces.is_empty()).then(|| self.external_forces.clone())
        };
        let mut solver = StaticSolver::new(options.solver)
            .map_err(|source| ShellError::Static { outer: 0, source })?;
        // Each outer solve starts from the last one's equilibrium and shift.
        solver.set_warm_start(true);
        let mut x = self.x.clone();
        let mut report = StaticReport::default();
        let start_volume = balloon_gas::enclosed_volume(&x, self.system.triangles())?;
        let mut gas = match options.control {
            StaticControl::Gas => GasTerm::Own,
            StaticControl::Volume { target } => {
                if !(target.is_finite() && target > 0.0) {
                    return Err(ShellError::InvalidParameter {
                        name: "volume",
                        value: target.to_string(),
                        reason: "the target gas volume must be positive".into(),
                    });
                }
                let (stiffness, balance) = self.volume_stiffness(time, &x)?;
                GasTerm::Volume {
                    lambda: balance,
                    rho: 100.0 * stiffness,
                    start: start_volume,
                    target,
                }
            }
        };
        let mut last_error = f64::INFINITY;
        let max_outer = options.max_outer_iterations.max(1);
        let final_tolerance = options.solver.tolerance;
        let volume_control = matches!(gas, GasTerm::Volume { .. });
        // The inexact outer loop (module docs): loose while the thickness still moves.
        let mut tolerance = if self.projection.is_some() {
            final_tolerance.max(LOOSE_TOLERANCE)
        } else {
            final_tolerance
        };
        let mut acceleration = ThicknessAcceleration::default();
        for outer in 0..max_outer {
            if volume_control {
                tolerance = tolerance.min(final_tolerance);
            }
            solver
                .set_params(StaticParams {
                    tolerance,
                    ..*solver.params()
                })
                .map_err(|source| ShellError::Static { outer, source })?;
            let (info, gauge, volume) = {
                let mut shell = StaticShell::new(&mut self.system, gas, options.follower_term);
                let info = if pinned {
                    let mut held = Pinned::new(&mut shell, &mut self.pins.dofs)?;
                    solver.solve_with_continuation(&mut held, time, &mut x, external.as_deref())
                } else {
                    solver.solve_with_continuation(&mut shell, time, &mut x, external.as_deref())
                }
                .map_err(|source| ShellError::Static { outer, source })?;
                (info, shell.gauge_pressure(), shell.volume())
            };
            report.outer_iterations = outer + 1;
            report.newton_iterations += info.iterations;
            report.load_steps += info.load_steps;
            report.line_search_cuts += info.line_search_cuts;
            report.factorizations += info.factorizations;
            report.linear_iterations += info.linear_iterations;
            report.times += info.times;
            report.relative_residual = info.relative_residual;
            let mut record = OuterRecord {
                tolerance,
                relative_residual: info.relative_residual,
                newton_iterations: info.iterations,
                regularized_solves: info.regularized_solves,
                factorizations: info.factorizations,
                ..Default::default()
            };
            report.last_solve = info;
            report.gauge_pressure = gauge;
            report.gas_volume = volume;
            // The volume control's multiplier update (from now on the target is reached at
            // factor 1 directly: start = target).
            let mut volume_met = true;
            if let GasTerm::Volume {
                lambda,
                rho,
                target,
                ..
            } = gas
            {
                let c = volume - target;
                report.volume_error = c.abs() / target;
                volume_met = report.volume_error <= options.volume_tolerance;
                let new_rho = if report.volume_error > 0.1 * last_error {
                    10.0 * rho
                } else {
                    rho
                };
                last_error = report.volume_error;
                gas = GasTerm::Volume {
                    lambda: lambda - rho * c,
                    rho: new_rho,
                    start: target,
                    target,
                };
                if volume_met {
                    // The multiplier at the converged volume is the pressure.
                    report.gauge_pressure = gauge;
                }
            }
            // An incompressible membrane's thickness follows its stretch (h = H / (l1 l2)) at
            // the solution just found (not the start shape `self.x`, set after the loop).
            self.system.refresh_thickness(&x);
            // The thickness rule at rest: project the equilibrium, keep the thickness.
            report.thickness_change = 0.0;
            if let Some(proj) = &mut self.projection {
                let input = ShellProjectionInput {
                    triangles: self.system.triangles(),
                    vertex_inverse_mass: if pinned {
                        &self.pins.vertex_inverse_mass
                    } else {
                        &self.vertex_inv_mass
                    },
                    element_inverse_mass: &self.element_inv_mass,
                    rest_shell_volume: self.rest_shell_volume,
                    rest_element_volumes: &self.rest_element_volumes,
                };
                let mut xp = x.clone();
                let mut h = self.system.thickness.clone();
                let projecting = Instant::now();
                let projected = proj.project(&input, &mut xp, &mut h);
                report.times.projection_ms += projecting.elapsed().as_secs_f64() * 1e3;
                projected.map_err(|source| ShellError::Projection {
                    step: self.step,
                    source,
                })?;
                if let Some((e, bad)) = h
                    .iter()
                    .enumerate()
                    .find(|(_, h)| !(h.is_finite() && **h > 0.0))
                {
                    return Err(ShellError::Diverged {
                        step: self.step,
                        time,
                        quantity: format!("thickness of element {e}"),
                        detail: format!(
                            "{bad:e} m after projecting the static equilibrium; lower the load"
                        ),
                    });
                }
                report.thickness_change = max_relative_change(&h, &self.system.thickness);
                record.thickness_change = report.thickness_change;
                let converged = volume_met
                    && report.thickness_change <= options.thickness_tolerance
                    && tolerance <= final_tolerance;
                if converged {
                    self.system.thickness = h;
                } else {
                    let equilibrium = x.clone();
                    record.accelerated = acceleration.next(&mut self.system.thickness, h, &mut x);
                    // The predicted start must be a state the shell can be evaluated at (no
                    // inverted element, a positive volume); else the last equilibrium.
                    let valid = self.system.elastic_energy(&x).is_finite()
                        && balloon_gas::enclosed_volume(&x, self.system.triangles())
                            .is_ok_and(|v| v.is_finite() && v > 0.0);
                    if !valid {
                        x = equilibrium;
                    }
                }
                // The next solve need not be much more accurate than the thickness it is
                // solved at (module docs), but it must reach the final tolerance once the
                // thickness has settled (else a thickness tolerance above
                // `final_tolerance / INEXACT_FACTOR` could never converge), and a final
                // tolerance above `LOOSE_TOLERANCE` is never tightened.
                let ceiling = LOOSE_TOLERANCE.max(final_tolerance);
                let floor = (INEXACT_FACTOR * options.thickness_tolerance).min(final_tolerance);
                tolerance = (INEXACT_FACTOR * report.thickness_change).clamp(floor, ceiling);
            }
            report.outer.push(record);
            if volume_met
                && report.thickness_change <= options.thickness_tolerance
                && record.tolerance <= final_tolerance
            {
                self.finish_static(x, &mut report, started);
                return Ok(report);
            }
        }
        Err(ShellError::StaticNotConverged {
            outer_iterations: report.outer_iterations,
            residual: report.relative_residual,
            thickness_change: report.thickness_change,
            volume_error: report.volume_error,
        })
    }

    /// The shell's volume stiffness along `g = dV/dx` at `x`, `g^T K g / |g|^4` (Pa/m^3), a
    /// positive floor when the shape has none; and the gauge pressure that balances the elastic
    /// forces `f_e` at `x` best in the least-squares sense, `-f_e . g / |g|^2` (Pa): at a
    /// previous equilibrium (the last point of a continuation) it is that point's pressure, so
    /// the multiplier starts where the branch is, at rest it is 0.
    fn volume_stiffness(&mut self, time: f64, x: &[f64]) -> Result<(f64, f64), ShellError> {
        let n = x.len();
        let mut f = vec![0.0; n];
        self.system
            .forces(time, x, &mut f)
            .map_err(|source| ShellError::Static {
                outer: 0,
                source: StaticError::System {
                    iteration: 0,
                    source,
                },
            })?;
        let g = self.system.gas.low_rank_term().vector.clone();
        // `f` holds the gas force `gauge * g` too (Eq. 15); remove it.
        let inner_gauge = self.system.gas.state().gauge_pressure;
        let fg: f64 = f.iter().zip(&g).map(|(a, b)| a * b).sum();
        let mut df = vec![0.0; n];
        self.system.add_elastic_differential(&g, &mut df);
        let gg: f64 = g.iter().map(|v| v * v).sum();
        let gkg: f64 = -g.iter().zip(&df).map(|(a, b)| a * b).sum::<f64>();
        let v = self.system.gas.state().volume;
        let k = gkg / (gg * gg);
        let balance = -(fg - inner_gauge * gg) / gg;
        // Floor: 1 Pa per 1% of the volume.
        let k = if k.is_finite() && k > 0.0 {
            k
        } else {
            100.0 / v
        };
        Ok((k, if balance.is_finite() { balance } else { 0.0 }))
    }

    fn finish_static(&mut self, x: Vec<f64>, report: &mut StaticReport, started: Instant) {
        self.x = x;
        self.v.iter_mut().for_each(|v| *v = 0.0);
        self.x_prev.copy_from_slice(&self.x);
        self.gas_volume = report.gas_volume;
        let th = &self.system.thickness;
        report.thickness_min = th.iter().copied().fold(f64::INFINITY, f64::min);
        report.thickness_max = th.iter().copied().fold(0.0, f64::max);
        report.thickness_mean = th.iter().sum::<f64>() / th.len().max(1) as f64;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for t in self.system.triangles() {
            let r = triangle_area(&self.x, t) / triangle_area(&self.rest_positions, t);
            lo = lo.min(r);
            hi = hi.max(r);
        }
        report.min_area_stretch = lo;
        report.max_area_stretch = hi;
        report.shell_volume_ratio = self.shell_volume() / self.rest_shell_volume;
        report.converged = true;
        report.solve_ms = started.elapsed().as_secs_f64() * 1e3;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gas::GasKind;
    use crate::shell::ShellBalloon;

    /// On an affine fixed point `h = A h + b` of two thicknesses with an affine equilibrium
    /// `x(h) = C h + d`, Anderson with two differences is exact: the extrapolated thickness is
    /// the fixed point, and the predicted start shape is the equilibrium there, `C h* + d`
    /// (the kept equilibria combined with the same weights); with one difference the shape
    /// moves; a plain update keeps it.
    #[test]
    fn extrapolated_thickness_comes_with_the_equilibrium_combined_alike() {
        let a = nalgebra::Matrix2::new(0.3, 0.1, -0.05, 0.4);
        let b = nalgebra::Vector2::new(0.7, 0.6);
        let c = nalgebra::Matrix3x2::new(1.0, 2.0, -0.5, 0.25, 3.0, -1.0);
        let d = nalgebra::Vector3::new(0.1, -0.2, 0.3);
        let fixed = (nalgebra::Matrix2::identity() - a).try_inverse().unwrap() * b;
        let shape = |h: &[f64]| {
            let x = c * nalgebra::Vector2::new(h[0], h[1]) + d;
            vec![x[0], x[1], x[2]]
        };
        let mut acc = ThicknessAcceleration::default();
        let mut h = vec![1.0, 1.0];
        let mut accelerated = Vec::new();
        for _ in 0..3 {
            let mut x = shape(&h);
            let g = a * nalgebra::Vector2::new(h[0], h[1]) + b;
            let solved_at = h.clone();
            let was = acc.next(&mut h, vec![g[0], g[1]], &mut x);
            accelerated.push(was);
            if accelerated.len() == 2 {
                // One difference: a first-order prediction, moved from the last equilibrium.
                assert!(was && x != shape(&solved_at));
            } else if was {
                let want = shape(&h);
                for i in 0..3 {
                    assert!((x[i] - want[i]).abs() <= 1e-12, "{i}: {x:?} vs {want:?}");
                }
            } else {
                assert_eq!(x, shape(&solved_at), "a plain update keeps the shape");
            }
        }
        assert_eq!(accelerated, [false, true, true]);
        // Two differences span the plane: the third iterate is the fixed point.
        assert!((h[0] - fixed[0]).abs() <= 1e-12 && (h[1] - fixed[1]).abs() <= 1e-12);
    }

    /// The thickness rule at rest, checked independently of the loop that reached it: the
    /// returned shape is an equilibrium of the shell's own forces at the returned thickness,
    /// and projecting the returned state again moves the thickness by less than the tolerance;
    /// the inexact, accelerated loop was exercised (a loose first solve, an extrapolated
    /// thickness), and its result is the thickness the plain fixed point converges to.
    #[test]
    fn the_rest_state_is_an_equilibrium_whose_projection_keeps_its_thickness() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 3).unwrap();
        let build = || {
            ShellBalloon::new(mesh.clone())
                .with_gas(GasKind::Ideal)
                .with_gauge_pressure(3000.0)
                .build()
                .unwrap()
        };
        let mut sim = build();
        let options = StaticOptions::default();
        let report = sim.solve_static(&options).unwrap();
        assert!(report.converged);
        assert!(
            report.outer[0].tolerance > options.solver.tolerance,
            "{report:?}"
        );
        assert!(report.outer.iter().any(|o| o.accelerated), "{report:?}");
        let last = report.outer.last().unwrap();
        assert!(last.tolerance <= options.solver.tolerance, "{last:?}");
        // The shell's own forces (elastic + the ideal gas at the current amount) at the result.
        let x = sim.x.clone();
        let mut f = vec![0.0; x.len()];
        sim.system.forces(sim.time, &x, &mut f).unwrap();
        let scale = sim.system.force_scale().unwrap();
        let relative = norm(&f) / scale;
        // The solve's tolerance at its thickness, plus what the last projection's change of at
        // most `thickness_tolerance` does to the elastic forces.
        assert!(
            relative <= options.solver.tolerance + 2.0 * options.thickness_tolerance,
            "relative residual {relative:e}"
        );
        // Project the returned state again.
        let input = ShellProjectionInput {
            triangles: sim.system.triangles(),
            vertex_inverse_mass: &sim.vertex_inv_mass,
            element_inverse_mass: &sim.element_inv_mass,
            rest_shell_volume: sim.rest_shell_volume,
            rest_element_volumes: &sim.rest_element_volumes,
        };
        let mut projector = sim.projection.clone().unwrap();
        let (mut xp, mut h) = (x.clone(), sim.system.thickness.clone());
        projector.project(&input, &mut xp, &mut h).unwrap();
        let change = max_relative_change(&h, &sim.system.thickness);
        assert!(
            change <= options.thickness_tolerance,
            "thickness change {change:e}"
        );
        // The plain fixed point (exact solves, no extrapolation: many outer iterations) ends at
        // the same thickness and shape.
        let mut plain = build();
        let mut h_plain = plain.system.thickness.clone();
        let mut x_plain = plain.x.clone();
        for _ in 0..60 {
            {
                let mut shell = StaticShell::new(&mut plain.system, GasTerm::Own, true);
                StaticSolver::new(options.solver)
                    .unwrap()
                    .solve(&mut shell, 0.0, &mut x_plain, None)
                    .unwrap();
            }
            let input = ShellProjectionInput {
                triangles: plain.system.triangles(),
                vertex_inverse_mass: &plain.vertex_inv_mass,
                element_inverse_mass: &plain.element_inv_mass,
                rest_shell_volume: plain.rest_shell_volume,
                rest_element_volumes: &plain.rest_element_volumes,
            };
            let mut xp = x_plain.clone();
            let proj = plain.projection.as_mut().unwrap();
            proj.project(&input, &mut xp, &mut h_plain).unwrap();
            let done = max_relative_change(&h_plain, &plain.system.thickness) <= 1e-10;
            plain.system.thickness.copy_from_slice(&h_plain);
            if done {
                break;
            }
        }
        assert!(max_relative_change(&sim.system.thickness, &h_plain) <= 1e-7);
        let d = x
            .iter()
            .zip(&x_plain)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(d <= 1e-7, "shape difference {d:e} m");
    }
}
