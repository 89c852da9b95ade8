//! The run loop of every system, written once over
//! [`balloon::Simulation`]: the first frame, then per step the stats line, the frames (regular
//! ones as files, `render` steps as pictures), the progress bar; then the pictures' finishing,
//! the summary and its printing, and the error (so the process exits non-zero).
//!
//! The records are written however the run ends: completed, stopped early (converged), failed
//! (a step's error, an output error, no progress), or interrupted by SIGINT / SIGTERM (checked
//! between steps, see [`crate::interrupt`]). `summary.json` and the `json` line then always
//! carry `steps` (completed steps), `frames`, `interrupted` and `error` (null on success).
//!
//! Steps are counted from 1: step N is the N-th step, `frame_N` and the `stats.jsonl` line
//! with `"step": N` are the state after it, `frame_00000` is the initial state, and a failure
//! "at step N" means N - 1 steps completed (`docs/outputs.md`).
//!
//! A system's job supplies a [`RunHooks`]: how a frame of its system looks, what it adds around
//! each step (a drag, convergence, lattice files) and its summary. Nothing else differs.

use crate::interrupt::{self, Interrupted};
use crate::output::{Frame, OutputDir, print_json_line, progress_bar};

use anyhow::Result;
use balloon::{Simulation, SimulationError, SimulationStats};
use serde::Serialize;
use std::io::Write;
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
    /// Print nothing (no progress bar, no summary line): the caller takes the returned summary
    /// (the Python package).
    pub quiet: bool,
}

/// A job that ran to its end: its summary and the simulation in its final state.
pub struct Finished<S> {
    /// The summary as `summary.json` holds it (with `interrupted`, `frames` and `error`).
    pub summary: Option<serde_json::Value>,
    /// The simulation after the last step.
    pub sim: S,
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
    /// The signal (SIGINT, SIGTERM) that stopped the run between two steps.
    pub interrupted: Option<i32>,
}

/// What a system's job adds to the shared loop.
pub trait RunHooks<S: Simulation> {
    /// The summary written to `summary.json` and printed (a JSON object; the loop adds
    /// `interrupted`, and `frames` and `error` when the summary has none).
    type Summary: Serialize;

    /// The current state as a frame of step `step`, with the system's fields.
    fn frame(&self, sim: &S, step: usize) -> Result<Frame>;

    /// The run's resolved scenario (the TOML text of `scenario.toml`), repeated in the summary
    /// as `scenario` so that `summary.json` and the `json` line carry every physical
    /// parameter of the run (issue 15, item 2). `None` leaves the key out.
    fn scenario(&self) -> Option<String> {
        None
    }

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

    /// A warning worth giving while the run goes on, after `step` of the `planned` steps
    /// (e.g. that its first steps were slow, and why), so that the user can stop a long run
    /// early instead of reading it in the summary at the end. Printed at once (human output
    /// only); the hook gives each warning once.
    fn early_warning(&mut self, _sim: &S, _step: usize, _planned: usize) -> Option<String> {
        None
    }

    /// Extra files once the run ended (after the pictures' `last` frame is made, before the
    /// summary), e.g. a named final frame.
    fn finish_extras(&mut self, _out: &mut OutputDir, _last: &Frame) -> Result<()> {
        Ok(())
    }

    /// Why a run whose steps all succeeded still did nothing it should have (e.g. the shell
    /// never moved under a load: a linear solver that makes no progress). The run is then an
    /// error. Checked only for runs that completed their steps.
    fn no_progress(&self, _sim: &S, _run: &RunRecord<S::Detail>) -> Option<String> {
        None
    }

    /// The summary of the run (also after a failure or an interruption).
    fn summary(&self, sim: &S, run: &RunRecord<S::Detail>) -> Self::Summary;

    /// Writes the human line(s) to `w` on success (and after a failure when
    /// [`RunHooks::print_after_failure`]).
    fn print(
        &self,
        summary: &Self::Summary,
        out: Option<&OutputDir>,
        w: &mut dyn Write,
    ) -> std::io::Result<()>;

    /// Whether the human line is still printed after a failure (the `json` line always is).
    fn print_after_failure(&self) -> bool {
        false
    }

    /// The error the job reports for a failed step `step` (1-based: `step - 1` steps
    /// completed).
    fn failure(&self, error: SimulationError, step: usize) -> anyhow::Error {
        anyhow::Error::new(error).context(format!(
            "step {step} failed ({} step(s) completed)",
            step - 1
        ))
    }
}

/// The error of a failed step `step` (1-based) of `what` ("the simulation of `MESH`"), saying how
/// many steps completed and, when there is one, which output folder keeps them.
pub fn step_failure(
    error: SimulationError,
    what: &str,
    step: usize,
    out: Option<&std::path::Path>,
) -> anyhow::Error {
    let kept = match out {
        Some(dir) => format!("; the output of the steps before is in {}", dir.display()),
        None => String::new(),
    };
    anyhow::Error::new(error).context(format!(
        "{what} failed at step {step} ({} step(s) completed){kept}",
        step - 1
    ))
}

/// A `stats.jsonl` line: the system's statistics with `step` set to the 1-based step number
/// (the systems count their own `step` fields differently).
fn stats_row<D: Serialize>(stats: &SimulationStats<D>) -> Result<serde_json::Value> {
    let mut row = serde_json::to_value(&stats.detail)?;
    if let Some(obj) = row.as_object_mut() {
        obj.insert("step".into(), stats.steps.into());
    }
    Ok(row)
}

/// Runs the steps; a step's error ends the loop in `run.failure`, an output or hook error is
/// returned.
fn step_loop<S, H>(
    sim: &mut S,
    hooks: &mut H,
    plan: &RunPlan,
    out: &mut Option<OutputDir>,
    run: &mut RunRecord<S::Detail>,
) -> Result<()>
where
    S: Simulation,
    H: RunHooks<S>,
{
    if let Some(o) = out {
        o.frame(&hooks.frame(sim, 0)?, true)?;
        run.frames += 1;
    }
    let pb = progress_bar(plan.steps as u64, !plan.json && !plan.quiet);
    for step in 1..=plan.steps {
        if let Some(sig) = interrupt::pending() {
            run.interrupted = Some(sig);
            break;
        }
        hooks.before_step(sim)?;
        let t0 = Instant::now();
        let result = sim.step();
        run.step_seconds += t0.elapsed().as_secs_f64();
        let stats = match result {
            Ok(s) => s,
            Err(e) => {
                // A step abandoned because a signal arrived during its Newton iterations is an
                // interruption, not a failure (the state is the last accepted one).
                match interrupt::pending() {
                    Some(sig) => run.interrupted = Some(sig),
                    None => run.failure = Some(e),
                }
                break;
            }
        };
        run.steps = step;
        let regular = plan.frames.writes(step, plan.steps);
        if let Some(o) = out {
            o.append_stats(&stats_row(&stats)?)?;
            if regular || o.wants_step(step) {
                o.frame(&hooks.frame(sim, step)?, regular)?;
                run.frames += usize::from(regular);
            }
        }
        let stop = hooks.after_step(sim, &stats, out.as_mut(), regular)?;
        if !plan.json
            && !plan.quiet
            && let Some(w) = hooks.early_warning(sim, step, plan.steps)
        {
            pb.suspend(|| eprintln!("warning: {w}"));
        }
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
    Ok(())
}

/// Adds `scenario`, the resolved scenario's TOML `text` as a JSON object, to a summary object
/// (a text that does not parse, which `balloon_scenario::file::record` never writes, adds
/// nothing).
pub fn insert_scenario(summary: &mut serde_json::Value, text: &str) {
    if let (Some(o), Some(scenario)) = (
        summary.as_object_mut(),
        balloon_scenario::file::record_json(text),
    ) {
        o.insert("scenario".into(), scenario);
    }
}

/// Adds what every summary carries: `interrupted`, and `frames` and `error` unless the
/// system's summary has them (an `error` it left null is filled in). A `status` of `"ok"`
/// becomes `"failed"` when there is an error the system did not see (an output that could
/// not be written, a run that made no progress).
fn annotate(
    summary: &mut serde_json::Value,
    interrupted: bool,
    frames: usize,
    error: Option<&str>,
) {
    if let Some(obj) = summary.as_object_mut() {
        obj.insert("interrupted".into(), interrupted.into());
        obj.entry("frames").or_insert_with(|| frames.into());
        let e = obj.entry("error").or_insert(serde_json::Value::Null);
        if e.is_null()
            && let Some(text) = error
        {
            *e = text.into();
            if let Some(status) = obj.get_mut("status")
                && status == "ok"
            {
                *status = "failed".into();
            }
        }
    }
}

/// Runs `sim` for `plan.steps` steps with the shared output, then finishes pictures and the
/// summary. Errors when the simulation failed, made no progress or was interrupted (after
/// everything computed so far is written), or when an output could not be written (after the
/// summary is written if it still can be). Returns the summary as `summary.json` holds it.
pub fn run_simulation<S, H>(
    sim: &mut S,
    hooks: &mut H,
    plan: &RunPlan,
    mut out: Option<OutputDir>,
) -> Result<serde_json::Value>
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
        interrupted: None,
    };
    let output_error = step_loop(sim, hooks, plan, &mut out, &mut run).err();
    let stalled = if run.failure.is_none() && output_error.is_none() && run.interrupted.is_none() {
        hooks.no_progress(sim, &run)
    } else {
        None
    };
    let failed = run.failure.is_some() || output_error.is_some() || stalled.is_some();
    let summary = hooks.summary(sim, &run);
    let mut record = serde_json::to_value(&summary)?;
    let error_text = run
        .failure
        .as_ref()
        .map(ToString::to_string)
        .or_else(|| stalled.clone())
        .or_else(|| output_error.as_ref().map(|e| format!("{e:#}")));
    annotate(
        &mut record,
        run.interrupted.is_some(),
        run.frames,
        error_text.as_deref(),
    );
    if let Some(text) = hooks.scenario() {
        insert_scenario(&mut record, &text);
    }
    // Everything below is attempted even when a part fails; the first error is kept.
    let mut finish_error: Option<anyhow::Error> = None;
    if let Some(o) = &mut out {
        let mut keep = |r: Result<()>| {
            if let Err(e) = r {
                if finish_error.is_none() {
                    finish_error = Some(e);
                } else {
                    eprintln!("warning: {e:#}");
                }
            }
        };
        match hooks.frame(sim, run.steps) {
            Ok(last) => {
                keep(hooks.finish_extras(o, &last));
                keep(o.write_json("summary.json", &record).map(drop));
                match o.finish(&last, failed) {
                    Ok(warnings) => warnings.iter().for_each(|w| eprintln!("warning: {w}")),
                    // Do not hide the simulation error behind a picture error.
                    Err(e) if failed => eprintln!("warning: {e:#}"),
                    Err(e) => keep(Err(e)),
                }
            }
            Err(e) => {
                keep(o.write_json("summary.json", &record).map(drop));
                keep(Err(e));
            }
        }
    }
    if plan.quiet {
        // The caller reports.
    } else if plan.json {
        print_json_line(&record)?;
    } else if !failed || hooks.print_after_failure() {
        // After a write failure the folder is not named as "written".
        let written = if output_error.is_some() || finish_error.is_some() {
            None
        } else {
            out.as_ref()
        };
        let mut stdout = std::io::stdout().lock();
        hooks.print(&summary, written, &mut stdout)?;
        stdout.flush()?;
    }
    if let Some(e) = run.failure.take() {
        if let Some(f) = &finish_error {
            eprintln!("warning: {f:#}");
        }
        return Err(hooks.failure(e, run.steps + 1));
    }
    if let Some(e) = output_error {
        if let Some(f) = &finish_error {
            eprintln!("warning: {f:#}");
        }
        return Err(e);
    }
    if let Some(msg) = stalled {
        anyhow::bail!("{msg}");
    }
    if let Some(e) = finish_error {
        return Err(e);
    }
    if let Some(signal) = run.interrupted {
        return Err(Interrupted {
            signal,
            steps: run.steps,
        }
        .into());
    }
    Ok(record)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries_get_interrupted_frames_and_a_missing_or_null_error() {
        let mut with_error_field = serde_json::json!({"steps": 3, "error": null, "frames": 7});
        annotate(&mut with_error_field, true, 2, Some("boom"));
        assert_eq!(
            with_error_field,
            serde_json::json!({"steps": 3, "error": "boom", "frames": 7, "interrupted": true})
        );
        let mut bare = serde_json::json!({"steps": 0});
        annotate(&mut bare, false, 1, None);
        assert_eq!(
            bare,
            serde_json::json!({"steps": 0, "error": null, "frames": 1, "interrupted": false})
        );
        // The subcommand's own error text is kept.
        let mut own = serde_json::json!({"error": "step 4: diverged"});
        annotate(&mut own, false, 0, Some("other"));
        assert_eq!(own["error"], "step 4: diverged");
    }

    #[test]
    fn stats_rows_carry_the_one_based_step() {
        #[derive(Serialize)]
        struct Detail {
            step: usize,
            x: f64,
        }
        let stats = SimulationStats {
            steps: 5,
            time: 0.5,
            dt: 0.1,
            kinetic_energy: 0.0,
            detail: Detail { step: 4, x: 1.5 },
        };
        assert_eq!(
            stats_row(&stats).unwrap(),
            serde_json::json!({"step": 5, "x": 1.5})
        );
    }

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
