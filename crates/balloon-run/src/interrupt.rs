//! Interruptions between steps: a front end that catches SIGINT (Ctrl-C) or SIGTERM reports
//! them through a checker ([`set_checker`]) that the run loop asks between two steps
//! ([`pending`]). The run then finishes the step it is in, writes its records
//! (`summary.json` with `"interrupted": true`, the frames so far) and ends with [`Interrupted`],
//! whose [`Interrupted::exit_code`] is 128 + the signal number (130 for SIGINT, 143 for
//! SIGTERM), as a shell reports a process killed by it.
//!
//! ```
//! assert_eq!(balloon_run::interrupt::pending(), None); // no checker set: never interrupted
//! let i = balloon_run::interrupt::Interrupted { signal: 2, steps: 7 };
//! assert_eq!(i.exit_code(), 130);
//! assert!(i.to_string().starts_with("interrupted by SIGINT after 7 completed step(s)"));
//! ```

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

/// The function [`pending`] asks (set once per process).
static CHECKER: OnceLock<fn() -> Option<i32>> = OnceLock::new();

/// Sets the function [`pending`] asks between steps for an interruption (once per process;
/// returns `false` when one was already set). It returns the signal number that stops the run:
/// the command-line tool's signal handlers, or the Python interpreter's (Ctrl-C in Python).
pub fn set_checker(check: fn() -> Option<i32>) -> bool {
    CHECKER.set(check).is_ok()
}

/// The interruption the checker reports now, if any.
pub fn pending() -> Option<i32> {
    CHECKER.get().and_then(|check| check())
}

/// The output folders of the runs in this process, whose temporary files
/// [`remove_temp_files`] removes.
static OUT_DIRS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Records `dir` as an output folder being written (done by `OutputDir::create`).
pub fn watch_out_dir(dir: &Path) {
    if let Ok(mut dirs) = OUT_DIRS.lock()
        && !dirs.iter().any(|d| d == dir)
    {
        dirs.push(dir.to_path_buf());
    }
}

/// Removes the temporary files (`.NAME.tmp`, `frame_N.tmp`, in the folder and its `renders/`)
/// of every output folder being written: what a front end does before it ends the process at
/// once (a second Ctrl-C while a GIF is encoded), so that no temporary file survives. Returns
/// how many were removed.
pub fn remove_temp_files() -> usize {
    let dirs = match OUT_DIRS.lock() {
        Ok(d) => d.clone(),
        Err(_) => return 0,
    };
    let mut removed = 0;
    for dir in dirs.iter().flat_map(|d| [d.clone(), d.join("renders")]) {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            if crate::output::is_temp_file(&name)
                && entry.file_type().is_ok_and(|t| t.is_file())
                && std::fs::remove_file(entry.path()).is_ok()
            {
                removed += 1;
            }
        }
    }
    removed
}

/// SIGINT's number.
const SIGINT: i32 = 2;
/// SIGTERM's number.
const SIGTERM: i32 = 15;

/// A run stopped by a signal after writing its records.
#[derive(Debug, thiserror::Error)]
#[error(
    "interrupted by {} after {steps} completed step(s); the records of the run so far are written",
    signal_name(*signal)
)]
pub struct Interrupted {
    /// The signal number.
    pub signal: i32,
    /// Steps (or static points) completed before it.
    pub steps: usize,
}

impl Interrupted {
    /// The process exit status: 128 + the signal number.
    pub fn exit_code(&self) -> u8 {
        u8::try_from(128 + self.signal).unwrap_or(1)
    }
}

fn signal_name(signal: i32) -> String {
    match signal {
        SIGINT => "SIGINT".into(),
        SIGTERM => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}
