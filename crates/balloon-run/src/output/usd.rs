//! One USD stage per run (`run.usda`, the text form of Pixar's Universal Scene Description), the
//! format Blender, Houdini, Maya, Omniverse and usdview read: a `Mesh` prim per body with its
//! topology once and its `points` time-sampled at every written frame, the frame's fields as
//! primvars (per face: `uniform`, per vertex: `vertex`, the gas pressure: `constant`), the
//! velocities as the mesh's `velocities`, and the scene's rigid objects (a sphere as a mesh moved
//! by a time-sampled `xformOp:translate`, the floor as a static quad).
//!
//! The stage is in metres (`metersPerUnit = 1`) with the run's up axis. Time code `k` is the
//! `k`-th written frame when frames are evenly spaced in time: `timeCodesPerSecond` is one over
//! the time between the first two frames, so the stage's time range (`startTimeCode` to
//! `endTimeCode`, divided by `timeCodesPerSecond`) is the simulated time since the first frame.
//! The exact simulated time and step of each sample are the time-sampled `balloon:time` and
//! `balloon:step` attributes of `/World`. A run whose frames share one time (a static solve's
//! load steps) numbers them 0, 1, 2, ... at one time code per second.
//!
//! # Written incrementally, valid after every frame
//!
//! A text layer keeps each attribute's time samples in one `{ ... }` block, so a new frame adds
//! a line to every block. Each block is followed by reserved blank lines (whitespace, which USD
//! ignores): a frame's lines are written into the reserve of their blocks and the header's
//! `endTimeCode` (a fixed-width field) is updated last, so after every frame the file is a
//! complete, valid stage holding the frames so far. When a block's reserve runs out, the file is
//! rewritten once (through a temporary file and a rename) with twice the reserve, so the total
//! work stays linear in the run's length. [`UsdWriter::finish`] (called when a run ends, also by
//! a failure or an interruption) rewrites it without the reserve.

use super::frame::{Body, Field, Frame};
use anyhow::{Context, Result, bail};
use balloon_render::{Prop, UpAxis};
use std::fmt::Write as _;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Width of the fixed-width header fields (`endTimeCode`, `timeCodesPerSecond`, ...).
const SLOT_WIDTH: usize = 26;

/// A piece of the file: fixed text, a header field rewritten in place, or a time-sample block's
/// contents (the samples so far, then the reserve).
#[derive(Debug)]
enum Piece {
    Text(String),
    Slot {
        offset: u64,
        value: String,
    },
    Samples {
        offset: u64,
        used: u64,
        capacity: u64,
    },
}

/// What one time-sample block holds (each frame adds one sample line to each).
#[derive(Clone, Debug)]
enum Source {
    /// `balloon:time` of `/World`.
    Time,
    /// `balloon:step` of `/World`.
    Step,
    /// The points of body `body`.
    Points { body: usize },
    /// The extent (bounding box) of body `body`.
    Extent { body: usize },
    /// Per-vertex field `field` of body `body`.
    PointField { body: usize, field: usize },
    /// Per-face field `field` of body `body`.
    CellField { body: usize, field: usize },
    /// Gas pressure of body `body`.
    Pressure { body: usize },
    /// Centre of sphere prop `prop`.
    Translate { prop: usize },
}

/// The frame's shape, fixed by the first frame (USD keeps one topology per mesh).
#[derive(Debug)]
struct Shape {
    vertices: usize,
    faces: usize,
    bodies: Vec<Body>,
    point_fields: Vec<(&'static str, usize)>,
    cell_fields: Vec<(&'static str, usize)>,
    props: usize,
}

impl Shape {
    fn of(frame: &Frame) -> Self {
        let vertices = frame.positions.len() / 3;
        let faces = frame.triangles.len();
        let bodies = if frame.bodies.is_empty() {
            vec![Body::whole("surface", vertices, faces)]
        } else {
            frame.bodies.clone()
        };
        Self {
            vertices,
            faces,
            bodies,
            point_fields: frame
                .point_data
                .iter()
                .map(|f| (f.name, f.components))
                .collect(),
            cell_fields: frame
                .cell_data
                .iter()
                .map(|f| (f.name, f.components))
                .collect(),
            props: frame.props.len(),
        }
    }

    /// Why `frame` does not fit this shape (a USD mesh keeps its topology), or `None`.
    fn mismatch(&self, frame: &Frame) -> Option<String> {
        let other = Shape::of(frame);
        if other.vertices != self.vertices || other.faces != self.faces {
            return Some(format!(
                "{} vertices and {} triangles where the first frame had {} and {}",
                other.vertices, other.faces, self.vertices, self.faces
            ));
        }
        if other.point_fields != self.point_fields || other.cell_fields != self.cell_fields {
            return Some("other fields than the first frame".into());
        }
        if other.bodies.len() != self.bodies.len() || other.props != self.props {
            return Some("other bodies or scene objects than the first frame".into());
        }
        None
    }
}

/// The USD stage of a run, written frame by frame (see the module docs).
#[derive(Debug)]
pub struct UsdWriter {
    path: PathBuf,
    up: UpAxis,
    file: Option<File>,
    pieces: Vec<Piece>,
    /// Which piece each source's block is, in `sources` order.
    blocks: Vec<(Source, usize)>,
    /// Piece indices of `endTimeCode`, `timeCodesPerSecond`, `framesPerSecond`.
    slots: [usize; 3],
    shape: Option<Shape>,
    /// Frames written, and the first frame's time.
    frames: usize,
    t0: f64,
    /// Time codes per second once two frames fixed it (`None`: frame numbers).
    per_second: Option<f64>,
    last_code: f64,
    /// Sphere props' rest centres (their meshes are written around the origin).
    rest_centres: Vec<[f64; 3]>,
}

/// A float as USD text: shortest round-trip form, `nan` / `inf` / `-inf` spelled as USD does.
fn num(out: &mut String, v: f64, single: bool) {
    if v.is_nan() {
        out.push_str("nan");
    } else if v.is_infinite() {
        out.push_str(if v > 0.0 { "inf" } else { "-inf" });
    } else if single {
        let _ = write!(out, "{}", v as f32);
    } else {
        let _ = write!(out, "{v}");
    }
}

/// `[a, b, ...]` (one component) or `[(a, b, c), ...]` (three) of single-precision values.
fn array(out: &mut String, values: &[f64], components: usize) {
    out.push('[');
    for (i, tuple) in values.chunks(components.max(1)).enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        if components == 1 {
            num(out, tuple[0], true);
        } else {
            out.push('(');
            for (j, v) in tuple.iter().enumerate() {
                if j > 0 {
                    out.push_str(", ");
                }
                num(out, *v, true);
            }
            out.push(')');
        }
    }
    out.push(']');
}

/// The USD type of a field (vertex or face values, 1 or 3 components).
fn field_type(components: usize) -> &'static str {
    if components == 3 {
        "float3[]"
    } else {
        "float[]"
    }
}

impl UsdWriter {
    /// A writer of the stage at `path` with `up` as its up axis; the file appears with the first
    /// frame ([`UsdWriter::push`]).
    pub fn new(path: &Path, up: UpAxis) -> Self {
        Self {
            path: path.to_path_buf(),
            up,
            file: None,
            pieces: Vec::new(),
            blocks: Vec::new(),
            slots: [0; 3],
            shape: None,
            frames: 0,
            t0: 0.0,
            per_second: None,
            last_code: 0.0,
            rest_centres: Vec::new(),
        }
    }

    /// The stage's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The layout of the stage for the first frame `frame`: header, `/World`, a mesh per body,
    /// the props.
    fn layout(&mut self, frame: &Frame, shape: &Shape) -> Result<()> {
        let mut pieces = Vec::new();
        let mut blocks = Vec::new();
        let mut text = String::new();
        let flush = |text: &mut String, pieces: &mut Vec<Piece>| {
            if !text.is_empty() {
                pieces.push(Piece::Text(std::mem::take(text)));
            }
        };
        let up = match self.up {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        };
        let mut slots = [0; 3];
        text.push_str(
            "#usda 1.0\n(\n    defaultPrim = \"World\"\n    doc = \"A balloon simulation run: a \
             Mesh prim per body with time-sampled points; balloon:time and balloon:step of \
             /World give each sample's simulated time (s) and step.\"\n    metersPerUnit = 1\n",
        );
        let _ = writeln!(text, "    upAxis = \"{up}\"\n    startTimeCode = 0");
        for (k, key) in ["endTimeCode", "timeCodesPerSecond", "framesPerSecond"]
            .iter()
            .enumerate()
        {
            let _ = write!(text, "    {key} = ");
            flush(&mut text, &mut pieces);
            slots[k] = pieces.len();
            pieces.push(Piece::Slot {
                offset: 0,
                value: if k == 0 { "0".into() } else { "1".into() },
            });
            text.push('\n');
        }
        text.push_str(")\n\ndef Xform \"World\"\n{\n");
        let block = |text: &mut String,
                     pieces: &mut Vec<Piece>,
                     blocks: &mut Vec<(Source, usize)>,
                     decl: &str,
                     source: Source| {
            let _ = writeln!(text, "{decl}.timeSamples = {{");
            flush(text, pieces);
            blocks.push((source, pieces.len()));
            pieces.push(Piece::Samples {
                offset: 0,
                used: 0,
                capacity: 0,
            });
            text.push_str("    }\n");
        };
        block(
            &mut text,
            &mut pieces,
            &mut blocks,
            "    custom double balloon:time",
            Source::Time,
        );
        block(
            &mut text,
            &mut pieces,
            &mut blocks,
            "    custom int balloon:step",
            Source::Step,
        );
        for (b, body) in shape.bodies.iter().enumerate() {
            let _ = writeln!(text, "\n    def Mesh \"{}\"\n    {{", body.name);
            text.push_str("        uniform token subdivisionScheme = \"none\"\n");
            text.push_str("        uniform bool doubleSided = 1\n");
            text.push_str("        int[] faceVertexCounts = [");
            for i in 0..body.faces.len() {
                text.push_str(if i == 0 { "3" } else { ", 3" });
            }
            text.push_str("]\n        int[] faceVertexIndices = [");
            for (i, t) in frame.triangles[body.faces.clone()].iter().enumerate() {
                for (j, &v) in t.iter().enumerate() {
                    let Some(local) = v
                        .checked_sub(body.vertices.start)
                        .filter(|l| *l < body.vertices.len())
                    else {
                        bail!(
                            "body `{}`: triangle {} uses vertex {v} outside its vertices {:?}",
                            body.name,
                            body.faces.start + i,
                            body.vertices
                        );
                    };
                    let sep = if i == 0 && j == 0 { "" } else { ", " };
                    let _ = write!(text, "{sep}{local}");
                }
            }
            text.push_str("]\n");
            block(
                &mut text,
                &mut pieces,
                &mut blocks,
                "        float3[] extent",
                Source::Extent { body: b },
            );
            block(
                &mut text,
                &mut pieces,
                &mut blocks,
                "        point3f[] points",
                Source::Points { body: b },
            );
            for (f, (name, comps)) in shape.point_fields.iter().enumerate() {
                let decl = if *name == "velocity" && *comps == 3 {
                    "        vector3f[] velocities".to_string()
                } else {
                    let ty = field_type(*comps);
                    let _ = writeln!(
                        text,
                        "        {ty} primvars:{name} (\n            interpolation = \"vertex\"\n        )"
                    );
                    format!("        {ty} primvars:{name}")
                };
                let source = Source::PointField { body: b, field: f };
                block(&mut text, &mut pieces, &mut blocks, &decl, source);
            }
            for (f, (name, comps)) in shape.cell_fields.iter().enumerate() {
                let ty = field_type(*comps);
                let _ = writeln!(
                    text,
                    "        {ty} primvars:{name} (\n            interpolation = \"uniform\"\n        )"
                );
                let decl = format!("        {ty} primvars:{name}");
                let source = Source::CellField { body: b, field: f };
                block(&mut text, &mut pieces, &mut blocks, &decl, source);
            }
            if body.pressure.is_some() {
                text.push_str(
                    "        float primvars:pressure (\n            doc = \"Gauge pressure of \
                     the enclosed gas, Pa.\"\n            interpolation = \"constant\"\n        )\n",
                );
                block(
                    &mut text,
                    &mut pieces,
                    &mut blocks,
                    "        float primvars:pressure",
                    Source::Pressure { body: b },
                );
            }
            text.push_str("    }\n");
        }
        let mut spheres = 0;
        let mut rest_centres = Vec::new();
        for (k, prop) in frame.props.iter().enumerate() {
            let (name, points, tris) = match *prop {
                Prop::Sphere { center, .. } => {
                    let (x, t) = prop.mesh()?;
                    let name = match spheres {
                        0 => "sphere".to_string(),
                        s => format!("sphere{s}"),
                    };
                    spheres += 1;
                    rest_centres.push(center);
                    let local: Vec<f64> = x
                        .chunks_exact(3)
                        .flat_map(|p| [p[0] - center[0], p[1] - center[1], p[2] - center[2]])
                        .collect();
                    (name, local, t)
                }
                Prop::Plane { .. } => {
                    let c = prop.corners().context("invalid floor plane")?;
                    rest_centres.push([0.0; 3]);
                    (
                        "floor".to_string(),
                        c.iter().flatten().copied().collect(),
                        vec![[0, 1, 2], [0, 2, 3]],
                    )
                }
            };
            let _ = writeln!(text, "\n    def Mesh \"{name}\"\n    {{");
            text.push_str("        uniform token subdivisionScheme = \"none\"\n");
            text.push_str("        int[] faceVertexCounts = [");
            for i in 0..tris.len() {
                text.push_str(if i == 0 { "3" } else { ", 3" });
            }
            text.push_str("]\n        int[] faceVertexIndices = [");
            let flat: Vec<String> = tris.iter().flatten().map(|v| v.to_string()).collect();
            text.push_str(&flat.join(", "));
            text.push_str("]\n        point3f[] points = ");
            array(&mut text, &points, 3);
            text.push('\n');
            if matches!(prop, Prop::Sphere { .. }) {
                text.push_str("        uniform token[] xformOpOrder = [\"xformOp:translate\"]\n");
                block(
                    &mut text,
                    &mut pieces,
                    &mut blocks,
                    "        double3 xformOp:translate",
                    Source::Translate { prop: k },
                );
            }
            text.push_str("    }\n");
        }
        text.push_str("}\n");
        flush(&mut text, &mut pieces);
        self.pieces = pieces;
        self.blocks = blocks;
        self.slots = slots;
        self.rest_centres = rest_centres;
        Ok(())
    }

    /// The sample line of `source` at time code `code` for `frame`.
    fn sample(&self, source: &Source, frame: &Frame, shape: &Shape, code: f64) -> String {
        let mut s = String::from(match source {
            Source::Time | Source::Step => "        ",
            _ => "            ",
        });
        num(&mut s, code, false);
        s.push_str(": ");
        let field = |list: &[Field], f: usize, range: std::ops::Range<usize>| -> Vec<f64> {
            let c = list[f].components;
            list[f].values[range.start * c..range.end * c].to_vec()
        };
        match *source {
            Source::Time => num(&mut s, frame.time, false),
            Source::Step => {
                let _ = write!(s, "{}", frame.step);
            }
            Source::Points { body } => {
                let v = &shape.bodies[body].vertices;
                array(&mut s, &frame.positions[3 * v.start..3 * v.end], 3);
            }
            Source::Extent { body } => {
                let v = &shape.bodies[body].vertices;
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for p in frame.positions[3 * v.start..3 * v.end].chunks_exact(3) {
                    for ((l, h), x) in lo.iter_mut().zip(&mut hi).zip(p) {
                        *l = l.min(*x);
                        *h = h.max(*x);
                    }
                }
                let b: Vec<f64> = lo.iter().chain(&hi).copied().collect();
                array(&mut s, &b, 3);
            }
            Source::PointField { body, field: f } => {
                let values = field(&frame.point_data, f, shape.bodies[body].vertices.clone());
                array(&mut s, &values, frame.point_data[f].components);
            }
            Source::CellField { body, field: f } => {
                let values = field(&frame.cell_data, f, shape.bodies[body].faces.clone());
                array(&mut s, &values, frame.cell_data[f].components);
            }
            Source::Pressure { body } => {
                num(
                    &mut s,
                    frame.bodies[body].pressure.unwrap_or(f64::NAN),
                    true,
                );
            }
            Source::Translate { prop } => {
                let c = match frame.props[prop] {
                    Prop::Sphere { center, .. } => center,
                    Prop::Plane { .. } => self.rest_centres[prop],
                };
                s.push('(');
                for (a, v) in c.iter().enumerate() {
                    if a > 0 {
                        s.push_str(", ");
                    }
                    num(&mut s, *v, false);
                }
                s.push(')');
            }
        }
        s.push_str(",\n");
        s
    }

    /// The time code of the next frame at time `t` (see the module docs).
    fn time_code(&mut self, t: f64) -> f64 {
        let code = match self.frames {
            0 => {
                self.t0 = t;
                0.0
            }
            1 => {
                let dt = t - self.t0;
                if dt > 0.0 && (1.0 / dt).is_finite() {
                    self.per_second = Some(1.0 / dt);
                }
                1.0
            }
            _ => match self.per_second {
                Some(r) => {
                    let c = (t - self.t0) * r;
                    let rounded = c.round();
                    if (c - rounded).abs() <= 1e-6 * c.abs().max(1.0) {
                        rounded
                    } else {
                        c
                    }
                }
                None => self.last_code + 1.0,
            },
        };
        // Time codes must increase; a frame whose time does not takes the next number.
        let code = if self.frames > 0 && code <= self.last_code {
            self.last_code + 1.0
        } else {
            code
        };
        self.last_code = code;
        code
    }

    /// Adds `frame` to the stage: on the first frame the file is created with the layout (a
    /// mesh per body, the props); each frame adds its samples and moves `endTimeCode`. After
    /// this returns the file is a valid stage with every frame so far.
    pub fn push(&mut self, frame: &Frame) -> Result<()> {
        if let Some(shape) = &self.shape {
            if let Some(why) = shape.mismatch(frame) {
                bail!(
                    "cannot add step {} to {}: a USD mesh keeps the first frame's topology, and \
                     this frame has {why}",
                    frame.step,
                    self.path.display()
                );
            }
        } else {
            let shape = Shape::of(frame);
            for b in &shape.bodies {
                if b.vertices.end > shape.vertices || b.faces.end > shape.faces {
                    bail!("body `{}` reaches beyond the frame's surface", b.name);
                }
            }
            self.layout(frame, &shape)?;
            self.shape = Some(shape);
        }
        let code = self.time_code(frame.time);
        let shape = self.shape.as_ref().expect("shape set above");
        let lines: Vec<(usize, String)> = self
            .blocks
            .iter()
            .map(|(source, piece)| (*piece, self.sample(source, frame, shape, code)))
            .collect();
        let mut grow = false;
        for (piece, line) in &lines {
            if let Piece::Samples { used, capacity, .. } = &mut self.pieces[*piece] {
                let need = *used + line.len() as u64;
                if need > *capacity {
                    *capacity = (2 * need).max(*capacity * 2);
                    grow = true;
                }
            }
        }
        if grow || self.file.is_none() {
            self.rewrite(true)?;
        }
        let file = self.file.as_mut().expect("file open after rewrite");
        let path = &self.path;
        for (piece, line) in &lines {
            if let Piece::Samples { offset, used, .. } = &mut self.pieces[*piece] {
                file.seek(SeekFrom::Start(*offset + *used))
                    .and_then(|_| file.write_all(line.as_bytes()))
                    .with_context(|| format!("cannot write {}", path.display()))?;
                *used += line.len() as u64;
            }
        }
        self.frames += 1;
        let rate = self.per_second.unwrap_or(1.0).to_string();
        let mut end = String::new();
        num(&mut end, code, false);
        for (k, value) in [(1, rate.clone()), (2, rate), (0, end)] {
            self.set_slot(k, value)?;
        }
        Ok(())
    }

    /// Writes header field `k` in place.
    fn set_slot(&mut self, k: usize, value: String) -> Result<()> {
        let Piece::Slot { offset, value: v } = &mut self.pieces[self.slots[k]] else {
            unreachable!("slots are slot pieces");
        };
        if value.len() > SLOT_WIDTH {
            bail!("header value {value} is wider than {SLOT_WIDTH} characters");
        }
        *v = value;
        let text = format!("{v:<SLOT_WIDTH$}");
        let file = self.file.as_mut().expect("file open");
        file.seek(SeekFrom::Start(*offset))
            .and_then(|_| file.write_all(text.as_bytes()))
            .with_context(|| format!("cannot write {}", self.path.display()))
    }

    /// Writes the whole file anew through a temporary file and a rename: the samples so far
    /// (read from the current file), each block followed by its reserve (`reserve`) or none.
    fn rewrite(&mut self, reserve: bool) -> Result<()> {
        let name = self
            .path
            .file_name()
            .map_or_else(|| "run.usda".into(), |n| n.to_string_lossy().into_owned());
        let tmp = self.path.with_file_name(format!(".{name}.tmp"));
        let result = self.rewrite_to(&tmp, reserve);
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result.with_context(|| format!("cannot write {}", self.path.display()))?;
        std::fs::rename(&tmp, &self.path)
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.file = Some(
            OpenOptions::new()
                .read(true)
                .write(true)
                .open(&self.path)
                .with_context(|| format!("cannot open {}", self.path.display()))?,
        );
        Ok(())
    }

    fn rewrite_to(&mut self, tmp: &Path, reserve: bool) -> Result<()> {
        let mut out = std::io::BufWriter::new(File::create(tmp)?);
        let mut at = 0u64;
        for piece in &mut self.pieces {
            match piece {
                Piece::Text(t) => {
                    out.write_all(t.as_bytes())?;
                    at += t.len() as u64;
                }
                Piece::Slot { offset, value } => {
                    *offset = at;
                    out.write_all(format!("{value:<SLOT_WIDTH$}").as_bytes())?;
                    at += SLOT_WIDTH as u64;
                }
                Piece::Samples {
                    offset,
                    used,
                    capacity,
                } => {
                    if *used > 0 {
                        let old = self.file.as_mut().context("no file to copy samples from")?;
                        old.seek(SeekFrom::Start(*offset))?;
                        let mut buf = vec![0u8; *used as usize];
                        old.read_exact(&mut buf)?;
                        out.write_all(&buf)?;
                    }
                    *offset = at;
                    if !reserve {
                        *capacity = *used;
                    }
                    let pad = (*capacity - *used) as usize;
                    out.write_all(&vec![b'\n'; pad])?;
                    at += *capacity;
                }
            }
        }
        out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        Ok(())
    }

    /// Rewrites the stage without the reserve (a no-op before the first frame). The file stays
    /// valid whether or not this is called.
    pub fn finish(&mut self) -> Result<()> {
        if self.file.is_none() {
            return Ok(());
        }
        self.rewrite(false)
    }
}

/// Writes `frame` as a one-frame stage at `path` (a named mesh such as the final state).
pub fn write_single(path: &Path, frame: &Frame, up: UpAxis) -> Result<()> {
    let mut w = UsdWriter::new(path, up);
    w.push(frame)?;
    w.finish()
}

#[cfg(test)]
#[path = "usd_tests.rs"]
mod tests;
