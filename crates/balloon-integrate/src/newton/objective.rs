//! What the Newton core minimises: the static energy `E(x) = W(x) - f_ext . x`, or the
//! incremental potential of a backward Euler step in its velocity form (module docs of
//! [`crate::implicit`]), and the residual `r = -dE` scaled as the convergence test needs it.

use std::time::Instant;

use super::NewtonError;
use super::convergence::{Residual, first_non_finite, norm};
use crate::system::ForceSystem;
use crate::timing::{PhaseTimes, ms_since};

/// The inertia of a backward Euler step: the unknown is the end-of-step velocity `v`, the
/// positions are `x = x^n + dt v`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Inertia {
    /// Positions at the start of the step, m.
    pub(crate) x_n: Vec<f64>,
    /// Velocities at the start of the step, m/s.
    pub(crate) v_n: Vec<f64>,
    /// The step, s.
    pub(crate) dt: f64,
    /// Rayleigh mass damping `alpha`, 1/s.
    pub(crate) alpha: f64,
    /// Rayleigh stiffness damping `beta`, s.
    pub(crate) beta: f64,
}

/// The objective of one Newton solve and its buffers: the forces, the external forces, the
/// right-hand side `r` (the negative gradient of the objective, scaled: `b` of Eq. 23 for a
/// step, `f + f_ext` for a static solve) and the positions of the last evaluation.
#[derive(Debug, Default)]
pub(crate) struct Objective {
    /// `Some` for a backward Euler step, `None` for a static solve (the unknown is `x`).
    pub(crate) inertia: Option<Inertia>,
    /// The time the forces are evaluated at, s.
    pub(crate) time: f64,
    /// The system's forces at the last evaluation, N.
    pub(crate) f: Vec<f64>,
    /// External forces (gravity included), N.
    pub(crate) f_ext: Vec<f64>,
    /// The right-hand side of the Newton system at the last evaluation.
    pub(crate) rhs: Vec<f64>,
    /// Positions of the last evaluation of a step (`x^n + dt v`), m.
    pub(crate) x: Vec<f64>,
    /// `K v` for stiffness damping.
    kv: Vec<f64>,
    tmp: Vec<f64>,
    /// The floor of the force scale, N.
    pub(crate) scale_floor: f64,
    /// The magnitude of the parts of the last energy evaluated, J: its round-off is relative
    /// to it.
    pub(crate) energy_magnitude: f64,
}

impl Objective {
    /// Sizes the buffers for `n` unknowns.
    pub(crate) fn resize(&mut self, n: usize) {
        for buf in [
            &mut self.f,
            &mut self.f_ext,
            &mut self.rhs,
            &mut self.x,
            &mut self.kv,
            &mut self.tmp,
        ] {
            buf.resize(n, 0.0);
        }
    }

    /// The Newton matrix coefficients `(m_coef, k_coef)` of `A = m_coef M + k_coef K` before
    /// any regularisation: `(1 + dt alpha, dt^2 + dt beta)` for a step, `(0, 1)` for a static
    /// solve.
    pub(crate) fn coefficients(&self) -> (f64, f64) {
        match &self.inertia {
            Some(s) => (1.0 + s.dt * s.alpha, s.dt * s.dt + s.dt * s.beta),
            None => (0.0, 1.0),
        }
    }

    /// Whether the objective has a stiffness-damping term (no potential then).
    pub(crate) fn stiffness_damped(&self) -> bool {
        self.inertia.as_ref().is_some_and(|s| s.beta != 0.0)
    }

    /// The positions of the unknowns `u` (written to `self.x` for a step).
    fn place<'a>(&'a mut self, u: &'a [f64]) -> &'a [f64] {
        match &self.inertia {
            Some(s) => {
                for i in 0..u.len() {
                    self.x[i] = s.x_n[i] + s.dt * u[i];
                }
                &self.x
            }
            None => u,
        }
    }

    /// Evaluates the forces at the unknowns `u`, the right-hand side into `self.rhs`, its norm
    /// and the force scale; with `with_energy` (no linearisation, no stiffness damping) also
    /// the objective from the same pass over the system
    /// ([`ForceSystem::residual_forces_and_energy`]; `None` without a potential). With
    /// `linearize` false (a line-search trial, which Newton may stop at) the system may leave
    /// its stiffness for [`ForceSystem::refresh_stiffness`]; stiffness damping needs `K v`
    /// here, so it always linearises.
    pub(crate) fn evaluate<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        u: &[f64],
        iteration: usize,
        linearize: bool,
        with_energy: bool,
        times: &mut PhaseTimes,
    ) -> Result<(Residual, Option<f64>), NewtonError> {
        let n = u.len();
        let beta = self.inertia.as_ref().map_or(0.0, |s| s.beta);
        let time = self.time;
        let mut f = std::mem::take(&mut self.f);
        let x = self.place(u);
        if let Some(dof) = first_non_finite(x) {
            self.f = f;
            return Err(NewtonError::NonFinite {
                quantity: "position",
                dof,
                vertex: dof / 3,
                iteration,
            });
        }
        let started = Instant::now();
        let mut potential = None;
        let evaluated = if with_energy && !linearize && beta == 0.0 {
            system
                .residual_forces_and_energy(time, x, &mut f)
                .map(|w| potential = w)
        } else if linearize || beta != 0.0 {
            system.forces(time, x, &mut f)
        } else {
            system.residual_forces(time, x, &mut f)
        };
        times.forces_ms += ms_since(started);
        self.f = f;
        evaluated.map_err(|source| NewtonError::System { iteration, source })?;
        if let Some(dof) = first_non_finite(&self.f) {
            return Err(NewtonError::NonFinite {
                quantity: "force",
                dof,
                vertex: dof / 3,
                iteration,
            });
        }
        let Some(s) = &self.inertia else {
            // Static: r = f + f_ext.
            for i in 0..n {
                self.rhs[i] = self.f[i] + self.f_ext[i];
            }
            let internal = system.force_scale().unwrap_or_else(|| norm(&self.f));
            let residual = Residual {
                norm: norm(&self.rhs),
                scale: (internal + norm(&self.f_ext)).max(self.scale_floor),
                dt: 1.0,
            };
            let energy = potential.map(|w| self.static_from_potential(w, u));
            return Ok((residual, energy));
        };
        let (alpha, dt) = (s.alpha, s.dt);
        // K v_(k) for stiffness damping.
        self.kv.fill(0.0);
        if beta != 0.0 {
            let started = Instant::now();
            self.tmp.fill(0.0);
            system.add_force_differential(u, &mut self.tmp);
            times.forces_ms += ms_since(started);
            for i in 0..n {
                self.kv[i] = -self.tmp[i];
            }
        }
        let s = self.inertia.as_ref().expect("a step's objective");
        let m = system.masses();
        let (mut b2, mut inertia2, mut f2, mut ext2, mut damp2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let cv = alpha * m[i] * u[i] + beta * self.kv[i];
            let inertia = m[i] * (s.v_n[i] - u[i]);
            self.rhs[i] = inertia + dt * (self.f[i] + self.f_ext[i] - cv);
            b2 += self.rhs[i] * self.rhs[i];
            inertia2 += inertia * inertia;
            f2 += self.f[i] * self.f[i];
            ext2 += self.f_ext[i] * self.f_ext[i];
            damp2 += cv * cv;
        }
        let internal = system.force_scale().unwrap_or(f2.sqrt());
        let terms = inertia2.sqrt() / dt + internal + ext2.sqrt() + damp2.sqrt();
        let residual = Residual {
            norm: b2.sqrt(),
            scale: terms.max(self.scale_floor),
            dt,
        };
        let energy = potential.map(|w| self.incremental_from_potential(system.masses(), w, u));
        Ok((residual, energy))
    }

    /// The objective at the unknowns `u`, or `None` when the system has no potential. An error
    /// of the system (an undefined energy) is returned as such.
    pub(crate) fn energy<S: ForceSystem + ?Sized>(
        &mut self,
        system: &mut S,
        u: &[f64],
        times: &mut PhaseTimes,
    ) -> Result<Option<f64>, NewtonError> {
        let time = self.time;
        let x = self.place(u);
        let started = Instant::now();
        let w = system.potential_energy(time, x);
        times.energy_ms += ms_since(started);
        let w = w.map_err(|source| NewtonError::System {
            iteration: 0,
            source,
        })?;
        let Some(w) = w else {
            return Ok(None);
        };
        Ok(Some(if self.inertia.is_some() {
            self.incremental_from_potential(system.masses(), w, u)
        } else {
            self.static_from_potential(w, u)
        }))
    }

    /// The static energy `W - f_ext . x` given the system's potential `w` at `x`; records the
    /// energy's magnitude for the round-off test of the line search.
    fn static_from_potential(&mut self, w: f64, x: &[f64]) -> f64 {
        let ext: f64 = self.f_ext.iter().zip(x).map(|(f, x)| f * x).sum();
        self.energy_magnitude = w.abs() + ext.abs();
        w - ext
    }

    /// The incremental potential at velocity `v` given the system's potential energy `w` there:
    /// `m_coef/2 |v - v^n/m_coef|_M^2 + W(x) - dt f_ext . v` (the module docs' `E(x)` of
    /// [`crate::implicit`] up to a constant); records the energy's magnitude for the round-off
    /// test of the line search.
    fn incremental_from_potential(&mut self, m: &[f64], w: f64, v: &[f64]) -> f64 {
        let s = self.inertia.as_ref().expect("a step's objective");
        let m_coef = 1.0 + s.dt * s.alpha;
        let (mut kinetic, mut external) = (0.0, 0.0);
        for i in 0..v.len() {
            let d = v[i] - s.v_n[i] / m_coef;
            kinetic += m[i] * d * d;
            external += self.f_ext[i] * v[i];
        }
        let kinetic = 0.5 * m_coef * kinetic;
        let external = s.dt * external;
        self.energy_magnitude = kinetic + w.abs() + external.abs();
        kinetic + w - external
    }
}
