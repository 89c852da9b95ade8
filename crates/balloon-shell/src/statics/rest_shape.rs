//! The outer loop of the static rest shape, [`ShellSimulation::solve_static`] (the `statics`
//! module docs): inexact Newton solves of [`StaticShell`] at a thickness, the projection of
//! each equilibrium (the thickness fixed point, Anderson-accelerated), and the multiplier
//! update of the volume control.

use std::time::Instant;

use balloon_constraint::projector::ShellProjectionInput;
use balloon_gas::GasModel;
use balloon_integrate::ForceSystem;
use balloon_integrate::decorators::{Pinned, Pins};
use balloon_integrate::statics::{
    Anderson, AndersonParams, StabilityParams, StaticError, StaticParams, StaticSolver,
};

use super::{GasTerm, OuterRecord, StaticControl, StaticOptions, StaticReport, StaticShell};
use crate::{ShellError, ShellMaterial, ShellSimulation};

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

/// The Anderson acceleration of the thickness fixed point `h = G(h)`, `G` = solve at `h`,
/// project, keep the projection's thickness (the `statics` module docs): depth
/// [`ANDERSON_DEPTH`], in the thickness relative to its first value, every thickness kept
/// positive and within half its plain update's value; the equilibria follow as companions.
fn thickness_acceleration() -> Anderson {
    Anderson::new(AndersonParams {
        depth: ANDERSON_DEPTH,
        max_deviation: 0.5,
        positive: true,
    })
}

/// The relative change `max_e |a_e - b_e| / b_e`.
pub(crate) fn max_relative_change(a: &[f64], b: &[f64]) -> f64 {
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
    /// Solves for the static rest shape directly (the [`crate::statics`] module docs) from
    /// the current shape and leaves the simulation there: positions at the equilibrium,
    /// velocities zero, thickness at the projection's fixed point; time and the gas model are
    /// unchanged. On error the simulation is left as it was.
    ///
    /// ```
    /// use balloon_constraint::shell_volume::{ShellVolumeParams, ShellVolumeProjection};
    /// use balloon_gas::{IdealGas, PressureLoad};
    /// use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
    /// use balloon_material::{Lame, StVenantKirchhoff};
    /// use balloon_shell::statics::StaticOptions;
    /// use balloon_shell::{ShellSimulation, ShellSystem};
    ///
    /// let mesh = balloon_mesh::generate::icosphere(0.1, 2)?;
    /// let x = mesh.positions_flat();
    /// let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
    /// // An ideal gas 3 kPa over the atmosphere in a latex sphere, 0.3 mm thick.
    /// let gas = PressureLoad::new(IdealGas::try_new(104_325.0, v0)?)
    ///     .with_ambient_pressure(101_325.0)?
    ///     .with_follower_term(true);
    /// let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
    /// let thickness = vec![3e-4; mesh.num_triangles()];
    /// let system =
    ///     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
    /// let integrator = BackwardEuler::new(BackwardEulerParams::default())?;
    /// let projection = ShellVolumeProjection::new(ShellVolumeParams::default());
    /// let mut sim =
    ///     ShellSimulation::new(system, x, 950.0, integrator, Some(Box::new(projection)), 0.01, 10)?;
    /// let report = sim.solve_static(&StaticOptions::default())?;
    /// assert!(report.converged && report.relative_residual <= 1e-6);
    /// assert!(sim.gas_volume() > sim.rest_gas_volume());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solve_static(&mut self, options: &StaticOptions) -> Result<StaticReport, ShellError> {
        let started = Instant::now();
        if !self.anchor_springs.is_empty() {
            return Err(ShellError::InvalidParameter {
                name: "anchor_springs",
                value: format!("{} springs", self.anchor_springs.len()),
                reason: "the static solve has no energy for anchor springs; remove them first"
                    .into(),
            });
        }
        for (name, v) in [
            ("thickness_tolerance", options.thickness_tolerance),
            ("volume_tolerance", options.volume_tolerance),
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
        // A free body (nothing pinned, no external force): its rigid motions are removed from
        // the Newton directions (`StaticParams::remove_rigid_motions`).
        let free = !pinned && external.is_none();
        let mut solver = StaticSolver::new(StaticParams {
            remove_rigid_motions: options.solver.remove_rigid_motions || free,
            ..options.solver
        })
        .map_err(|source| ShellError::Static {
            outer: 0,
            newton_iterations: 0,
            source: Box::new(source),
        })?;
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
                        name: "target",
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
        let mut acceleration = thickness_acceleration();
        for outer in 0..max_outer {
            if volume_control {
                tolerance = tolerance.min(final_tolerance);
            }
            solver
                .set_params(StaticParams {
                    tolerance,
                    ..*solver.params()
                })
                .map_err(|source| ShellError::Static {
                    outer,
                    newton_iterations: report.newton_iterations,
                    source: Box::new(source),
                })?;
            let (info, gauge, volume) = {
                let mut shell = StaticShell::new(&mut self.system, gas, options.follower_term);
                let solved = if pinned {
                    let mut held = Pinned::new(&mut shell, &mut self.pins.dofs)
                        .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                    solver.solve_with_continuation(&mut held, time, &mut x, external.as_deref())
                } else {
                    solver.solve_with_continuation(&mut shell, time, &mut x, external.as_deref())
                };
                let info = match solved {
                    Ok(info) => info,
                    Err(mut source) => {
                        if matches!(source, StaticError::NoEquilibrium(_)) {
                            stalled_stability(
                                &mut solver,
                                &mut shell,
                                pinned.then_some(&mut self.pins.dofs),
                                time,
                                &mut source,
                            );
                        }
                        return Err(ShellError::Static {
                            outer,
                            newton_iterations: report.newton_iterations + solver.last_iterations(),
                            source: Box::new(source),
                        });
                    }
                };
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
                if options.stability {
                    let stability = {
                        let mut shell =
                            StaticShell::new(&mut self.system, gas, options.follower_term);
                        let params = StabilityParams {
                            rigid_modes: !pinned,
                            ..StabilityParams::default()
                        };
                        if pinned {
                            let fixed = self.pins.dofs.pinned_dofs().to_vec();
                            let mut held = Pinned::new(&mut shell, &mut self.pins.dofs)
                                .map_err(|e| ShellError::from_decorator("pinned_vertices", e))?;
                            solver.stability(&mut held, time, &x, &fixed, &params)
                        } else {
                            solver.stability(&mut shell, time, &x, &[], &params)
                        }
                        .map_err(|source| ShellError::Static {
                            outer,
                            newton_iterations: report.newton_iterations,
                            source: Box::new(source),
                        })?
                    };
                    report.stability = Some((&stability).into());
                }
                self.finish_static(x, &mut report, started);
                return Ok(report);
            }
        }
        Err(ShellError::StaticNotConverged {
            outer_iterations: report.outer_iterations,
            newton_iterations: report.newton_iterations,
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
                newton_iterations: 0,
                source: Box::new(StaticError::System {
                    iteration: 0,
                    source,
                }),
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

/// Fills the smallest eigenvalue of the stiffness at the stalled iterate into a
/// [`StaticError::NoEquilibrium`] (the evidence of a wrinkling or buckling wall); left `None`
/// when it cannot be computed.
fn stalled_stability<M: ShellMaterial, G: GasModel>(
    solver: &mut StaticSolver,
    shell: &mut StaticShell<'_, M, G>,
    pins: Option<&mut Pins>,
    time: f64,
    error: &mut StaticError,
) {
    let Some(x) = solver.stalled_iterate().map(<[f64]>::to_vec) else {
        return;
    };
    let params = StabilityParams {
        rigid_modes: pins.is_none(),
        ..StabilityParams::default()
    };
    let stability = match pins {
        Some(dofs) => {
            let fixed = dofs.pinned_dofs().to_vec();
            match Pinned::new(shell, dofs) {
                Ok(mut held) => solver.stability(&mut held, time, &x, &fixed, &params),
                Err(_) => return,
            }
        }
        None => solver.stability(shell, time, &x, &[], &params),
    };
    if let (Ok(s), StaticError::NoEquilibrium(stall)) = (stability, error) {
        stall.smallest_eigenvalue = Some(s.smallest_eigenvalue);
        stall.relative_eigenvalue = Some(s.relative_eigenvalue);
    }
}
