//! A cancellation request ends a Newton solve within one iteration, as
//! [`balloon_integrate::newton::NewtonError::Interrupted`], for the dynamic step and the static
//! solve, and is not retried by the sub-step controller. (Its own test binary: the check is
//! process-wide and would stop the other tests' solves.)

use std::sync::atomic::{AtomicBool, Ordering};

use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::newton::{NewtonError, set_cancel_check};
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_integrate::{ForceSystem, SystemError};

static STOP: AtomicBool = AtomicBool::new(false);

/// One particle on a stiff nonlinear spring to the origin under gravity-like load: a few
/// Newton iterations to converge, with a potential.
struct Anchor {
    masses: Vec<f64>,
    k: f64,
    x: Vec<f64>,
}

impl ForceSystem for Anchor {
    fn num_dofs(&self) -> usize {
        3
    }
    fn masses(&self) -> &[f64] {
        &self.masses
    }
    fn forces(&mut self, _time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        // Energy k/4 |x|^4 - g . x with g = (0, 0, -1).
        let r2: f64 = x.iter().map(|a| a * a).sum();
        for i in 0..3 {
            f[i] = -self.k * r2 * x[i];
        }
        f[2] -= 1.0;
        Ok(())
    }
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        let x = &self.x;
        let r2: f64 = x.iter().map(|a| a * a).sum();
        let xdx: f64 = x.iter().zip(dx).map(|(a, b)| a * b).sum();
        for i in 0..3 {
            df[i] -= self.k * (r2 * dx[i] + 2.0 * xdx * x[i]);
        }
    }
    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let x = &self.x;
        let r2: f64 = x.iter().map(|a| a * a).sum();
        for i in 0..3 {
            for j in 0..3 {
                let d = if i == j { r2 } else { 0.0 };
                triplets.push((i, j, self.k * (d + 2.0 * x[i] * x[j])));
            }
        }
        Ok(())
    }
    fn force_scale(&self) -> Option<f64> {
        // The spring's and the load's magnitudes, which balance at equilibrium.
        let r2: f64 = self.x.iter().map(|a| a * a).sum();
        Some(self.k * r2 * r2.sqrt() + 1.0)
    }
    fn potential_energy(&mut self, _time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let r2: f64 = x.iter().map(|a| a * a).sum();
        Ok(Some(0.25 * self.k * r2 * r2 + x[2]))
    }
}

fn anchor() -> Anchor {
    Anchor {
        masses: vec![1e-3; 3],
        k: 50.0,
        x: vec![0.0; 3],
    }
}

#[test]
fn a_cancel_request_ends_the_dynamic_step_and_the_static_solve() {
    assert!(set_cancel_check(|| STOP.load(Ordering::SeqCst)));
    // A second registration is refused; the first is kept.
    assert!(!set_cancel_check(|| true));

    // Requested: both solvers stop in their first iteration, with the state untouched.
    STOP.store(true, Ordering::SeqCst);
    let mut be = BackwardEuler::new(BackwardEulerParams::default()).unwrap();
    let (mut x, mut v) = (vec![0.3, 0.1, 0.2], vec![0.0; 3]);
    let e = be
        .step(&mut anchor(), 0.0, 0.01, &mut x, &mut v, None)
        .unwrap_err();
    assert!(
        matches!(e, NewtonError::Interrupted { iteration: 0 }),
        "{e}"
    );
    assert!(!e.is_recoverable());
    assert!(e.to_string().contains("interrupted"), "{e}");
    let mut statics = StaticSolver::new(StaticParams::default()).unwrap();
    let mut xs = vec![0.3, 0.1, 0.2];
    let e = statics
        .solve(&mut anchor(), 0.0, &mut xs, None)
        .unwrap_err();
    assert!(matches!(e, NewtonError::Interrupted { .. }), "{e}");
    assert_eq!(xs, vec![0.3, 0.1, 0.2]);

    // Withdrawn: the same solves converge (the static one to |x|^2 x_z = -1/k).
    STOP.store(false, Ordering::SeqCst);
    be.step(&mut anchor(), 0.0, 0.01, &mut x, &mut v, None)
        .unwrap();
    let info = StaticSolver::new(StaticParams::default())
        .unwrap()
        .solve(&mut anchor(), 0.0, &mut xs, None)
        .unwrap();
    assert!(info.iterations > 1, "{info:?}");
    let r2: f64 = xs.iter().map(|a| a * a).sum();
    assert!((50.0 * r2 * xs[2] + 1.0).abs() < 1e-6, "{xs:?}");
}
