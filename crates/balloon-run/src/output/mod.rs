//! The output folder of a run: frames, `stats.jsonl` (one JSON object per step, flushed line
//! by line so a failed run leaves a readable file), `summary.json` (written atomically:
//! temporary file, then rename), the pictures ([`pictures`]); and the summary line on stdout and
//! the progress bar.
//!
//! Frames are OBJ, PLY or VTK XML PolyData (`.vtp`, with per-vertex and per-face fields, listed
//! with their times in `series.pvd`, rewritten after every frame), or one USD stage `run.usda`
//! for the whole run ([`usd`]). Every file is written
//! atomically, and [`OutputDir::finish`] is also called when a run fails, so everything written
//! so far stays valid.

pub mod frame;
pub mod pictures;
pub mod temp;
pub mod usd;

pub use balloon_scenario::output::ColorField;
pub use frame::{Body, Field, Frame};
pub use pictures::PictureStyle;

use anyhow::{Context, Result, bail};
use balloon::mesh::TriMesh;
use balloon::mesh::io::{PvdWriter, VtkEncoding, VtpArray};
use balloon_render::{Prop, Renderer, Surface};
use balloon_scenario::output::{FrameFormat, Output, RenderSpec};
use indicatif::{ProgressBar, ProgressStyle};
use pictures::{Pictures, keep_for_gif, render_options, render_png, write_gif};
use serde::Serialize;
use std::collections::BTreeSet;
use std::fs::File;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

/// An output folder for one run.
pub struct OutputDir {
    dir: PathBuf,
    format: FrameFormat,
    /// `stats.jsonl`, written a whole line at a time (see [`append_whole_line`]).
    stats: Option<File>,
    /// Bytes of complete lines in `stats.jsonl`.
    stats_len: u64,
    pvd: Option<PvdWriter>,
    pictures: Option<Pictures>,
    /// The floor file (`floor.<ext>`) is written (once: the floor does not move).
    floor_written: bool,
    /// The run's USD stage (`run.usda`) with the USD format.
    usd: Option<usd::UsdWriter>,
    /// The scene's up axis (from the picture style).
    up: balloon_render::UpAxis,
}

/// Whether `name` is a file this program writes into an output folder (frames, records,
/// pictures, their temporary files), so `overwrite` may remove it. Anything else is the
/// user's and is never touched.
fn is_run_file(name: &str) -> bool {
    const EXACT: &[&str] = &[
        "stats.jsonl",
        "summary.json",
        "scenario.toml",
        "series.pvd",
        "run.gif",
        "final.pov",
        "lattice.vtk",
        "run.usda",
    ];
    let name = name
        .strip_prefix('.')
        .and_then(|n| n.strip_suffix(".tmp"))
        .unwrap_or(name);
    let numbered = |prefix: &str, exts: &[&str]| {
        name.strip_prefix(prefix)
            .and_then(|rest| rest.split_once('.'))
            .is_some_and(|(n, ext)| {
                !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) && exts.contains(&ext)
            })
    };
    let named = |stem: &str, exts: &[&str]| {
        name.strip_prefix(stem)
            .and_then(|rest| rest.strip_prefix('.'))
            .is_some_and(|ext| exts.contains(&ext))
    };
    let frames = ["obj", "ply", "vtp", "usda", "tmp"];
    EXACT.contains(&name)
        || numbered("frame_", &frames)
        || numbered("lattice_", &["vtk"])
        || name
            .strip_prefix("sphere")
            .and_then(|rest| rest.split_once('_'))
            .is_some_and(|(k, rest)| {
                k.bytes().all(|b| b.is_ascii_digit())
                    && rest.split_once('.').is_some_and(|(n, ext)| {
                        !n.is_empty()
                            && n.bytes().all(|b| b.is_ascii_digit())
                            && frames.contains(&ext)
                    })
            })
        || named("floor", &frames)
        || named("final", &frames)
        || named("input_soup", &frames)
}

/// Whether `name` is a temporary file this program writes into an output folder (a file it
/// writes, as `.NAME.tmp` or, for OBJ / PLY frames, `NAME.tmp`; a render `.frame_N.png.tmp`).
pub(crate) fn is_temp_file(name: &str) -> bool {
    name.ends_with(".tmp")
        && (is_run_file(name)
            || name == ".pressure_volume.png.tmp"
            || name
                .strip_prefix(".frame_")
                .and_then(|n| n.strip_suffix(".png.tmp"))
                .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit())))
}

/// Checks the output folder before any work: a path that exists but is not a folder is refused,
/// and so is a folder holding an earlier run's files (they would mix with this run's: a shorter
/// run leaves the old frames beyond its end) unless `overwrite`, and a folder where one of those
/// files is an input this process has read (e.g. `out = "."` beside the scenario file
/// `scenario.toml`: it would be replaced). Removes nothing: [`prepare_out_dir`] does, once the
/// run is set up.
pub fn check_out_dir(dir: &Path, overwrite: bool) -> Result<()> {
    old_run_files(dir, overwrite).map(drop)
}

/// Checks the output folder as [`check_out_dir`] does and, with `overwrite`, removes the earlier
/// run's files (see `is_run_file`; `renders/frame_*.png` too) and nothing else. Called once the
/// new run is set up (its mesh and inputs read, its parameters valid), so a run that cannot
/// start leaves the earlier one in place; an input of the run is never removed.
pub fn prepare_out_dir(dir: &Path, overwrite: bool) -> Result<()> {
    let old = old_run_files(dir, overwrite)?;
    for f in &old {
        std::fs::remove_file(f).with_context(|| format!("cannot remove {}", f.display()))?;
    }
    // The renders folder goes too when nothing else is in it.
    let renders = dir.join("renders");
    if !old.is_empty() && renders.is_dir() {
        let _ = std::fs::remove_dir(&renders);
    }
    Ok(())
}

/// The earlier run's files in `dir` (refused unless `overwrite`; an input of this process is
/// refused always).
fn old_run_files(dir: &Path, overwrite: bool) -> Result<Vec<PathBuf>> {
    old_files(dir, overwrite, &is_run_file, true, "run")
}

/// [`check_out_dir`] for a job that writes the files `names` (and nothing else) into `dir`,
/// `what` naming the job in the error (`design`): a path that is not a folder, a folder holding
/// one of them without `overwrite`, or holding one that is an input of this process, is
/// refused. Removes nothing.
pub fn check_out_dir_files(dir: &Path, overwrite: bool, names: &[&str], what: &str) -> Result<()> {
    old_files(dir, overwrite, &|n| names.contains(&n), false, what).map(drop)
}

/// [`check_out_dir_files`], then with `overwrite` the removal of those of `names` that `dir`
/// holds, so that the job's files are all its own (a design without a fitted wall leaves no
/// `rest.ply` of an earlier one). Nothing else is touched.
pub fn prepare_out_dir_files(
    dir: &Path,
    overwrite: bool,
    names: &[&str],
    what: &str,
) -> Result<()> {
    for f in old_files(dir, overwrite, &|n| names.contains(&n), false, what)? {
        std::fs::remove_file(&f).with_context(|| format!("cannot remove {}", f.display()))?;
    }
    Ok(())
}

/// The files of an earlier job in `dir` (those `ours` names, and with `renders` the rendered
/// frames in `renders/`), refused as [`check_out_dir`] says.
fn old_files(
    dir: &Path,
    overwrite: bool,
    ours: &dyn Fn(&str) -> bool,
    renders: bool,
    what: &str,
) -> Result<Vec<PathBuf>> {
    let meta = match std::fs::metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => {
            return Err(e).with_context(|| format!("cannot read `out` = {}", dir.display()));
        }
    };
    if !meta.is_dir() {
        bail!("`out` = {} exists and is not a folder", dir.display());
    }
    let mut old: Vec<PathBuf> = Vec::new();
    let list = |d: &Path, png: bool, old: &mut Vec<PathBuf>| -> Result<()> {
        let entries =
            std::fs::read_dir(d).with_context(|| format!("cannot list {}", d.display()))?;
        for entry in entries {
            let entry = entry.with_context(|| format!("cannot list {}", d.display()))?;
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let ours = if png {
                name.strip_prefix("frame_")
                    .and_then(|n| n.strip_suffix(".png"))
                    .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            } else {
                ours(&name)
            };
            if ours && entry.file_type().is_ok_and(|t| t.is_file()) {
                old.push(entry.path());
            }
        }
        Ok(())
    };
    list(dir, false, &mut old)?;
    let renders_dir = dir.join("renders");
    if renders && renders_dir.is_dir() {
        list(&renders_dir, true, &mut old)?;
    }
    old.sort();
    if let Some(input) = old.iter().find(|f| balloon::mesh::io::was_read(f)) {
        bail!(
            "`out` = {} holds {}, an input of this {what}, where the {what} writes its own \
             file of that name; choose another output folder",
            dir.display(),
            input.display()
        );
    }
    if old.is_empty() {
        return Ok(old);
    }
    if !overwrite {
        bail!(
            "`out` = {} already holds the files of an earlier {what} ({} file(s), e.g. {}); \
             choose another folder or add `overwrite` to remove them first",
            dir.display(),
            old.len(),
            old[0]
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        );
    }
    Ok(old)
}

/// Writes a file at `path` through `tmp` and a rename; on any failure `tmp` is removed, so a
/// failed write leaves no temporary file, and the error names `path`.
pub(crate) fn write_via_tmp(
    path: &Path,
    tmp: &Path,
    write: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let result = write(tmp).and_then(|()| {
        std::fs::rename(tmp, path).with_context(|| format!("cannot write {}", path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    result.with_context(|| format!("cannot write {}", path.display()))
}

impl OutputDir {
    /// Creates (or reuses, after [`prepare_out_dir`]) the folder `dir` and an empty
    /// `stats.jsonl` in it, so a run that fails at its first step still leaves a (valid,
    /// empty) stats file. With the VTK format, also an empty `series.pvd`.
    pub fn create(dir: &Path, format: FrameFormat) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        temp::watch_out_dir(dir);
        let path = dir.join("stats.jsonl");
        let f = File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
        let pvd = match format {
            FrameFormat::Vtk => {
                let p = dir.join("series.pvd");
                Some(
                    PvdWriter::create(&p)
                        .with_context(|| format!("cannot write {}", p.display()))?,
                )
            }
            _ => None,
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            format,
            stats: Some(f),
            stats_len: 0,
            pvd,
            pictures: None,
            floor_written: false,
            usd: (format == FrameFormat::Usd)
                .then(|| usd::UsdWriter::new(&dir.join("run.usda"), balloon_render::UpAxis::Y)),
            up: balloon_render::UpAxis::Y,
        })
    }

    /// Enables the picture outputs of `args` (checked, and `render` parsed into `spec`, by
    /// [`Output::check_pictures`]).
    pub fn with_pictures(
        mut self,
        args: &Output,
        spec: Option<RenderSpec>,
        style: PictureStyle,
    ) -> Result<Self> {
        self.up = style.camera.up;
        if let Some(u) = &mut self.usd {
            *u = usd::UsdWriter::new(u.path(), style.camera.up);
        }
        if spec.is_none() && !args.gif && !args.pov {
            return Ok(self);
        }
        if spec.is_some() {
            let r = self.dir.join("renders");
            std::fs::create_dir_all(&r)
                .with_context(|| format!("cannot create {}", r.display()))?;
        }
        let color = args.color.unwrap_or(style.default_color);
        self.pictures = Some(Pictures {
            spec,
            gif: args.gif,
            pov: args.pov,
            color,
            color_range: args.color_range,
            label: "",
            size: args.image_size,
            style,
            renderer: Renderer::new(),
            triangles: Vec::new(),
            gif_frames: Vec::new(),
            gif_stride: 1,
            gif_seen: 0,
            rendered: BTreeSet::new(),
            last_written: None,
        });
        Ok(self)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Whether step `step` must be captured as a frame for `render` even if it is not a
    /// regular frame step.
    pub fn wants_step(&self, step: usize) -> bool {
        self.pictures
            .as_ref()
            .and_then(|p| p.spec.as_ref())
            .is_some_and(|s| s.steps.contains(&step))
    }

    /// Handles frame `frame`: writes `frame_NNNNN.<ext>` when `as_file` (and adds it to
    /// `series.pvd` for VTK), renders it when `render` asks for its step (or `all` and
    /// `as_file`), and keeps it for the GIF when `as_file`.
    ///
    /// The frame's rigid objects go into side files of the same format, so that the frame file
    /// stays the simulated surface alone for every reader: a sphere as `sphere_NNNNN.<ext>`
    /// (an icosphere of 642 vertices on the sphere, the second and further spheres
    /// `sphereK_NNNNN`), a plane as `floor.<ext>` (one quad, written with the first frame: it
    /// does not move). With VTK, `series.pvd` lists them at the frame's time as parts 1, 2, ...
    /// after the surface (part 0).
    ///
    /// With the USD format a frame file is instead a time sample of `run.usda`, which holds the
    /// props as its own prims ([`usd`]).
    pub fn frame(&mut self, frame: &Frame, as_file: bool) -> Result<()> {
        if let (Some(u), true) = (&mut self.usd, as_file) {
            u.push(frame)?;
        } else if as_file {
            let ext = self.format.extension();
            let name = format!("frame_{:05}.{ext}", frame.step);
            let path = self.dir.join(&name);
            self.write_frame_file(&path, frame)?;
            let mut parts = vec![name];
            let mut spheres = 0;
            for prop in &frame.props {
                let (name, positions, triangles) = match prop {
                    Prop::Sphere { .. } => {
                        let (x, t) = prop.mesh()?;
                        let stem = match spheres {
                            0 => "sphere".to_string(),
                            k => format!("sphere{k}"),
                        };
                        spheres += 1;
                        (format!("{stem}_{:05}.{ext}", frame.step), x, t)
                    }
                    Prop::Plane { .. } => {
                        let c = prop.corners().context("invalid floor plane")?;
                        (
                            format!("floor.{ext}"),
                            c.iter().flatten().copied().collect(),
                            vec![[0, 1, 2], [0, 2, 3]],
                        )
                    }
                };
                let is_floor = matches!(prop, Prop::Plane { .. });
                if !(is_floor && self.floor_written) {
                    let side = Frame::new(frame.step, frame.time, positions, triangles);
                    self.write_frame_file(&self.dir.join(&name), &side)?;
                }
                self.floor_written |= is_floor;
                parts.push(name);
            }
            if let Some(pvd) = &mut self.pvd {
                for (part, name) in parts.iter().enumerate() {
                    pvd.push_part(frame.time, name, part).with_context(|| {
                        format!("cannot write {}", self.dir.join("series.pvd").display())
                    })?;
                }
            }
        }
        let Some(p) = &mut self.pictures else {
            return Ok(());
        };
        let explicit = p
            .spec
            .as_ref()
            .is_some_and(|s| s.steps.contains(&frame.step));
        let all = p.spec.as_ref().is_some_and(|s| s.all) && as_file;
        if (explicit || all) && !p.rendered.contains(&frame.step) {
            render_png(p, &self.dir, frame)?;
        }
        if as_file && p.gif {
            keep_for_gif(p, frame)?;
        }
        if as_file {
            p.last_written = Some(frame.clone());
        }
        Ok(())
    }

    /// Writes the final outputs of the pictures: `--render last` of `last`, `run.gif` of the
    /// kept frames (and `last`) and `final.pov` of `last`. Called on success and on failure, so
    /// the pictures of what was computed exist either way; after a failure (`failed`), the state
    /// may be garbage, so "last" is the last frame written before it. Returns warnings (e.g.
    /// asked steps never reached) for the caller to print.
    pub fn finish(&mut self, last: &Frame, failed: bool) -> Result<Vec<String>> {
        let mut warnings = Vec::new();
        let dir = self.dir.clone();
        if let Some(u) = &mut self.usd {
            u.finish()?;
        }
        let Some(p) = &mut self.pictures else {
            return Ok(warnings);
        };
        let good;
        let last = match (&p.last_written, failed) {
            (Some(f), true) => {
                good = f.clone();
                &good
            }
            _ => last,
        };
        if let Some(spec) = p.spec.clone() {
            if spec.last && !p.rendered.contains(&last.step) {
                render_png(p, &dir, last)?;
            }
            for s in spec.steps.iter().filter(|s| !p.rendered.contains(s)) {
                warnings.push(format!(
                    "`render`: step {s} was not reached (the run ended at step {})",
                    last.step
                ));
            }
        }
        if p.gif {
            if p.gif_frames.last().is_none_or(|g| g.step != last.step) {
                keep_for_gif(p, last)?;
            }
            write_gif(p, &dir.join("run.gif"))?;
        }
        if p.pov {
            if p.triangles.is_empty() {
                p.triangles = last.triangles.clone();
            }
            let colors = last.color_values(p.color)?;
            let opts = render_options(
                p,
                (last.step, last.time),
                colors.as_ref().map(|c| &c.0),
                None,
            );
            let mut surface = Surface::new(&last.positions, &last.triangles);
            if let Some((c, _)) = &colors {
                surface = surface.with_scalars(c);
            }
            let path = dir.join("final.pov");
            balloon_render::pov::write_scene_with_props(
                &path,
                &surface,
                &last.props,
                &opts,
                last.framing().as_ref(),
            )
            .with_context(|| format!("cannot write {}", path.display()))?;
        }
        Ok(warnings)
    }

    /// Writes `mesh` to `stem.<ext>` inside the folder (format from the frame format; a VTK
    /// file then has no fields).
    pub fn write_named_mesh(&self, stem: &str, mesh: &TriMesh) -> Result<PathBuf> {
        let path = self.dir.join(format!("{stem}.{}", self.format.extension()));
        let frame = Frame::new(0, 0.0, mesh.positions_flat(), mesh.triangles.clone());
        self.write_frame_file(&path, &frame)?;
        Ok(path)
    }

    /// Writes `frame` to `stem.<ext>` with its fields (VTK) or as a plain mesh (OBJ / PLY).
    pub fn write_named_frame(&self, stem: &str, frame: &Frame) -> Result<PathBuf> {
        let path = self.dir.join(format!("{stem}.{}", self.format.extension()));
        self.write_frame_file(&path, frame)?;
        Ok(path)
    }

    fn write_frame_file(&self, path: &Path, frame: &Frame) -> Result<()> {
        if self.format == FrameFormat::Usd {
            return usd::write_single(path, frame, self.up);
        }
        if self.format == FrameFormat::Vtk {
            let pd: Vec<VtpArray<'_>> = frame
                .point_data
                .iter()
                .map(|f| VtpArray {
                    name: f.name,
                    components: f.components,
                    values: &f.values,
                })
                .collect();
            let cd: Vec<VtpArray<'_>> = if frame.triangles.is_empty() {
                Vec::new()
            } else {
                frame
                    .cell_data
                    .iter()
                    .map(|f| VtpArray {
                        name: f.name,
                        components: f.components,
                        values: &f.values,
                    })
                    .collect()
            };
            balloon::mesh::io::write_vtp(
                path,
                &frame.positions,
                &frame.triangles,
                &pd,
                &cd,
                VtkEncoding::Base64,
            )
            .with_context(|| format!("cannot write {}", path.display()))?;
            return Ok(());
        }
        let mesh = TriMesh::new(
            frame
                .positions
                .chunks_exact(3)
                .map(|c| nalgebra::Point3::new(c[0], c[1], c[2]))
                .collect(),
            frame.triangles.clone(),
        );
        // Write to a temporary name and rename, so a frame is either complete or absent.
        let tmp = path.with_extension("tmp");
        write_via_tmp(path, &tmp, |tmp| {
            match self.format {
                FrameFormat::Obj => balloon::mesh::io::write_obj(tmp, &mesh)?,
                FrameFormat::Ply => balloon::mesh::io::write_ply_binary(tmp, &mesh)?,
                FrameFormat::Vtk | FrameFormat::Usd => unreachable!("handled above"),
            }
            Ok(())
        })
    }

    /// Appends one JSON object as a line of `stats.jsonl`, whole or not at all: the line is
    /// written with one unbuffered write, and a failed write (a full disk) cuts the file back to
    /// its last complete line before the error is returned.
    pub fn append_stats<T: Serialize>(&mut self, row: &T) -> Result<()> {
        let path = self.dir.join("stats.jsonl");
        if self.stats.is_none() {
            let f =
                File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
            self.stats = Some(f);
            self.stats_len = 0;
        }
        let mut line = serde_json::to_vec(row)?;
        line.push(b'\n');
        let f = self.stats.as_mut().expect("stats writer exists");
        append_whole_line(f, self.stats_len, &line)
            .with_context(|| format!("cannot write {}", path.display()))?;
        self.stats_len += line.len() as u64;
        Ok(())
    }

    /// Writes `text` to `name` (e.g. `scenario.toml`) atomically.
    pub fn write_text(&self, name: &str, text: &str) -> Result<PathBuf> {
        let path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        write_via_tmp(&path, &tmp, |tmp| Ok(std::fs::write(tmp, text)?))?;
        Ok(path)
    }

    /// Writes the file `name` in the folder atomically: `write` writes a temporary file beside it
    /// (its path is the argument), which is renamed to `name` on success and removed on failure.
    pub fn write_file(
        &self,
        name: &str,
        write: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<PathBuf> {
        let path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        write_via_tmp(&path, &tmp, write)?;
        Ok(path)
    }

    /// Writes `value` as pretty JSON to `name` (e.g. `summary.json`) atomically.
    pub fn write_json<T: Serialize>(&self, name: &str, value: &T) -> Result<PathBuf> {
        let path = self.dir.join(name);
        let tmp = self.dir.join(format!(".{name}.tmp"));
        let bytes = serde_json::to_vec_pretty(value)?;
        write_via_tmp(&path, &tmp, |tmp| Ok(std::fs::write(tmp, &bytes)?))?;
        Ok(path)
    }
}

/// A file that can be cut back to a length (a [`File`]; tests inject failing ones).
pub(crate) trait Truncate: Write {
    /// Cuts the file to `len` bytes and puts the write position there.
    fn truncate_to(&mut self, len: u64) -> std::io::Result<()>;
}

impl Truncate for File {
    fn truncate_to(&mut self, len: u64) -> std::io::Result<()> {
        use std::io::{Seek, SeekFrom};
        self.set_len(len)?;
        self.seek(SeekFrom::Start(len)).map(drop)
    }
}

/// Writes `line` (ending in a newline) at the end of `w`, which holds `len` bytes of complete
/// lines: on a failed write, `w` is cut back to `len`, so it never ends in part of a line (if
/// even the cut fails, its error is added to the write's).
pub(crate) fn append_whole_line(
    w: &mut impl Truncate,
    len: u64,
    line: &[u8],
) -> std::io::Result<()> {
    match w.write_all(line).and_then(|()| w.flush()) {
        Ok(()) => Ok(()),
        Err(e) => match w.truncate_to(len) {
            Ok(()) => Err(e),
            Err(cut) => Err(std::io::Error::new(
                e.kind(),
                format!("{e}; the partial line could not be removed either: {cut}"),
            )),
        },
    }
}

/// Prints `value` as one JSON line on stdout (the last line a `json` run prints).
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

#[cfg(test)]
mod tests;
