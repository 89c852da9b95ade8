//! Shared output of the subcommands: an output folder with frames, `stats.jsonl` (one JSON object
//! per step, flushed line by line so a failed run leaves a readable file), `summary.json` (written
//! atomically: temporary file, then rename), a JSON summary line on stdout, and a progress bar.

use anyhow::{Context, Result};
use balloon_mesh::TriMesh;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};

/// File format of surface frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameFormat {
    /// Wavefront OBJ.
    #[default]
    Obj,
    /// Binary little-endian PLY.
    Ply,
}

impl FrameFormat {
    fn extension(self) -> &'static str {
        match self {
            FrameFormat::Obj => "obj",
            FrameFormat::Ply => "ply",
        }
    }
}

/// An output folder for one run.
pub struct OutputDir {
    dir: PathBuf,
    format: FrameFormat,
    stats: Option<BufWriter<File>>,
}

impl OutputDir {
    /// Creates (or reuses) the folder `dir` and an empty `stats.jsonl` in it, so a run that fails
    /// at its first step still leaves a (valid, empty) stats file.
    pub fn create(dir: &Path, format: FrameFormat) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let path = dir.join("stats.jsonl");
        let f = File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            format,
            stats: Some(BufWriter::new(f)),
        })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes surface frame `index` as `frame_NNNNN.<ext>` and returns its path.
    pub fn write_frame(&self, index: usize, mesh: &TriMesh) -> Result<PathBuf> {
        let path = self
            .dir
            .join(format!("frame_{index:05}.{}", self.format.extension()));
        self.write_mesh(&path, mesh)?;
        Ok(path)
    }

    /// Writes `mesh` to `name` inside the folder (format from the frame format).
    pub fn write_named_mesh(&self, stem: &str, mesh: &TriMesh) -> Result<PathBuf> {
        let path = self.dir.join(format!("{stem}.{}", self.format.extension()));
        self.write_mesh(&path, mesh)?;
        Ok(path)
    }

    fn write_mesh(&self, path: &Path, mesh: &TriMesh) -> Result<()> {
        // Write to a temporary name and rename, so a frame is either complete or absent.
        let tmp = path.with_extension("tmp");
        match self.format {
            FrameFormat::Obj => balloon_mesh::io::write_obj(&tmp, mesh)?,
            FrameFormat::Ply => balloon_mesh::io::write_ply_binary(&tmp, mesh)?,
        }
        std::fs::rename(&tmp, path)
            .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))?;
        Ok(())
    }

    /// Appends one JSON object as a line of `stats.jsonl` and flushes it.
    pub fn append_stats<T: Serialize>(&mut self, row: &T) -> Result<()> {
        if self.stats.is_none() {
            let path = self.dir.join("stats.jsonl");
            let f =
                File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
            self.stats = Some(BufWriter::new(f));
        }
        let w = self.stats.as_mut().expect("stats writer exists");
        serde_json::to_writer(&mut *w, row)?;
        w.write_all(b"\n")?;
        w.flush()?;
        Ok(())
    }

    /// Writes `value` as pretty JSON to `name` (e.g. `summary.json`) atomically.
    pub fn write_json<T: Serialize>(&self, name: &str, value: &T) -> Result<PathBuf> {
        let path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        std::fs::write(&tmp, serde_json::to_vec_pretty(value)?)
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        std::fs::rename(&tmp, &path)?;
        Ok(path)
    }
}

/// Prints `value` as one JSON line on stdout (the last line a `--json` run prints).
pub fn print_json_line<T: Serialize>(value: &T) -> Result<()> {
    let mut out = std::io::stdout().lock();
    serde_json::to_writer(&mut out, value)?;
    out.write_all(b"\n")?;
    out.flush()?;
    Ok(())
}

/// A progress bar over `len` steps, drawn on stderr only when `enabled` and stderr is a terminal.
pub fn progress_bar(len: u64, enabled: bool) -> ProgressBar {
    if !enabled || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} steps {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}
