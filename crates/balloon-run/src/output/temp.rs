//! The output folders being written in this process, and the removal of their temporary files
//! when a front end ends the process at once (a second signal).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The output folders of the jobs in this process, whose temporary files
/// [`remove_temp_files`] removes, each with the names of the files a job other than a run
/// writes there through `.NAME.tmp`.
static OUT_DIRS: Mutex<Vec<(PathBuf, &'static [&'static str])>> = Mutex::new(Vec::new());

/// Records `dir` as an output folder being written (done by `OutputDir::create`).
pub fn watch_out_dir(dir: &Path) {
    watch_out_files(dir, &[]);
}

/// Records `dir` as an output folder into which a job writes the files `names`, each through
/// a temporary `.NAME.tmp` (a design's files).
pub fn watch_out_files(dir: &Path, names: &'static [&'static str]) {
    if let Ok(mut dirs) = OUT_DIRS.lock() {
        match dirs.iter_mut().find(|(d, _)| d == dir) {
            Some(entry) if !names.is_empty() => entry.1 = names,
            Some(_) => {}
            None => dirs.push((dir.to_path_buf(), names)),
        }
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
    for (dir, names) in dirs
        .iter()
        .flat_map(|(d, names)| [(d.clone(), *names), (d.join("renders"), &[][..])])
    {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let named = name
                .strip_prefix('.')
                .and_then(|n| n.strip_suffix(".tmp"))
                .is_some_and(|n| names.contains(&n));
            if (named || super::is_temp_file(&name))
                && entry.file_type().is_ok_and(|t| t.is_file())
                && std::fs::remove_file(entry.path()).is_ok()
            {
                removed += 1;
            }
        }
    }
    removed
}
