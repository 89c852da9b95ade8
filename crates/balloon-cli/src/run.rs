//! The run loop of `inflate`, `volumetric` and `two-layer`, written once over
//! [`balloon::Simulation`]: the first frame, then per step the stats line, the frames (regular
//! ones as files, `--render` steps as pictures), the progress bar; then the pictures' finishing
//! (also after a failure, so everything written so far stays valid), the summary and its
//! printing, and the error (so the process exits non-zero).
//!
//! A subcommand supplies a [`RunHooks`]: how a frame of its system looks, what it adds around
//! each step (a drag, convergence, lattice files) and its summary. Nothing else differs.

use crate::output::{Frame, OutputDir, print_json_line, progress_bar};
use anyhow::Result;
use balloon::{Simulation, SimulationError, SimulationStats};
use serde::Serialize;
use std::time::Instant;

/// Which steps are written as frame files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FramePolicy {
    /// Every this many steps (0: none but the first, and the last with `last`).
    pub every: usize,
    /// The last step of the run is written too.
    pub last: bool,
}

impl FramePolicy {
    /// Whether step `step` (1-based) of a run of `steps` is a frame file.
    fn writes(self, step: usize, steps: usize) -> bool {
        (self.every > 0 && step.is_multiple_of(self.every)) || (self.last && step == steps)
    }
}

/// The run's length and output settings.
#[derive(Clone, Copy, Debug)]
pub struct RunPlan {
    /// Steps to take (at most, when a hook stops early).
    pub steps: usize,
    /// Frame files.
    pub frames: FramePolicy,
    /// Print the summary as one JSON line instead of the human line; no progress bar.
    pub json: bool,
}

/// What the loop saw, for the summary.
#[derive(Debug)]
pub struct RunRecord<D> {
    /// Steps completed in this run.
    pub steps: usize,
    /// A hook asked to stop before `steps` (e.g. converged).
    pub stopped_early: bool,
    /// Wall-clock seconds spent inside `Simulation::step`.
    pub step_seconds: f64,
    /// Frame files written (the first included).
    pub frames: usize,
    /// Statistics of the last completed step.
    pub last: Option<SimulationStats<D>>,
    /// The error that stopped the run.
    pub failure: Option<SimulationError>,
}

/// What a subcommand adds to the shared loop.
pub trait RunHooks<S: Simulation> {
    /// The summary written to `summary.json` and printed.
    type Summary: Serialize;

    /// The current state as a frame of step `step`, with the system's fields.
    fn frame(&self, sim: &S, step: usize) -> Result<Frame>;

    /// Called before each step (e.g. to set a drag).
    fn before_step(&mut self, _sim: &mut S) -> Result<()> {
        Ok(())
    }

    /// Called after each successful step, after its stats line and frame; `regular` when the step
    /// was a frame file. Returns `true` to stop the run (e.g. converged).
    fn after_step(
        &mut self,
        _sim: &S,
        _stats: &SimulationStats<S::Detail>,
        _out: Option<&mut OutputDir>,
        _regular: bool,
    ) -> Result<bool> {
        Ok(false)
    }

    /// The progress bar's message after a step.
    fn progress(&self, _stats: &SimulationStats<S::Detail>) -> Option<String> {
        None
    }

    /// Extra files once the run ended (after the pictures' `last` frame is made, before the
    /// summary), e.g. a named final frame.
    fn finish_extras(&mut self, _out: &mut OutputDir, _last: &Frame) -> Result<()> {
        Ok(())
    }

    /// The summary of the run; `None` when the subcommand writes none (e.g. after a failure).
    fn summary(&self, sim: &S, run: &RunRecord<S::Detail>) -> Option<Self::Summary>;

    /// The human line(s) printed on success (and after a failure when
    /// [`RunHooks::print_after_failure`]).
    fn print(&self, summary: &Self::Summary, out: Option<&OutputDir>);

    /// Whether the summary is still printed (JSON line or human line) after a failure.
    fn print_after_failure(&self) -> bool {
        false
    }

    /// The error the subcommand reports for a failed step `step` (1-based).
    fn failure(&self, error: SimulationError, _step: usize) -> anyhow::Error {
        error.into()
    }
}

/// Runs `sim` for `plan.steps` steps with the shared output, then finishes pictures and the
/// summary. Errors when the simulation failed (after everything computed so far is written) or
/// when an output could not be written.
pub fn run_simulation<S, H>(
    sim: &mut S,
    hooks: &mut H,
    plan: &RunPlan,
    mut out: Option<OutputDir>,
) -> Result<()>
where
    S: Simulation,
    H: RunHooks<S>,
{
    let mut run = RunRecord {
        steps: 0,
        stopped_early: false,
        step_seconds: 0.0,
        frames: 0,
        last: None,
        failure: None,
    };
    if let Some(o) = &mut out {
        o.frame(&hooks.frame(sim, 0)?, true)?;
        run.frames += 1;
    }
    let pb = progress_bar(plan.steps as u64, !plan.json);
    for step in 1..=plan.steps {
        hooks.before_step(sim)?;
        let t0 = Instant::now();
        let result = sim.step();
        run.step_seconds += t0.elapsed().as_secs_f64();
        let stats = match result {
            Ok(s) => s,
            Err(e) => {
                run.failure = Some(e);
                break;
            }
        };
        run.steps = step;
        let regular = plan.frames.writes(step, plan.steps);
        if let Some(o) = &mut out {
            o.append_stats(&stats.detail)?;
            if regular || o.wants_step(step) {
                o.frame(&hooks.frame(sim, step)?, regular)?;
                run.frames += usize::from(regular);
            }
        }
        let stop = hooks.after_step(sim, &stats, out.as_mut(), regular)?;
        pb.inc(1);
        if let Some(m) = hooks.progress(&stats) {
            pb.set_message(m);
        }
        run.last = Some(stats);
        if stop {
            run.stopped_early = true;
            break;
        }
    }
    pb.finish_and_clear();
    let failed = run.failure.is_some();
    let summary = hooks.summary(sim, &run);
    if let Some(o) = &mut out {
        let last = hooks.frame(sim, sim.steps())?;
        hooks.finish_extras(o, &last)?;
        if let Some(s) = &summary {
            o.write_json("summary.json", s)?;
        }
        match o.finish(&last, failed) {
            Ok(warnings) => warnings.iter().for_each(|w| eprintln!("warning: {w}")),
            // Do not hide the simulation error behind a picture error.
            Err(e) if failed => eprintln!("warning: {e:#}"),
            Err(e) => return Err(e),
        }
    }
    if let Some(s) = &summary
        && (!failed || hooks.print_after_failure())
    {
        if plan.json {
            print_json_line(s)?;
        } else {
            hooks.print(s, out.as_ref());
        }
    }
    match run.failure.take() {
        Some(e) => Err(hooks.failure(e, run.steps + 1)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_policies_pick_the_steps_of_each_subcommand() {
        let picked = |p: FramePolicy, steps: usize| -> Vec<usize> {
            (1..=steps).filter(|&s| p.writes(s, steps)).collect()
        };
        // inflate and volumetric: every K steps.
        let every = FramePolicy {
            every: 3,
            last: false,
        };
        assert_eq!(picked(every, 10), vec![3, 6, 9]);
        // two-layer: every K steps and the last; K = 0 only the last.
        let with_last = FramePolicy {
            every: 3,
            last: true,
        };
        assert_eq!(picked(with_last, 10), vec![3, 6, 9, 10]);
        let only_last = FramePolicy {
            every: 0,
            last: true,
        };
        assert_eq!(picked(only_last, 10), vec![10]);
        let none = FramePolicy {
            every: 0,
            last: false,
        };
        assert!(picked(none, 10).is_empty());
    }
}
