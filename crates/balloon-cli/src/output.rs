//! Shared output of the subcommands: an output folder with frames, `stats.jsonl` (one JSON object
//! per step, flushed line by line so a failed run leaves a readable file), `summary.json` (written
//! atomically: temporary file, then rename), a JSON summary line on stdout, and a progress bar.
//!
//! Frames are OBJ, PLY or VTK XML PolyData (`.vtp`, with per-vertex and per-face fields, listed
//! with their times in `series.pvd`, rewritten after every frame). Pictures (issue 7): PNG
//! renders of chosen frames in `renders/` (`--render`), an animated `run.gif` of the written
//! frames (`--gif`) and a POV-Ray scene `final.pov` of the last frame (`--pov`), made with
//! `balloon-render`. Every file is written atomically, and [`OutputDir::finish`] is also called
//! when a run fails, so everything written so far stays valid.

use anyhow::{Context, Result, bail};
use balloon::fields;
use balloon_mesh::TriMesh;
use balloon_mesh::io::{PvdWriter, VtkEncoding, VtpArray};
use balloon_render::{
    Camera, ColorScale, Framing, GifWriter, Projection, Prop, RenderOptions, Renderer, Surface,
    UpAxis,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::collections::BTreeSet;
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
    /// VTK XML PolyData `.vtp` with the fields (velocity, thickness, stretch, ...) and a
    /// `series.pvd` time series for ParaView.
    Vtk,
}

impl FrameFormat {
    fn extension(self) -> &'static str {
        match self {
            FrameFormat::Obj => "obj",
            FrameFormat::Ply => "ply",
            FrameFormat::Vtk => "vtp",
        }
    }
}

/// The field that colours renders, the GIF and the POV scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ColorField {
    /// Shell thickness per face (inflate only), shown in mm.
    Thickness,
    /// Mean in-plane stretch sqrt(A/A0) per face, against the rest (or initial) shape.
    Stretch,
    /// Vertex speed |v|, m/s.
    Speed,
    /// Plain shaded surface, no legend.
    None,
}

impl ColorField {
    fn name(self) -> &'static str {
        match self {
            ColorField::Thickness => "thickness",
            ColorField::Stretch => "stretch",
            ColorField::Speed => "speed",
            ColorField::None => "none",
        }
    }
}

/// Picture flags shared by `inflate`, `volumetric` and `two-layer`.
#[derive(Debug, Clone, clap::Args)]
pub struct PictureArgs {
    /// Write PNG images of chosen steps into OUT/renders/: `last`, `all` (every written frame)
    /// or a comma list of step numbers and `last` (e.g. `0,100,last`). Needs --out.
    #[arg(long, value_name = "SPEC")]
    pub render: Option<String>,
    /// Colour of renders, GIF and POV scene: thickness | stretch | speed | none (default:
    /// thickness for inflate, stretch for volumetric, speed for two-layer).
    #[arg(long, value_enum)]
    pub color: Option<ColorField>,
    /// Write OUT/run.gif, an animation of the written frames (same framing and colour range in
    /// every frame). Needs --out.
    #[arg(long)]
    pub gif: bool,
    /// Write OUT/final.pov, a POV-Ray scene of the last frame. Needs --out.
    #[arg(long)]
    pub pov: bool,
    /// Size of the PNG renders and GIF frames, WxH pixels.
    #[arg(long, value_name = "WxH", default_value = "640x480", value_parser = parse_image_size)]
    pub image_size: (u32, u32),
    /// Colour-map range: `full` (smallest to largest value of the picture, or of the whole GIF),
    /// `robust` (2nd to 98th percentile, so a few outliers do not flatten the map; values
    /// beyond get the end colours) or `MIN:MAX` (fixed, e.g. `1:1.5`, to compare runs).
    #[arg(long, value_name = "full|robust|MIN:MAX", default_value = "full", value_parser = parse_color_range)]
    pub color_range: ColorRange,
}

/// How the colour-map range of pictures is chosen (`--color-range`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColorRange {
    /// Smallest to largest finite value.
    Full,
    /// 2nd to 98th percentile of the finite values.
    Robust,
    /// A fixed range.
    Fixed(f64, f64),
}

/// Parses `--color-range`: `full`, `robust` or `MIN:MAX` (finite, MIN < MAX).
pub fn parse_color_range(s: &str) -> Result<ColorRange, String> {
    match s.trim() {
        "full" => return Ok(ColorRange::Full),
        "robust" => return Ok(ColorRange::Robust),
        _ => {}
    }
    let bad = || format!("`{s}`: expected full, robust or MIN:MAX with finite MIN < MAX");
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let lo: f64 = a.trim().parse().map_err(|_| bad())?;
    let hi: f64 = b.trim().parse().map_err(|_| bad())?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(bad());
    }
    Ok(ColorRange::Fixed(lo, hi))
}

impl ColorRange {
    /// The range of `values` (non-finite ones ignored) under this rule; `None` when no value
    /// is finite (and the rule is not fixed).
    pub fn of<'a>(self, values: impl Iterator<Item = &'a f64>) -> Option<(f64, f64)> {
        if let ColorRange::Fixed(lo, hi) = self {
            return Some((lo, hi));
        }
        let mut v: Vec<f64> = values.copied().filter(|v| v.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_unstable_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Some(match self {
            ColorRange::Robust => (at(0.02), at(0.98)),
            _ => (v[0], v[v.len() - 1]),
        })
    }
}

/// Parses `WxH`.
pub fn parse_image_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected WxH in pixels, e.g. 640x480 (each side 32..=8192)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(32..=8192).contains(&w) || !(32..=8192).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// Which steps `--render` asks for.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderSpec {
    /// Every written frame.
    pub all: bool,
    /// The final state.
    pub last: bool,
    /// Explicit step numbers.
    pub steps: BTreeSet<usize>,
}

impl RenderSpec {
    /// Parses `last`, `all` or a comma list of step numbers and `last`.
    pub fn parse(s: &str) -> Result<Self> {
        let mut spec = RenderSpec::default();
        let help = "expected `last`, `all`, or a comma list of step numbers and `last` (e.g. `0,100,last`)";
        if s.trim().is_empty() {
            bail!("invalid --render ``: {help}");
        }
        for item in s.split(',').map(str::trim) {
            match item {
                "last" => spec.last = true,
                "all" => spec.all = true,
                _ => {
                    let n: usize = item.parse().map_err(|_| {
                        anyhow::anyhow!(
                            "invalid --render `{s}`: `{item}` is not a step number; {help}"
                        )
                    })?;
                    spec.steps.insert(n);
                }
            }
        }
        Ok(spec)
    }
}

/// A named per-vertex or per-face array of a frame.
#[derive(Clone, Debug)]
pub struct Field {
    /// Name in the `.vtp` file.
    pub name: &'static str,
    /// 1 (scalar) or 3 (vector).
    pub components: usize,
    /// Flat values.
    pub values: Vec<f64>,
}

impl Field {
    /// A scalar field.
    pub fn scalar(name: &'static str, values: Vec<f64>) -> Self {
        Self {
            name,
            components: 1,
            values,
        }
    }

    /// A vector field (3 per tuple).
    pub fn vector(name: &'static str, values: Vec<f64>) -> Self {
        Self {
            name,
            components: 3,
            values,
        }
    }
}

/// One frame of a run: the surface and its fields.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Step number.
    pub step: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Flat positions.
    pub positions: Vec<f64>,
    /// Triangles.
    pub triangles: Vec<[usize; 3]>,
    /// Per-vertex fields (velocity, speed, pressure force, ...).
    pub point_data: Vec<Field>,
    /// Per-face fields (thickness, stretch, ...).
    pub cell_data: Vec<Field>,
    /// Rigid objects of the scene at this step (the volumetric drop-sphere's sphere and floor):
    /// written beside the frame file (`sphere_NNNNN.<ext>`, `floor.<ext>`, see
    /// [`OutputDir::frame`]) and drawn in the pictures.
    pub props: Vec<Prop>,
}

impl Frame {
    /// A frame with no fields.
    pub fn new(step: usize, time: f64, positions: Vec<f64>, triangles: Vec<[usize; 3]>) -> Self {
        Self {
            step,
            time,
            positions,
            triangles,
            point_data: Vec::new(),
            cell_data: Vec::new(),
            props: Vec::new(),
        }
    }

    /// The same frame with the rigid objects `props` of the scene.
    pub fn with_props(mut self, props: Vec<Prop>) -> Self {
        self.props = props;
        self
    }

    /// The region pictures show: the surface and every sphere (not the planes, which extend
    /// beyond it); `None` without props, so that a frame without them is framed as before.
    fn framing(&self) -> Option<Framing> {
        let spheres = self.props.iter().filter_map(|p| match *p {
            Prop::Sphere { center, radius, .. } => Some(Framing { center, radius }),
            Prop::Plane { .. } => None,
        });
        let mut f: Option<Framing> = None;
        for s in spheres {
            let base = f
                .or_else(|| Framing::of_points(&self.positions))
                .unwrap_or(s);
            f = Some(base.union(&s));
        }
        f
    }

    /// Adds velocity (vector) and speed (scalar) from flat velocities.
    pub fn with_velocity(mut self, v: Vec<f64>) -> Result<Self> {
        let speed = fields::vertex_speeds(&v)?;
        self.point_data.push(Field::vector("velocity", v));
        self.point_data.push(Field::scalar("speed", speed));
        Ok(self)
    }

    /// Adds per-face `stretch` (sqrt(A/A0)) and `max_stretch` (largest principal stretch)
    /// against `rest`. A degenerate rest triangle (possible in a triangle soup) gets NaN.
    pub fn with_stretch(mut self, rest: &[f64]) -> Result<Self> {
        let area = fields::face_area_stretch_or_nan(rest, &self.positions, &self.triangles)?;
        let max = fields::face_max_stretch_or_nan(rest, &self.positions, &self.triangles)?;
        self.cell_data.push(Field::scalar("stretch", area));
        self.cell_data.push(Field::scalar("max_stretch", max));
        Ok(self)
    }

    fn field<'a>(list: &'a [Field], name: &str) -> Option<&'a [f64]> {
        list.iter()
            .find(|f| f.name == name)
            .map(|f| f.values.as_slice())
    }

    /// Per-vertex values for `color` and the legend label, or `None` for [`ColorField::None`].
    fn color_values(&self, color: ColorField) -> Result<Option<(Vec<f64>, &'static str)>> {
        let face = |name: &str| -> Result<Vec<f64>> {
            let v = Self::field(&self.cell_data, name).with_context(|| {
                format!("--color {}: this run has no `{name}` field", color.name())
            })?;
            Ok(fields::face_to_vertex(&self.positions, &self.triangles, v)?)
        };
        Ok(match color {
            ColorField::None => None,
            ColorField::Thickness => Some((
                face("thickness")?.into_iter().map(|t| 1e3 * t).collect(),
                "thickness (mm)",
            )),
            ColorField::Stretch => Some((face("stretch")?, "stretch sqrt(A/A0)")),
            ColorField::Speed => Some((
                Self::field(&self.point_data, "speed")
                    .context("--color speed: this run has no velocities")?
                    .to_vec(),
                "speed (m/s)",
            )),
        })
    }
}

/// How a system is drawn.
#[derive(Clone, Copy, Debug)]
pub struct PictureStyle {
    /// System name for titles.
    pub system: &'static str,
    /// Camera.
    pub camera: Camera,
    /// Colour when none is asked.
    pub default_color: ColorField,
    /// Colours this system can provide.
    pub available: &'static [ColorField],
    /// The surface is closed and outward oriented, so back faces can be skipped when drawing.
    pub closed: bool,
}

impl PictureStyle {
    /// Perspective view from the front-left, slightly above, with `up` as the up axis.
    pub fn new(
        system: &'static str,
        up: UpAxis,
        default_color: ColorField,
        available: &'static [ColorField],
    ) -> Self {
        Self {
            system,
            camera: Camera {
                azimuth_deg: 30.0,
                elevation_deg: 20.0,
                up,
                projection: Projection::Perspective { fov_y_deg: 30.0 },
            },
            default_color,
            available,
            closed: false,
        }
    }
}

/// A frame kept for the GIF: positions and colour values.
struct GifFrame {
    step: usize,
    time: f64,
    positions: Vec<f64>,
    colors: Option<Vec<f64>>,
    props: Vec<Prop>,
}

/// Most frames kept for the GIF; beyond, every other one is dropped.
const MAX_GIF_FRAMES: usize = 120;

struct Pictures {
    spec: Option<RenderSpec>,
    gif: bool,
    pov: bool,
    color: ColorField,
    color_range: ColorRange,
    label: &'static str,
    size: (u32, u32),
    style: PictureStyle,
    renderer: Renderer,
    triangles: Vec<[usize; 3]>,
    gif_frames: Vec<GifFrame>,
    gif_stride: usize,
    gif_seen: usize,
    rendered: BTreeSet<usize>,
    last_written: Option<Frame>,
}

/// An output folder for one run.
pub struct OutputDir {
    dir: PathBuf,
    format: FrameFormat,
    stats: Option<BufWriter<File>>,
    pvd: Option<PvdWriter>,
    pictures: Option<Pictures>,
    /// The floor file (`floor.<ext>`) is written (once: the floor does not move).
    floor_written: bool,
}

/// Checks that picture flags come with `--out`, parses `--render` and checks `--color` is
/// available, before any simulation work. Returns the parsed spec.
pub fn check_picture_args(
    args: &PictureArgs,
    out: Option<&Path>,
    style: &PictureStyle,
) -> Result<Option<RenderSpec>> {
    let spec = args.render.as_deref().map(RenderSpec::parse).transpose()?;
    let wants = spec.is_some() || args.gif || args.pov;
    if wants && out.is_none() {
        let flag = if spec.is_some() {
            "--render"
        } else if args.gif {
            "--gif"
        } else {
            "--pov"
        };
        bail!("{flag} needs --out DIR (images are written into the output folder)");
    }
    if let Some(c) = args.color
        && c != ColorField::None
        && !style.available.contains(&c)
    {
        bail!(
            "invalid --color {}: `{}` has no such field (available: {}, none)",
            c.name(),
            style.system,
            style
                .available
                .iter()
                .map(|c| c.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(spec)
}

/// Whether `name` is a file this program writes into an output folder (frames, records,
/// pictures, their temporary files), so `--overwrite` may remove it. Anything else is the
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
    let frames = ["obj", "ply", "vtp", "tmp"];
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

/// Checks the output folder before any work: a path that exists but is not a folder is refused,
/// and so is a folder holding an earlier run's files (they would mix with this run's: a shorter
/// run leaves the old frames beyond its end) unless `overwrite`, which removes exactly those
/// files (see `is_run_file`; `renders/frame_*.png` too) and nothing else.
pub fn prepare_out_dir(dir: &Path, overwrite: bool) -> Result<()> {
    let meta = match std::fs::metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("cannot read --out {}", dir.display())),
    };
    if !meta.is_dir() {
        bail!("--out {} exists and is not a folder", dir.display());
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
                is_run_file(&name)
            };
            if ours && entry.file_type().is_ok_and(|t| t.is_file()) {
                old.push(entry.path());
            }
        }
        Ok(())
    };
    list(dir, false, &mut old)?;
    let renders = dir.join("renders");
    if renders.is_dir() {
        list(&renders, true, &mut old)?;
    }
    if old.is_empty() {
        return Ok(());
    }
    if !overwrite {
        old.sort();
        bail!(
            "--out {} already holds the files of an earlier run ({} file(s), e.g. {}); choose \
             another folder or add --overwrite to remove them first",
            dir.display(),
            old.len(),
            old[0]
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        );
    }
    for f in &old {
        std::fs::remove_file(f).with_context(|| format!("cannot remove {}", f.display()))?;
    }
    // The renders folder goes too when nothing else is in it.
    if renders.is_dir() {
        let _ = std::fs::remove_dir(&renders);
    }
    Ok(())
}

/// Writes a file at `path` through `tmp` and a rename; on any failure `tmp` is removed, so a
/// failed write leaves no temporary file, and the error names `path`.
fn write_via_tmp(path: &Path, tmp: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
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
            stats: Some(BufWriter::new(f)),
            pvd,
            pictures: None,
            floor_written: false,
        })
    }

    /// Enables the picture outputs of `args` (checked by [`check_picture_args`]).
    pub fn with_pictures(
        mut self,
        args: &PictureArgs,
        spec: Option<RenderSpec>,
        style: PictureStyle,
    ) -> Result<Self> {
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

    /// Whether step `step` must be captured as a frame for `--render` even if it is not a
    /// regular frame step.
    pub fn wants_step(&self, step: usize) -> bool {
        self.pictures
            .as_ref()
            .and_then(|p| p.spec.as_ref())
            .is_some_and(|s| s.steps.contains(&step))
    }

    /// Handles frame `frame`: writes `frame_NNNNN.<ext>` when `as_file` (and adds it to
    /// `series.pvd` for VTK), renders it when `--render` asks for its step (or `all` and
    /// `as_file`), and keeps it for the GIF when `as_file`.
    ///
    /// The frame's rigid objects go into side files of the same format, so that the frame file
    /// stays the simulated surface alone for every reader: a sphere as `sphere_NNNNN.<ext>`
    /// (an icosphere of 642 vertices on the sphere, the second and further spheres
    /// `sphereK_NNNNN`), a plane as `floor.<ext>` (one quad, written with the first frame: it
    /// does not move). With VTK, `series.pvd` lists them at the frame's time as parts 1, 2, ...
    /// after the surface (part 0).
    pub fn frame(&mut self, frame: &Frame, as_file: bool) -> Result<()> {
        if as_file {
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
                    "--render: step {s} was not reached (the run ended at step {})",
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
            balloon_mesh::io::write_vtp(
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
                FrameFormat::Obj => balloon_mesh::io::write_obj(tmp, &mesh)?,
                FrameFormat::Ply => balloon_mesh::io::write_ply_binary(tmp, &mesh)?,
                FrameFormat::Vtk => unreachable!("handled above"),
            }
            Ok(())
        })
    }

    /// Appends one JSON object as a line of `stats.jsonl` and flushes it.
    pub fn append_stats<T: Serialize>(&mut self, row: &T) -> Result<()> {
        if self.stats.is_none() {
            let path = self.dir.join("stats.jsonl");
            let f =
                File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
            self.stats = Some(BufWriter::new(f));
        }
        let path = self.dir.join("stats.jsonl");
        let w = self.stats.as_mut().expect("stats writer exists");
        serde_json::to_writer(&mut *w, row)
            .map_err(std::io::Error::from)
            .and_then(|()| w.write_all(b"\n"))
            .and_then(|()| w.flush())
            .with_context(|| format!("cannot write {}", path.display()))
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

/// Options for a picture of step `step` at time `time`: the system's camera, a colour scale over
/// `range` (or the range of `colors`), and a title naming the system, step and time.
fn render_options(
    p: &Pictures,
    (step, time): (usize, f64),
    colors: Option<&Vec<f64>>,
    range: Option<(f64, f64)>,
) -> RenderOptions {
    let color_scale = colors.map(|c| {
        let label = if p.label.is_empty() {
            p.color.name()
        } else {
            p.label
        };
        match range.or_else(|| p.color_range.of(c.iter())) {
            Some((lo, hi)) => ColorScale::new(lo, hi, label),
            None => ColorScale::from_values(c, label),
        }
    });
    RenderOptions {
        camera: p.style.camera,
        color_scale,
        cull_back_faces: p.style.closed,
        title: Some(format!(
            "{}  step {}  t = {} s",
            p.style.system,
            step,
            balloon_render::format_tick(time)
        )),
        ..RenderOptions::new(p.size.0, p.size.1)
    }
}

fn render_png(p: &mut Pictures, dir: &Path, frame: &Frame) -> Result<()> {
    let colors = frame.color_values(p.color)?;
    if let Some((_, label)) = &colors {
        p.label = label;
    }
    let opts = render_options(
        p,
        (frame.step, frame.time),
        colors.as_ref().map(|c| &c.0),
        None,
    );
    let mut surface = Surface::new(&frame.positions, &frame.triangles);
    if let Some((c, _)) = &colors {
        surface = surface.with_scalars(c);
    }
    let path = dir
        .join("renders")
        .join(format!("frame_{:05}.png", frame.step));
    p.renderer
        .render_with_props(&surface, &frame.props, &opts, frame.framing().as_ref())
        .and_then(|img| img.write_png(&path))
        .with_context(|| format!("cannot render {}", path.display()))?;
    p.rendered.insert(frame.step);
    Ok(())
}

fn keep_for_gif(p: &mut Pictures, frame: &Frame) -> Result<()> {
    p.gif_seen += 1;
    if !(p.gif_seen - 1).is_multiple_of(p.gif_stride) {
        return Ok(());
    }
    if p.triangles.is_empty() {
        p.triangles = frame.triangles.clone();
    }
    let colors = frame.color_values(p.color)?;
    if let Some((_, label)) = &colors {
        p.label = label;
    }
    p.gif_frames.push(GifFrame {
        step: frame.step,
        time: frame.time,
        positions: frame.positions.clone(),
        colors: colors.map(|c| c.0),
        props: frame.props.clone(),
    });
    if p.gif_frames.len() >= MAX_GIF_FRAMES {
        // Keep every other frame (always the first), and from now on every other new one.
        let mut k = 0;
        p.gif_frames.retain(|_| {
            k += 1;
            (k - 1) % 2 == 0
        });
        p.gif_stride *= 2;
    }
    Ok(())
}

fn write_gif(p: &mut Pictures, path: &Path) -> Result<()> {
    if p.gif_frames.is_empty() {
        return Ok(());
    }
    // One framing and one colour range for the whole animation.
    let framing = p
        .gif_frames
        .iter()
        .filter_map(|g| Framing::of_points(&g.positions))
        .chain(p.gif_frames.iter().flat_map(|g| {
            g.props.iter().filter_map(|prop| match *prop {
                Prop::Sphere { center, radius, .. } => Some(Framing { center, radius }),
                Prop::Plane { .. } => None,
            })
        }))
        .reduce(|a, b| a.union(&b))
        .context("--gif: no frame has finite coordinates")?;
    let range = p.color_range.of(p
        .gif_frames
        .iter()
        .filter_map(|g| g.colors.as_ref())
        .flatten());
    let n = p.gif_frames.len();
    // About 6 s for the whole run, between 4 and 20 hundredths per frame.
    let delay = (600 / n.max(1)).clamp(4, 20) as u16;
    let mut gif = GifWriter::create(path, p.size.0, p.size.1)?;
    let frames = std::mem::take(&mut p.gif_frames);
    for g in &frames {
        let opts = render_options(p, (g.step, g.time), g.colors.as_ref(), range);
        let mut surface = Surface::new(&g.positions, &p.triangles);
        if let Some(c) = &g.colors {
            surface = surface.with_scalars(c);
        }
        let img = p
            .renderer
            .render_with_props(&surface, &g.props, &opts, Some(&framing))
            .with_context(|| format!("cannot render GIF frame of step {}", g.step))?;
        gif.add_frame(img, delay)?;
    }
    p.gif_frames = frames;
    gif.finish()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_files_this_program_writes_count_as_an_earlier_run() {
        for ours in [
            "stats.jsonl",
            "summary.json",
            ".summary.json.tmp",
            "series.pvd",
            ".series.pvd.tmp",
            "frame_00000.obj",
            "frame_12345.vtp",
            ".frame_00010.vtp.tmp",
            "frame_00002.tmp",
            "final.ply",
            "final.pov",
            "run.gif",
            ".run.gif.tmp",
            "lattice.vtk",
            "lattice_00020.vtk",
            "input_soup.obj",
            "sphere_00020.obj",
            "sphere1_00020.vtp",
            ".sphere_00020.vtp.tmp",
            "floor.ply",
        ] {
            assert!(is_run_file(ours), "{ours}");
        }
        for theirs in [
            "notes.txt",
            "frame_.obj",
            "frame_abc.obj",
            "frame_00001.png",
            "final.txt",
            "my_summary.json",
            "lattice_1.vtp",
            "teddy.obj",
            "sphere.obj",
            "sphere_a.obj",
            "floor_1.obj",
        ] {
            assert!(!is_run_file(theirs), "{theirs}");
        }
    }

    #[test]
    fn prepare_refuses_a_reused_folder_and_overwrite_removes_only_run_files() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        prepare_out_dir(&out, false).unwrap();
        std::fs::create_dir_all(out.join("renders")).unwrap();
        for f in [
            "frame_00000.obj",
            "summary.json",
            "mine.txt",
            "renders/frame_00003.png",
        ] {
            std::fs::write(out.join(f), "x").unwrap();
        }
        let e = prepare_out_dir(&out, false).unwrap_err().to_string();
        assert!(
            e.contains(&out.display().to_string()) && e.contains("--overwrite"),
            "{e}"
        );
        prepare_out_dir(&out, true).unwrap();
        let left: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, ["mine.txt"]);
        let file = dir.path().join("file");
        std::fs::write(&file, "x").unwrap();
        let e = prepare_out_dir(&file, true).unwrap_err().to_string();
        assert!(e.contains("not a folder"), "{e}");
    }

    #[test]
    fn render_specs_and_sizes_parse_or_explain() {
        let s = RenderSpec::parse("0, 50,last").unwrap();
        assert!(s.last && !s.all);
        assert_eq!(s.steps.into_iter().collect::<Vec<_>>(), vec![0, 50]);
        assert!(RenderSpec::parse("all").unwrap().all);
        for bad in ["", "first", "1,,2", "-3", "1.5"] {
            let e = RenderSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--render") && e.contains("last"), "{bad}: {e}");
        }
        assert_eq!(parse_image_size("320x200"), Ok((320, 200)));
        assert!(parse_image_size("320").is_err());
        assert!(parse_image_size("10x10").unwrap_err().contains("640x480"));
    }

    #[test]
    fn color_ranges_parse_and_robust_ignores_outliers() {
        assert_eq!(parse_color_range("full"), Ok(ColorRange::Full));
        assert_eq!(parse_color_range("robust"), Ok(ColorRange::Robust));
        assert_eq!(parse_color_range("1:1.5"), Ok(ColorRange::Fixed(1.0, 1.5)));
        for bad in ["", "2:1", "1:1", "a:b", "1", "nan:2", "0:inf"] {
            assert!(
                parse_color_range(bad).unwrap_err().contains("MIN:MAX"),
                "{bad}"
            );
        }
        // 100 values 1.00..1.99 plus one outlier and one NaN.
        let mut v: Vec<f64> = (0..100).map(|i| 1.0 + f64::from(i) / 100.0).collect();
        v.push(50.0);
        v.push(f64::NAN);
        assert_eq!(ColorRange::Full.of(v.iter()), Some((1.0, 50.0)));
        let (lo, hi) = ColorRange::Robust.of(v.iter()).unwrap();
        assert!(
            (lo - 1.02).abs() < 1e-12 && (hi - 1.98).abs() < 1e-12,
            "{lo} {hi}"
        );
        assert_eq!(ColorRange::Fixed(0.0, 2.0).of(v.iter()), Some((0.0, 2.0)));
        assert_eq!(ColorRange::Robust.of([f64::NAN].iter()), None);
    }

    #[test]
    fn stretch_of_a_soup_with_a_degenerate_triangle_is_nan_there() {
        let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0];
        let x: Vec<f64> = rest.iter().map(|c| 2.0 * c).collect();
        let f = Frame::new(0, 0.0, x, vec![[0, 1, 2], [0, 1, 3]])
            .with_stretch(&rest)
            .unwrap();
        let s = &f.cell_data[0].values;
        assert!((s[0] - 2.0).abs() < 1e-12 && s[1].is_nan());
    }
}
