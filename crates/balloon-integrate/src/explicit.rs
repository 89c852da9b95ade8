//! Explicit time integrators (Song 2009, Ch. 5): explicit Euler (Eq. 5.5), midpoint (Eq. 5.9),
//! classical fourth-order Runge-Kutta, and symplectic (semi-implicit) Euler.
//!
//! Two kinds of systems are integrated:
//!
//! * [`OdeSystem`]: a generic first-order system `dy/dt = A(y, t)` (Song 2009, Eq. 5.1); Euler,
//!   midpoint and RK4 apply.
//! * [`SecondOrderSystem`]: a mechanical system `dx/dt = v`, `dv/dt = a(x, v, t)` (Newton's
//!   second law, Song 2009, Sec. 5.2). Its state is stored as one slice `[x; v]` (positions first,
//!   velocities second, both of length [`SecondOrderSystem::dof`]); all four methods apply, and
//!   Euler / midpoint / RK4 treat it as the first-order system of Song 2009, Eq. 5.25-5.40.
//!
//! [`ExplicitIntegrator`] owns its scratch buffers, so a step allocates nothing once the buffers
//! have grown to the system's size. Nothing here knows what the forces are.
//!
//! ```
//! use balloon_integrate::explicit::{ExplicitIntegrator, ExplicitMethod, SecondOrderSystem};
//! /// Unit harmonic oscillator: a = -x.
//! struct Oscillator;
//! impl SecondOrderSystem for Oscillator {
//!     fn dof(&self) -> usize { 1 }
//!     fn acceleration(&mut self, _t: f64, x: &[f64], _v: &[f64], a: &mut [f64]) { a[0] = -x[0]; }
//! }
//! let mut integrator = ExplicitIntegrator::new(ExplicitMethod::Rk4);
//! let mut state = [1.0, 0.0]; // x = 1, v = 0
//! let dt = 0.01;
//! for i in 0..100 {
//!     integrator.step_second_order(&mut Oscillator, i as f64 * dt, dt, &mut state).unwrap();
//! }
//! assert!((state[0] - 1f64.cos()).abs() < 1e-9);
//! ```

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// A first-order ODE system `dy/dt = A(y, t)` (Song 2009, Eq. 5.1).
pub trait OdeSystem {
    /// Length of the state vector `y`.
    fn dimension(&self) -> usize;
    /// Writes `A(y, t)` into `dydt` (both of length [`OdeSystem::dimension`]).
    fn derivative(&mut self, t: f64, y: &[f64], dydt: &mut [f64]);
}

/// A second-order mechanical system `x'' = a(x, v, t)` (Song 2009, Sec. 5.2: `a = F / m`).
pub trait SecondOrderSystem {
    /// Number of position coordinates (e.g. `3 * particles`).
    fn dof(&self) -> usize;
    /// Writes the acceleration `a(x, v, t)` (length [`SecondOrderSystem::dof`]) for positions `x`
    /// and velocities `v`.
    fn acceleration(&mut self, t: f64, x: &[f64], v: &[f64], a: &mut [f64]);
}

/// Views a [`SecondOrderSystem`] as the first-order system `y = [x; v]`, `y' = [v; a(x, v, t)]`.
pub struct FirstOrderView<'a, S: SecondOrderSystem + ?Sized>(pub &'a mut S);

impl<S: SecondOrderSystem + ?Sized> OdeSystem for FirstOrderView<'_, S> {
    fn dimension(&self) -> usize {
        2 * self.0.dof()
    }

    fn derivative(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
        let n = self.0.dof();
        let (x, v) = y.split_at(n);
        let (dx, dv) = dydt.split_at_mut(n);
        dx.copy_from_slice(v);
        self.0.acceleration(t, x, v, dv);
    }
}

/// The explicit method of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ExplicitMethod {
    /// Explicit (forward) Euler, Song 2009, Eq. 5.5: `y += h A(y, t)`. First order; one evaluation.
    Euler,
    /// Explicit midpoint (RK2), Song 2009, Eq. 5.9-5.15: `k1 = A(y, t)`,
    /// `y += h A(y + h/2 k1, t + h/2)`. Second order; two evaluations. (The paper's pseudocode
    /// averages the slopes at both ends, i.e. Heun's method; the text describes the slope at
    /// the centre of the interval, which is what is implemented. Both are second order.)
    Midpoint,
    /// Classical fourth-order Runge-Kutta (Song 2009, Sec. 5.1.3). Fourth order; four evaluations.
    #[default]
    Rk4,
    /// Symplectic (semi-implicit) Euler for second-order systems: `v += h a(x, v, t)`, then
    /// `x += h v` with the new velocity. First order, one evaluation, bounded energy error for
    /// conservative forces.
    Symplectic,
}

impl ExplicitMethod {
    /// All methods, in the order of their names in [`ExplicitMethod::NAMES`].
    pub const ALL: [ExplicitMethod; 4] = [
        ExplicitMethod::Euler,
        ExplicitMethod::Midpoint,
        ExplicitMethod::Rk4,
        ExplicitMethod::Symplectic,
    ];
    /// The accepted names.
    pub const NAMES: [&'static str; 4] = ["euler", "midpoint", "rk4", "symplectic"];

    /// The lowercase name (`"euler"`, `"midpoint"`, `"rk4"`, `"symplectic"`).
    pub fn name(self) -> &'static str {
        match self {
            ExplicitMethod::Euler => "euler",
            ExplicitMethod::Midpoint => "midpoint",
            ExplicitMethod::Rk4 => "rk4",
            ExplicitMethod::Symplectic => "symplectic",
        }
    }

    /// Force (derivative) evaluations per step.
    pub fn evaluations_per_step(self) -> usize {
        match self {
            ExplicitMethod::Euler | ExplicitMethod::Symplectic => 1,
            ExplicitMethod::Midpoint => 2,
            ExplicitMethod::Rk4 => 4,
        }
    }

    /// Order of accuracy (global error `O(h^order)`).
    pub fn order(self) -> u32 {
        match self {
            ExplicitMethod::Euler | ExplicitMethod::Symplectic => 1,
            ExplicitMethod::Midpoint => 2,
            ExplicitMethod::Rk4 => 4,
        }
    }
}

impl fmt::Display for ExplicitMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExplicitMethod {
    type Err = ExplicitError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let lower = s.trim().to_ascii_lowercase();
        ExplicitMethod::ALL
            .into_iter()
            .find(|m| m.name() == lower)
            .ok_or_else(|| ExplicitError::UnknownMethod(s.to_string()))
    }
}

/// Errors of the explicit integrators.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ExplicitError {
    /// A method name did not parse. Use one of `euler`, `midpoint`, `rk4`, `symplectic`.
    #[error("unknown explicit method `{0}` (expected one of: euler, midpoint, rk4, symplectic)")]
    UnknownMethod(String),
    /// The time step is not a positive finite number. Pass `dt > 0`.
    #[error("time step dt = {0} must be a positive finite number of seconds")]
    InvalidTimeStep(f64),
    /// The state slice has the wrong length for the system.
    #[error("state has length {actual} but the system needs {expected}")]
    DimensionMismatch {
        /// Length the system needs.
        expected: usize,
        /// Length passed.
        actual: usize,
    },
    /// Symplectic Euler needs a split into positions and velocities, which a generic
    /// [`OdeSystem`] has not. Use [`ExplicitIntegrator::step_second_order`] or another method.
    #[error(
        "symplectic Euler needs a second-order system (positions and velocities); use step_second_order or euler/midpoint/rk4"
    )]
    SymplecticNeedsSecondOrder,
}

/// An explicit integrator with its own scratch buffers (no allocation per step once warm).
#[derive(Clone, Debug)]
pub struct ExplicitIntegrator {
    method: ExplicitMethod,
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    tmp: Vec<f64>,
}

impl ExplicitIntegrator {
    /// An integrator using `method`.
    pub fn new(method: ExplicitMethod) -> Self {
        Self {
            method,
            k1: Vec::new(),
            k2: Vec::new(),
            k3: Vec::new(),
            k4: Vec::new(),
            tmp: Vec::new(),
        }
    }

    /// The method.
    pub fn method(&self) -> ExplicitMethod {
        self.method
    }

    /// Changes the method (buffers are kept).
    pub fn set_method(&mut self, method: ExplicitMethod) {
        self.method = method;
    }

    fn resize(&mut self, n: usize) {
        for b in [
            &mut self.k1,
            &mut self.k2,
            &mut self.k3,
            &mut self.k4,
            &mut self.tmp,
        ] {
            if b.len() != n {
                b.resize(n, 0.0);
            }
        }
    }

    fn check(dt: f64, expected: usize, actual: usize) -> Result<(), ExplicitError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ExplicitError::InvalidTimeStep(dt));
        }
        if expected != actual {
            return Err(ExplicitError::DimensionMismatch { expected, actual });
        }
        Ok(())
    }

    /// Advances the first-order system from `(t, y)` to `t + dt`, overwriting `y`.
    ///
    /// Errors: [`ExplicitError::InvalidTimeStep`], [`ExplicitError::DimensionMismatch`], and
    /// [`ExplicitError::SymplecticNeedsSecondOrder`] for the symplectic method.
    pub fn step<S: OdeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t: f64,
        dt: f64,
        y: &mut [f64],
    ) -> Result<(), ExplicitError> {
        Self::check(dt, system.dimension(), y.len())?;
        self.resize(y.len());
        let h = dt;
        match self.method {
            ExplicitMethod::Euler => {
                system.derivative(t, y, &mut self.k1);
                axpy(y, h, &self.k1);
            }
            ExplicitMethod::Midpoint => {
                system.derivative(t, y, &mut self.k1);
                lincomb(&mut self.tmp, y, 0.5 * h, &self.k1);
                system.derivative(t + 0.5 * h, &self.tmp, &mut self.k2);
                axpy(y, h, &self.k2);
            }
            ExplicitMethod::Rk4 => {
                system.derivative(t, y, &mut self.k1);
                lincomb(&mut self.tmp, y, 0.5 * h, &self.k1);
                system.derivative(t + 0.5 * h, &self.tmp, &mut self.k2);
                lincomb(&mut self.tmp, y, 0.5 * h, &self.k2);
                system.derivative(t + 0.5 * h, &self.tmp, &mut self.k3);
                lincomb(&mut self.tmp, y, h, &self.k3);
                system.derivative(t + h, &self.tmp, &mut self.k4);
                let w = h / 6.0;
                for i in 0..y.len() {
                    y[i] += w * (self.k1[i] + 2.0 * (self.k2[i] + self.k3[i]) + self.k4[i]);
                }
            }
            ExplicitMethod::Symplectic => return Err(ExplicitError::SymplecticNeedsSecondOrder),
        }
        Ok(())
    }

    /// Advances the second-order system from `(t, state = [x; v])` to `t + dt`, overwriting
    /// `state` (length `2 * system.dof()`). All four methods apply.
    pub fn step_second_order<S: SecondOrderSystem + ?Sized>(
        &mut self,
        system: &mut S,
        t: f64,
        dt: f64,
        state: &mut [f64],
    ) -> Result<(), ExplicitError> {
        let n = system.dof();
        Self::check(dt, 2 * n, state.len())?;
        if self.method == ExplicitMethod::Symplectic {
            self.resize(n);
            let (x, v) = state.split_at_mut(n);
            system.acceleration(t, x, v, &mut self.k1);
            axpy(v, dt, &self.k1);
            axpy(x, dt, v);
            return Ok(());
        }
        self.step(&mut FirstOrderView(system), t, dt, state)
    }
}

/// `y += a * x`.
fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// `out = y + a * x`.
fn lincomb(out: &mut [f64], y: &[f64], a: f64, x: &[f64]) {
    for ((o, yi), xi) in out.iter_mut().zip(y).zip(x) {
        *o = yi + a * xi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Harmonic oscillator `x'' = -omega^2 x` with exact solution `x = cos(omega t)`.
    struct Oscillator {
        omega: f64,
        evaluations: usize,
    }

    impl SecondOrderSystem for Oscillator {
        fn dof(&self) -> usize {
            1
        }
        fn acceleration(&mut self, _t: f64, x: &[f64], _v: &[f64], a: &mut [f64]) {
            self.evaluations += 1;
            a[0] = -self.omega * self.omega * x[0];
        }
    }

    /// Non-autonomous scalar ODE `y' = y cos t`, exact `y = exp(sin t)`: checks that the stage
    /// times are right (an autonomous test cannot see them).
    struct TimeDependent;

    impl OdeSystem for TimeDependent {
        fn dimension(&self) -> usize {
            1
        }
        fn derivative(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
            dydt[0] = y[0] * t.cos();
        }
    }

    fn oscillator_error(method: ExplicitMethod, dt: f64) -> f64 {
        let t_end = 1.0;
        let steps = (t_end / dt).round() as usize;
        let mut sys = Oscillator {
            omega: 2.0,
            evaluations: 0,
        };
        let mut it = ExplicitIntegrator::new(method);
        let mut s = [1.0, 0.0];
        for i in 0..steps {
            it.step_second_order(&mut sys, i as f64 * dt, dt, &mut s)
                .unwrap();
        }
        assert_eq!(sys.evaluations, steps * method.evaluations_per_step());
        let t = steps as f64 * dt;
        let (xe, ve) = ((2.0 * t).cos(), -2.0 * (2.0 * t).sin());
        ((s[0] - xe).powi(2) + (s[1] - ve).powi(2)).sqrt()
    }

    /// Least-squares slope of log(error) against log(dt).
    fn fitted_order(errors: &[(f64, f64)]) -> f64 {
        let n = errors.len() as f64;
        let (lx, ly): (Vec<f64>, Vec<f64>) = errors.iter().map(|(h, e)| (h.ln(), e.ln())).unzip();
        let mx = lx.iter().sum::<f64>() / n;
        let my = ly.iter().sum::<f64>() / n;
        let num: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
        let den: f64 = lx.iter().map(|x| (x - mx).powi(2)).sum();
        num / den
    }

    #[test]
    fn measured_orders_of_accuracy_match_theory() {
        for method in ExplicitMethod::ALL {
            let dts = [0.02, 0.01, 0.005, 0.0025];
            let errors: Vec<(f64, f64)> = dts
                .iter()
                .map(|&h| (h, oscillator_error(method, h)))
                .collect();
            let p = fitted_order(&errors);
            assert!(
                (p - method.order() as f64).abs() < 0.3,
                "{method}: fitted order {p:.3}, expected {} (errors {errors:?})",
                method.order()
            );
        }
    }

    #[test]
    fn stage_times_are_right_for_time_dependent_ode() {
        for method in [
            ExplicitMethod::Euler,
            ExplicitMethod::Midpoint,
            ExplicitMethod::Rk4,
        ] {
            let errs: Vec<(f64, f64)> = [0.04, 0.02, 0.01]
                .iter()
                .map(|&h| {
                    let mut it = ExplicitIntegrator::new(method);
                    let mut y = [1.0];
                    let steps = (2.0f64 / h).round() as usize;
                    for i in 0..steps {
                        it.step(&mut TimeDependent, i as f64 * h, h, &mut y)
                            .unwrap();
                    }
                    (h, (y[0] - (2.0f64).sin().exp()).abs())
                })
                .collect();
            let p = fitted_order(&errs);
            assert!(
                (p - method.order() as f64).abs() < 0.3,
                "{method}: order {p:.3} on y' = y cos t"
            );
        }
    }

    #[test]
    fn rk4_energy_drift_is_bounded_and_symplectic_energy_oscillates() {
        // The oscillator conserves E = (v^2 + omega^2 x^2) / 2; RK4 loses it at O(h^4) per unit
        // time, symplectic Euler keeps it within O(h) without secular drift.
        let omega = 2.0;
        let energy = |s: &[f64; 2]| 0.5 * (s[1] * s[1] + omega * omega * s[0] * s[0]);
        for (method, tol) in [
            (ExplicitMethod::Rk4, 1e-6),
            (ExplicitMethod::Symplectic, 0.05),
        ] {
            let mut sys = Oscillator {
                omega,
                evaluations: 0,
            };
            let mut it = ExplicitIntegrator::new(method);
            let mut s = [1.0, 0.0];
            let e0 = energy(&s);
            let dt = 0.01;
            let mut worst = 0.0f64;
            for i in 0..20_000 {
                it.step_second_order(&mut sys, i as f64 * dt, dt, &mut s)
                    .unwrap();
                worst = worst.max((energy(&s) - e0).abs() / e0);
            }
            assert!(worst < tol, "{method}: relative energy drift {worst:.3e}");
        }
        // Explicit Euler gains energy every step (|1 + i h omega| > 1): it must grow.
        let mut sys = Oscillator {
            omega,
            evaluations: 0,
        };
        let mut it = ExplicitIntegrator::new(ExplicitMethod::Euler);
        let mut s = [1.0, 0.0];
        for i in 0..1000 {
            it.step_second_order(&mut sys, i as f64 * 0.01, 0.01, &mut s)
                .unwrap();
        }
        assert!(energy(&s) > 1.2 * 2.0, "explicit Euler should gain energy");
    }

    #[test]
    fn parse_display_and_errors() {
        for (m, name) in ExplicitMethod::ALL.iter().zip(ExplicitMethod::NAMES) {
            assert_eq!(name.parse::<ExplicitMethod>().unwrap(), *m);
            assert_eq!(m.to_string(), name);
            let json = serde_json_like(*m);
            assert_eq!(json, name);
        }
        assert_eq!(
            "RK4".parse::<ExplicitMethod>().unwrap(),
            ExplicitMethod::Rk4
        );
        assert!(matches!(
            "verlet".parse::<ExplicitMethod>(),
            Err(ExplicitError::UnknownMethod(_))
        ));
        let mut it = ExplicitIntegrator::new(ExplicitMethod::Euler);
        let mut y = [1.0];
        assert_eq!(
            it.step(&mut TimeDependent, 0.0, 0.0, &mut y),
            Err(ExplicitError::InvalidTimeStep(0.0))
        );
        assert!(matches!(
            it.step(&mut TimeDependent, 0.0, f64::NAN, &mut y),
            Err(ExplicitError::InvalidTimeStep(_))
        ));
        let mut y2 = [1.0, 2.0];
        assert_eq!(
            it.step(&mut TimeDependent, 0.0, 0.1, &mut y2),
            Err(ExplicitError::DimensionMismatch {
                expected: 1,
                actual: 2
            })
        );
        it.set_method(ExplicitMethod::Symplectic);
        assert_eq!(
            it.step(&mut TimeDependent, 0.0, 0.1, &mut y),
            Err(ExplicitError::SymplecticNeedsSecondOrder)
        );
    }

    /// The serde name of a method, through its `Deserialize` impl (round trip via a string
    /// deserializer, no JSON crate needed).
    fn serde_json_like(m: ExplicitMethod) -> String {
        use serde::de::IntoDeserializer;
        use serde::de::value::{Error, StrDeserializer};
        let name = m.name();
        let d: StrDeserializer<'_, Error> = name.into_deserializer();
        let back = ExplicitMethod::deserialize(d).unwrap();
        assert_eq!(back, m);
        name.to_string()
    }
}
