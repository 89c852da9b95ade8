//! Adaptive sub-stepping of any time stepper: a step that fails numerically is rolled back and
//! retried in halved sub-steps that add up to the step, and the sub-step size grows back after
//! easy sub-steps.
//!
//! The remedy of Diziol, Bender and Bayer (2011, Sec. 4) for their impulse-based bodies (halve
//! the time step where it fails) applied to any stepper: [`AdaptiveSubsteps::advance`] drives
//! a [`Substepper`] (save, restore, one sub-step) from `t` to `t + dt` in sub-steps that add up
//! to `dt` exactly, so a step ends at the time asked for. A sub-step that fails with an error
//! the stepper calls retryable is rolled back and retried at half the size, at most
//! `max_halvings` halvings below `dt`; after easy sub-steps (for Newton: converged in at most
//! [`EASY_NEWTON_ITERATIONS`] iterations without line-search cuts) the size doubles again, up
//! to `dt`, when [`SubstepGrowth`] says so. The size reached is where the next step starts.
//!
//! ```
//! use balloon_integrate::substep::{AdaptiveSubsteps, Attempt, Substepper};
//!
//! /// `dx/dt = -x` by explicit Euler, which "fails" when a sub-step is longer than 0.3 s.
//! struct Decay(f64);
//! impl Substepper for Decay {
//!     type State = f64;
//!     type Info = ();
//!     type Error = &'static str;
//!     fn save(&self) -> f64 {
//!         self.0
//!     }
//!     fn restore(&mut self, state: f64) {
//!         self.0 = state;
//!     }
//!     fn substep(&mut self, _t: f64, h: f64) -> Result<(), &'static str> {
//!         self.0 -= h * self.0;
//!         if h > 0.3 { Err("too long") } else { Ok(()) }
//!     }
//!     fn is_easy(_: &()) -> bool {
//!         true
//!     }
//!     fn may_retry(_: &&'static str) -> bool {
//!         true
//!     }
//! }
//!
//! let mut substeps = AdaptiveSubsteps::new(10);
//! let mut x = Decay(1.0);
//! let report = substeps.advance(&mut x, 0.0, 1.0, |_: Attempt<'_, (), &str>| {}).unwrap();
//! // 1.0 and 0.5 fail; after two easy sub-steps of 0.25 s the size doubles, 0.5 fails again,
//! // and two more sub-steps of 0.25 s end the step.
//! assert_eq!((report.substeps, report.halvings, report.min_dt), (4, 3, 0.25));
//! assert!((x.0 - 0.75f64.powi(4)).abs() < 1e-15);
//! ```

use crate::ForceSystem;
use crate::implicit::{BackwardEuler, IntegrateError, StepInfo};

/// A sub-step whose Newton converged in at most this many iterations, without line-search
/// cuts, counts as easy: easy sub-steps in a row let a sub-step size that a failure halved
/// double again (one after a single failure; more, up to [`MAX_EASY_BEFORE_GROWTH`], while the
/// doubled size keeps failing).
pub const EASY_NEWTON_ITERATIONS: usize = 6;

/// Most easy sub-steps in a row the sub-step size waits for before it doubles again, after
/// repeated failures of the doubled size (see [`EASY_NEWTON_ITERATIONS`]).
pub const MAX_EASY_BEFORE_GROWTH: usize = 16;

/// A time stepper that [`AdaptiveSubsteps`] can drive: it can save and restore its state and
/// take one sub-step of a given size.
pub trait Substepper {
    /// A snapshot of the state a failed sub-step is rolled back to.
    type State;
    /// What an accepted sub-step reports.
    type Info;
    /// Why a sub-step failed.
    type Error;
    /// A snapshot of the current state.
    fn save(&self) -> Self::State;
    /// Goes back to a snapshot.
    fn restore(&mut self, state: Self::State);
    /// One sub-step from `time` (s) of size `dt` (s).
    fn substep(&mut self, time: f64, dt: f64) -> Result<Self::Info, Self::Error>;
    /// Whether an accepted sub-step was easy (its size may grow after a few of them).
    fn is_easy(info: &Self::Info) -> bool;
    /// Whether a failure may go away at a smaller size (a numerical failure, not a physical
    /// runaway or bad input).
    fn may_retry(error: &Self::Error) -> bool;
}

/// A [`ForceSystem`] stepped by [`BackwardEuler`] as a [`Substepper`]: any force system gets
/// adaptive sub-steps this way. The state is the positions and velocities; a sub-step is
/// easy when Newton converged in at most [`EASY_NEWTON_ITERATIONS`] iterations without
/// line-search cuts; every failure but bad input ([`IntegrateError::is_recoverable`]) is
/// retried at half the size.
///
/// ```
/// use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
/// use balloon_integrate::substep::{AdaptiveSubsteps, ImplicitSteps};
/// use balloon_integrate::{ForceSystem, SystemError};
///
/// /// A stiff spring to the origin.
/// struct Spring([f64; 3]);
/// impl ForceSystem for Spring {
///     fn num_dofs(&self) -> usize {
///         3
///     }
///     fn masses(&self) -> &[f64] {
///         &self.0
///     }
///     fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
///         f.iter_mut().zip(x).for_each(|(f, x)| *f = -1e4 * x);
///         Ok(())
///     }
///     fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
///         df.iter_mut().zip(dx).for_each(|(df, dx)| *df -= 1e4 * dx);
///     }
/// }
///
/// let mut steps = ImplicitSteps {
///     integrator: BackwardEuler::new(BackwardEulerParams::default())?,
///     system: Spring([1.0; 3]),
///     x: vec![0.1, 0.0, 0.0],
///     v: vec![0.0; 3],
///     external_forces: None,
/// };
/// let mut control = AdaptiveSubsteps::new(10);
/// for n in 0..10 {
///     control
///         .advance(&mut steps, n as f64 * 0.01, 0.01, |_| {})
///         .map_err(|failure| failure.error)?;
/// }
/// // Backward Euler damps the oscillation.
/// assert!(steps.x[0].abs() < 0.1);
/// # Ok::<(), balloon_integrate::implicit::IntegrateError>(())
/// ```
#[derive(Debug)]
pub struct ImplicitSteps<S> {
    /// The integrator.
    pub integrator: BackwardEuler,
    /// The force system.
    pub system: S,
    /// Positions, m (flat, one entry per degree of freedom).
    pub x: Vec<f64>,
    /// Velocities, m/s.
    pub v: Vec<f64>,
    /// External forces per degree of freedom, N (held over each step).
    pub external_forces: Option<Vec<f64>>,
}

impl<S: ForceSystem> Substepper for ImplicitSteps<S> {
    type State = (Vec<f64>, Vec<f64>);
    type Info = StepInfo;
    type Error = IntegrateError;

    fn save(&self) -> Self::State {
        (self.x.clone(), self.v.clone())
    }

    fn restore(&mut self, (x, v): Self::State) {
        (self.x, self.v) = (x, v);
    }

    fn substep(&mut self, time: f64, dt: f64) -> Result<StepInfo, IntegrateError> {
        self.integrator.step(
            &mut self.system,
            time,
            dt,
            &mut self.x,
            &mut self.v,
            self.external_forces.as_deref(),
        )
    }

    fn is_easy(info: &StepInfo) -> bool {
        info.newton_iterations <= EASY_NEWTON_ITERATIONS && info.line_search_cuts == 0
    }

    fn may_retry(error: &IntegrateError) -> bool {
        error.is_recoverable()
    }
}

/// One attempt of a sub-step, as [`AdaptiveSubsteps::advance`] hands it to its observer.
#[derive(Debug)]
pub enum Attempt<'a, I, E> {
    /// The sub-step of size `dt` was accepted.
    Accepted {
        /// What it reported.
        info: &'a I,
        /// Its size, s.
        dt: f64,
    },
    /// The sub-step of size `dt` failed and was rolled back.
    Failed {
        /// Why.
        error: &'a E,
        /// Its size, s.
        dt: f64,
    },
}

/// What [`AdaptiveSubsteps::advance`] did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SubstepReport {
    /// Sub-steps accepted (1 when the step was not split).
    pub substeps: usize,
    /// Sub-steps rolled back and retried at half the size.
    pub halvings: usize,
    /// The smallest accepted sub-step, s.
    pub min_dt: f64,
}

/// A step that failed even at the smallest sub-step (or with an error that is not retried):
/// the stepper is back at the start of the step.
#[derive(Clone, Debug, PartialEq)]
pub struct SubstepFailure<E> {
    /// The last sub-step's error.
    pub error: E,
    /// Halvings in this step.
    pub halvings: usize,
    /// The size of the sub-step that failed last, s.
    pub dt: f64,
}

/// When the sub-step size doubles again after a failure halved it.
///
/// A failed sub-step costs a whole Newton solve that is thrown away, several times an easy one
/// (on a 0.1 m armadillo under the default pump, about 1.8 s against 0.7 s at half the
/// size), so doubling after every easy sub-step, only to fail and halve again, spent more
/// than half the run on rejected attempts. Instead the size doubles after `wait` easy
/// sub-steps in a row; a failure of the size just doubled doubles `wait` (up to
/// [`MAX_EASY_BEFORE_GROWTH`]), a doubled size that converges halves it again (down to 1,
/// the rule before: once the doubled sizes converge again the size grows back after every
/// easy sub-step). After any failure `wait` is at least 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubstepGrowth {
    /// Easy sub-steps in a row so far.
    streak: usize,
    /// Easy sub-steps in a row needed before the size doubles.
    wait: usize,
    /// The last sub-step size was just doubled (its outcome adjusts `wait`).
    just_grew: bool,
}

impl Default for SubstepGrowth {
    fn default() -> Self {
        Self {
            streak: 0,
            wait: 1,
            just_grew: false,
        }
    }
}

impl SubstepGrowth {
    /// After an accepted sub-step: whether the size doubles now. `can_grow` is false when the
    /// size already is the whole step (a later failure then is not one of a doubled size).
    pub fn accepted(&mut self, easy: bool, can_grow: bool) -> bool {
        if self.just_grew {
            self.wait = (self.wait / 2).max(1);
            self.just_grew = false;
        }
        if !easy {
            self.streak = 0;
            return false;
        }
        self.streak += 1;
        if can_grow && self.streak >= self.wait {
            self.streak = 0;
            self.just_grew = true;
            true
        } else {
            false
        }
    }

    /// After a sub-step that failed and is retried at half the size.
    pub fn failed(&mut self) {
        if self.just_grew {
            self.wait = (2 * self.wait).min(MAX_EASY_BEFORE_GROWTH);
        }
        self.wait = self.wait.max(2);
        self.just_grew = false;
        self.streak = 0;
    }
}

/// The sub-step controller: the most halvings below a step, the sub-step size reached and when
/// it grows (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveSubsteps {
    /// The most halvings of a step (its smallest sub-step is `dt / 2^max_halvings`).
    max_halvings: usize,
    /// The sub-step size the next step starts with, s (0: the whole step).
    size: f64,
    /// When the size may double again (kept across steps, like `size`).
    growth: SubstepGrowth,
}

impl AdaptiveSubsteps {
    /// A controller allowing `max_halvings` halvings below each step (capped at 60).
    pub fn new(max_halvings: usize) -> Self {
        Self {
            max_halvings,
            size: 0.0,
            growth: SubstepGrowth::default(),
        }
    }

    /// Starts the next step at sub-steps of `size` (s; 0 or more than the step: the whole
    /// step), as after a step that had to be split into sub-steps of that size.
    pub fn with_size(mut self, size: f64) -> Self {
        self.size = size;
        self
    }

    /// The most halvings below a step.
    pub fn max_halvings(&self) -> usize {
        self.max_halvings
    }

    /// Sets the most halvings below a step.
    pub fn set_max_halvings(&mut self, max_halvings: usize) {
        self.max_halvings = max_halvings;
    }

    /// The sub-step size the next step starts with, s (0 until a step had to be split).
    pub fn size(&self) -> f64 {
        self.size
    }

    /// Advances `stepper` from `time` by `dt` in sub-steps that add up to `dt` exactly,
    /// handing every attempt to `observe` (module docs). On failure the stepper is back at
    /// the state it had at `time`.
    pub fn advance<S: Substepper>(
        &mut self,
        stepper: &mut S,
        time: f64,
        dt: f64,
        mut observe: impl FnMut(Attempt<'_, S::Info, S::Error>),
    ) -> Result<SubstepReport, SubstepFailure<S::Error>> {
        let min_h = dt / f64::powi(2.0, self.max_halvings.min(60) as i32);
        let mut h = if self.size > 0.0 {
            self.size.min(dt)
        } else {
            dt
        };
        let mut elapsed = 0.0;
        let mut report = SubstepReport::default();
        let start = stepper.save();
        while elapsed < dt {
            let remaining = dt - elapsed;
            // Never leave a sliver: take the rest when it is (nearly) within reach.
            let this = if h >= remaining * (1.0 - 1e-9) {
                remaining
            } else {
                h
            };
            let before = stepper.save();
            match stepper.substep(time + elapsed, this) {
                Ok(info) => {
                    observe(Attempt::Accepted {
                        info: &info,
                        dt: this,
                    });
                    report.substeps += 1;
                    report.min_dt = if report.substeps == 1 {
                        this
                    } else {
                        report.min_dt.min(this)
                    };
                    elapsed = if this == remaining {
                        dt
                    } else {
                        elapsed + this
                    };
                    if self.growth.accepted(S::is_easy(&info), h < dt) {
                        h = (2.0 * h).min(dt);
                    }
                }
                Err(error) => {
                    stepper.restore(before);
                    observe(Attempt::Failed {
                        error: &error,
                        dt: this,
                    });
                    if !S::may_retry(&error) || 0.5 * this < min_h * (1.0 - 1e-9) {
                        // Back to the start of the whole step, not only of this sub-step.
                        stepper.restore(start);
                        return Err(SubstepFailure {
                            error,
                            halvings: report.halvings,
                            dt: this,
                        });
                    }
                    h = 0.5 * this;
                    self.growth.failed();
                    report.halvings += 1;
                }
            }
        }
        self.size = h;
        Ok(report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stepper whose sub-steps fail above a size limit that can change between steps, and
    /// that counts its work.
    struct Limited {
        x: f64,
        limit: f64,
        taken: Vec<f64>,
    }

    impl Substepper for Limited {
        type State = f64;
        type Info = f64;
        type Error = bool;
        fn save(&self) -> f64 {
            self.x
        }
        fn restore(&mut self, state: f64) {
            self.x = state;
        }
        fn substep(&mut self, _t: f64, h: f64) -> Result<f64, bool> {
            self.x += h;
            if h > self.limit {
                return Err(true);
            }
            self.taken.push(h);
            Ok(h)
        }
        fn is_easy(_: &f64) -> bool {
            true
        }
        fn may_retry(retry: &bool) -> bool {
            *retry
        }
    }

    #[test]
    fn sub_steps_add_up_to_the_step_and_failures_are_rolled_back() {
        let mut s = Limited {
            x: 0.0,
            limit: 0.3,
            taken: vec![],
        };
        let mut c = AdaptiveSubsteps::new(10);
        let (mut accepted, mut failed) = (0, 0);
        let r = c
            .advance(&mut s, 0.0, 1.0, |a| match a {
                Attempt::Accepted { .. } => accepted += 1,
                Attempt::Failed { .. } => failed += 1,
            })
            .unwrap();
        // 1 and 0.5 fail, two sub-steps of 0.25 let the size double, 0.5 fails again, two more
        // of 0.25 end the step.
        assert_eq!((r.substeps, r.halvings, accepted, failed), (4, 3, 4, 3));
        assert_eq!(s.taken, vec![0.25; 4]);
        // Only accepted sub-steps moved the state: exactly the step.
        assert_eq!(s.x, 1.0);
        assert_eq!(c.size(), 0.25);
        // The next step starts at the size reached; the doubled size failed, so it waits for
        // four easy sub-steps in a row (two were at the end of the last step) before it
        // doubles, then grows back to the whole step.
        s.limit = 10.0;
        s.taken.clear();
        let r = c.advance(&mut s, 1.0, 1.0, |_| {}).unwrap();
        assert_eq!(s.taken, vec![0.25, 0.25, 0.5]);
        assert_eq!((r.substeps, r.halvings, r.min_dt), (3, 0, 0.25));
        assert_eq!(c.size(), 0.5);
        s.taken.clear();
        c.advance(&mut s, 2.0, 1.0, |_| {}).unwrap();
        assert_eq!(s.taken, vec![0.5, 0.5]);
        assert_eq!(c.size(), 1.0);
    }

    #[test]
    fn a_step_that_fails_at_the_smallest_size_or_for_good_is_rolled_back_whole() {
        let mut s = Limited {
            x: 2.0,
            limit: 1e-9,
            taken: vec![],
        };
        let mut c = AdaptiveSubsteps::new(3);
        let e = c.advance(&mut s, 0.0, 1.0, |_| {}).unwrap_err();
        assert_eq!((e.halvings, e.dt), (3, 0.125));
        assert_eq!(s.x, 2.0);
        // An error that is not retried ends the step at once.
        struct Fatal(f64);
        impl Substepper for Fatal {
            type State = f64;
            type Info = ();
            type Error = ();
            fn save(&self) -> f64 {
                self.0
            }
            fn restore(&mut self, state: f64) {
                self.0 = state;
            }
            fn substep(&mut self, _t: f64, h: f64) -> Result<(), ()> {
                self.0 += h;
                Err(())
            }
            fn is_easy(_: &()) -> bool {
                true
            }
            fn may_retry(_: &()) -> bool {
                false
            }
        }
        let mut f = Fatal(1.0);
        let e = c.advance(&mut f, 0.0, 1.0, |_| {}).unwrap_err();
        assert_eq!((e.halvings, f.0), (0, 1.0));
    }

    /// The sub-step controller against a model of a hard phase: sizes up to `limit` converge
    /// easily, larger ones fail. Doubling after every easy sub-step failed once per accepted
    /// sub-step; now the doubled size is tried ever more rarely while it keeps failing, and once
    /// the hard phase ends the size grows back to `dt` within a bounded number of sub-steps.
    #[test]
    fn a_sub_step_size_that_keeps_failing_is_tried_ever_more_rarely() {
        let dt = 1.0_f64;
        let limit = dt / 8.0;
        let mut growth = SubstepGrowth::default();
        let mut h = dt;
        let (mut accepted, mut failed) = (0, 0);
        while accepted < 400 {
            if h <= limit {
                accepted += 1;
                if growth.accepted(true, h < dt) {
                    h = (2.0 * h).min(dt);
                }
            } else {
                failed += 1;
                growth.failed();
                h *= 0.5;
            }
        }
        // 3 failures to get down from dt, then one per MAX_EASY_BEFORE_GROWTH accepted
        // sub-steps at most.
        assert!(
            failed <= 3 + 2 + accepted / MAX_EASY_BEFORE_GROWTH,
            "{failed} failures in {accepted} accepted sub-steps"
        );
        // The hard phase ends: every size converges.
        let mut to_dt = 0;
        while h < dt {
            to_dt += 1;
            if growth.accepted(true, true) {
                h = (2.0 * h).min(dt);
            }
            assert!(
                to_dt <= MAX_EASY_BEFORE_GROWTH + 3 * 4,
                "size {h} after {to_dt}"
            );
        }
        // After a single failure the size waits for two easy sub-steps, then (the doubled
        // size converging) doubles after every one again.
        let mut growth = SubstepGrowth::default();
        growth.failed();
        let grows: Vec<bool> = (0..4).map(|_| growth.accepted(true, true)).collect();
        assert_eq!(grows, [false, true, true, true]);
        // A hard (not easy) sub-step never lets the size grow.
        assert!(!SubstepGrowth::default().accepted(false, true));
        // A failure, the size doubles back to the whole step and converges there many times,
        // then fails again: that size did not just double, so it waits for 2 easy sub-steps,
        // not 4 (the caller used to skip the controller at the whole step, leaving it
        // believing the size had just doubled).
        let mut growth = SubstepGrowth::default();
        growth.failed();
        assert!(!growth.accepted(true, true));
        assert!(growth.accepted(true, true));
        (0..50).for_each(|_| assert!(!growth.accepted(true, false)));
        growth.failed();
        let grows: Vec<bool> = (0..2).map(|_| growth.accepted(true, true)).collect();
        assert_eq!(grows, [false, true]);
    }

    #[test]
    fn a_doubled_size_that_fails_again_waits_longer_before_the_next_doubling() {
        let mut g = SubstepGrowth::default();
        // A failure: at least two easy sub-steps before the size doubles.
        g.failed();
        assert!(!g.accepted(true, true));
        assert!(g.accepted(true, true));
        // The doubled size fails: four easy sub-steps next time.
        g.failed();
        for _ in 0..3 {
            assert!(!g.accepted(true, true));
        }
        assert!(g.accepted(true, true));
        // A hard sub-step resets the streak; a size that is the whole step never grows.
        assert!(!g.accepted(false, true));
        assert!(!g.accepted(true, false));
        // A doubled size that keeps failing waits at most MAX_EASY_BEFORE_GROWTH.
        let mut g = SubstepGrowth::default();
        for _ in 0..40 {
            g.failed();
            while !g.accepted(true, true) {}
        }
        assert_eq!(g.wait, MAX_EASY_BEFORE_GROWTH);
    }
}
