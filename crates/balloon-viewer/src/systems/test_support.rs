//! Set-up shared by the viewer's scenario, drag and saved-scenario tests.

use super::view::{DragRequest, ViewSystem};
use crate::protocol::DragMode;
use std::path::PathBuf;

/// A folder holding a coarse sphere `sphere.obj` (radius 0.1 m, 162 vertices), and its path.
pub(super) fn sphere_dir() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let sphere = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let obj = dir.path().join("sphere.obj");
    balloon_mesh::io::write_obj(&obj, &sphere).unwrap();
    (dir, obj)
}

/// A folder with the coarse sphere ([`sphere_dir`]) and `scenario.toml` of `text`, and the
/// scenario's path.
pub(super) fn scenario_dir(text: &str) -> (tempfile::TempDir, PathBuf) {
    let (dir, _) = sphere_dir();
    let path = dir.path().join("scenario.toml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// The largest difference between two flat position lists of the same length.
pub(super) fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// One drag sequence as a user's mouse makes it in the page: `pre` steps, a grab of vertex
/// `grab` pulled `pull` (m) up and right (+x, +y) in 8 moves and held `hold` steps, released for
/// `gap` steps, a pinch of vertex `pinch` towards where the page last drew it (`stale` steps
/// ago, shifted by `jitter` m) held `pinch_hold` steps, then `after` steps.
#[derive(Clone, Copy, Debug)]
pub(super) struct DragSequence {
    pub(super) pre: usize,
    pub(super) grab: usize,
    pub(super) pull: f64,
    pub(super) hold: usize,
    pub(super) gap: usize,
    pub(super) pinch: usize,
    pub(super) stale: usize,
    pub(super) jitter: f64,
    pub(super) pinch_hold: usize,
    pub(super) after: usize,
}

impl DragSequence {
    /// A random sequence on a body of `vertices` vertices, from uniform numbers in [0, 1):
    /// 5 to 29 steps before, a pull of 2 to 15 cm held 3 to 14 steps, a gap of 0 to 3 steps,
    /// a pinch 0 to 9 steps stale held 1 to 5 steps, 30 steps after.
    pub(super) fn random(vertices: usize, mut uniform: impl FnMut() -> f64) -> Self {
        let pick = |u: f64, n: usize| (u * n as f64) as usize % n;
        let pre = 5 + pick(uniform(), 25);
        let grab = pick(uniform(), vertices);
        let pull = 0.02 + 0.13 * uniform();
        let hold = 3 + pick(uniform(), 12);
        let gap = pick(uniform(), 4);
        let pinch = pick(uniform(), vertices);
        let stale = pick(uniform(), 10);
        let jitter = 0.005 * uniform();
        let pinch_hold = 1 + pick(uniform(), 5);
        Self {
            pre,
            grab,
            pull,
            hold,
            gap,
            pinch,
            stale,
            jitter,
            pinch_hold,
            after: 30,
        }
    }

    /// Plays the sequence on `view`: the error of the first step that fails, named by its
    /// phase. A drag the view undid ([`ViewSystem::take_notice`]) ends there, as the runner
    /// drops it; the notices are printed.
    pub(super) fn run(&self, view: &mut dyn ViewSystem) -> Result<(), String> {
        // What the page has drawn: the positions after every step.
        let mut drawn: Vec<Vec<f64>> = Vec::new();
        // Whether the view undid the drag in progress.
        let undone = std::cell::Cell::new(false);
        let mut step = |view: &mut dyn ViewSystem, phase: &str, k: usize| {
            view.step().map_err(|e| format!("{phase} step {k}: {e}"))?;
            if let Some(notice) = view.take_notice() {
                eprintln!("{phase} step {k}: {notice}");
                undone.set(true);
            }
            drawn.push(view.positions());
            Ok::<_, String>(drawn[drawn.len() - 1 - self.stale.min(drawn.len() - 1)].clone())
        };
        let drag = |view: &mut dyn ViewSystem, request: Option<DragRequest>| {
            if request.is_none() {
                // The sequence's release: its next drag is a new one.
                undone.set(false);
            }
            let request = request.filter(|_| !undone.get());
            view.apply_drag(request.as_ref())
                .map_err(|e| format!("drag {request:?}: {e}"))
        };
        let mut seen = Vec::new();
        for k in 0..self.pre {
            seen = step(view, "before", k)?;
        }
        let x = view.positions();
        let mut target = [x[3 * self.grab], x[3 * self.grab + 1], x[3 * self.grab + 2]];
        for k in 0..self.hold {
            if k < 8 {
                target[0] += self.pull / 8.0;
                target[1] += self.pull / 8.0;
            }
            let grab = DragRequest {
                vertex: self.grab,
                target,
                mode: DragMode::Grab,
            };
            drag(view, Some(grab))?;
            seen = step(view, "grab", k)?;
        }
        drag(view, None)?;
        for k in 0..self.gap {
            seen = step(view, "gap", k)?;
        }
        let w = self.pinch;
        let pinch = DragRequest {
            vertex: w,
            target: [
                seen[3 * w] + self.jitter,
                seen[3 * w + 1] - self.jitter,
                seen[3 * w + 2],
            ],
            mode: DragMode::Pinch,
        };
        for k in 0..self.pinch_hold {
            drag(view, Some(pinch))?;
            step(view, "pinch", k)?;
        }
        drag(view, None)?;
        for k in 0..self.after {
            step(view, "after the pinch", k)?;
        }
        Ok(())
    }
}

/// Plays `TRIALS` (default 10) random drag sequences ([`DragSequence::random`], seeded by
/// `SEED`, default 1; with `HOLD=N` the grab and the pinch are held up to `N` steps) on fresh
/// views from `view`, printing each sequence, its outcome and the
/// count of failures. A measurement, not a check: the ignored tests that call it say where
/// its figures are used.
pub(super) fn random_drag_sequences<V: ViewSystem>(mut view: impl FnMut() -> V) {
    let var = |name: &str, default: u64| {
        std::env::var(name)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default)
    };
    let (trials, seed) = (var("TRIALS", 10), var("SEED", 1));
    let hold = std::env::var("HOLD")
        .ok()
        .and_then(|s| s.parse::<usize>().ok());
    // A linear congruential generator (Knuth's MMIX constants), uniform in [0, 1).
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64) / ((1u64 << 53) as f64)
    };
    let mut failed = 0;
    for trial in 0..trials {
        let mut v = view();
        let mut sequence = DragSequence::random(v.positions().len() / 3, &mut uniform);
        if let Some(most) = hold {
            // Holds as long as a slow page makes them (the e2e test's pinch lasted tens of
            // steps on a fast server).
            sequence.hold = 3 + (uniform() * most as f64) as usize;
            sequence.pinch_hold = 1 + (uniform() * most as f64) as usize;
        }
        let outcome = sequence.run(&mut v);
        failed += usize::from(outcome.is_err());
        eprintln!("trial {trial}: {sequence:?}: {outcome:?}");
    }
    eprintln!("{failed} of {trials} sequences failed");
}
