//! Vertex selections and what `balloon inflate` does with them: rest-thickness maps
//! (`--thickness-file`, `--thickness-rule`, a PLY `thickness` property), anchors (`--pin`,
//! `--pin-stiffness`) and loads scheduled in time (`--load`).
//!
//! A selector picks vertices of the (scaled) rest mesh:
//! `indices:1,2,3`, `file:PATH` (one vertex index per line, `#` comments),
//! `below:AXIS:VALUE` / `above:AXIS:VALUE` (a half-space, coordinate in m, `AXIS` one of `x`,
//! `y`, `z`), `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m, bounds included) or
//! `ply:PATH:PROPERTY` (a vertex group stored in a PLY file: the vertices whose `PROPERTY` is
//! not zero, typically the mesh's own file, e.g. `ply:balloon.ply:neck`).
//!
//! An anchor (`--pin SELECTOR[@K]`) holds its vertices where they are at rest: hard (removed
//! from the solve, `balloon::shell::ShellSimulation::set_pinned_vertices`) unless a stiffness is
//! given, by `@K` or `--pin-stiffness K` (N/m), which makes it a zero-length spring per vertex to
//! its rest position (`set_anchor_springs`). A load (`--load KEY=VALUE;...`) is `gravity=GX,GY,GZ`
//! (m/s^2), `force=FX,FY,FZ;on=SELECTOR[;per=vertex|total]` (N: on each vertex, or the total
//! spread evenly over the selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (the vertices pulled
//! toward a point by springs of K N/m each, like the viewer's drag), each active from `start`
//! (s, default 0) until `end` (s, default for ever).

use crate::params::{End, check_real};
use balloon::mesh::TriMesh;
use balloon::mesh::io::PlyProperty;
use balloon::shell::{AnchorSpring, ShellMaterial, ShellSimulation};
use balloon::volumetric::VolumetricSimulation;
use std::path::{Path, PathBuf};

/// The flags of thickness maps, anchors and loads (part of `balloon inflate`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SetupArgs {
    /// Rest thickness map: a text file of thicknesses (m), one per line (`#` comments), one per
    /// face or one per vertex (averaged to the faces), told apart by their count. Replaces
    /// --thickness. Without a file or a rule, a PLY mesh's `thickness` vertex or face property
    /// is used when it has one.
    #[arg(long, conflicts_with = "thickness_rule")]
    pub thickness_file: Option<PathBuf>,
    /// Rest thickness linear in a coordinate over the mesh's bounding box, `AXIS:FROM:TO` (m;
    /// e.g. `z:3e-4:6e-4` is 0.3 mm at the lowest face centroid, 0.6 mm at the highest).
    /// Replaces --thickness.
    #[arg(long, value_parser = parse_rule)]
    pub thickness_rule: Option<LinearRule>,
    /// Pin vertices (repeatable): `indices:1,2,3`, `file:PATH`, `below:AXIS:VALUE`,
    /// `above:AXIS:VALUE`, `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m) or `ply:PATH:PROPERTY` (the
    /// vertices whose PLY vertex property is not 0), with `@K` for springs of K N/m instead of
    /// a hard pin (a hard-pinned vertex does not move at all).
    #[arg(long, value_parser = parse_pin)]
    pub pin: Vec<Pin>,
    /// Stiffness of the --pin anchors without their own `@K`, N/m, in (0, 1e12]; absent: hard
    /// pins.
    #[arg(long, value_parser = stiffness)]
    pub pin_stiffness: Option<f64>,
    /// A load (repeatable): `gravity=GX,GY,GZ` (m/s^2), `force=FX,FY,FZ;on=SELECTOR` (N per
    /// vertex; `per=total` spreads it over the selection) or `grab=X,Y,Z;on=SELECTOR;
    /// stiffness=K` (pulled toward the point, N/m per vertex); `start=S;end=S` schedule it (s).
    #[arg(long, value_parser = parse_load)]
    pub load: Vec<Load>,
}

/// What is wrong with a selection, a thickness map, an anchor or a load.
#[derive(Debug, thiserror::Error)]
pub enum SelectionError {
    /// A file cannot be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A line of a file is not what it should be.
    #[error("{}:{line}: {message}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A thickness map has a count that matches neither the faces nor the vertices.
    #[error(
        "{what} has {count} values, but the mesh has {faces} faces and {vertices} vertices \
         (one value per face or per vertex)"
    )]
    Count {
        /// Where the values come from.
        what: String,
        /// Values given.
        count: usize,
        /// Faces of the mesh.
        faces: usize,
        /// Vertices of the mesh.
        vertices: usize,
    },
    /// A thickness is not a positive finite number of at most 1 m.
    #[error("{what}: thickness {value:e} of {place} is not in (0, 1] m")]
    Thickness {
        /// Where the values come from.
        what: String,
        /// Which face or vertex.
        place: String,
        /// The value.
        value: f64,
    },
    /// A vertex index is out of range.
    #[error("{what}: vertex {index} does not exist (the mesh has {vertices} vertices)")]
    Index {
        /// The selector.
        what: String,
        /// The index.
        index: usize,
        /// Vertices of the mesh.
        vertices: usize,
    },
    /// A selector picks no vertex.
    #[error("`{0}` selects no vertex of the mesh")]
    Empty(String),
    /// A PLY vertex group cannot be read.
    #[error("cannot read the vertex group `{property}` of {}", path.display())]
    GroupFile {
        /// The PLY file.
        path: PathBuf,
        /// The vertex property.
        property: String,
        /// Why.
        #[source]
        source: balloon::mesh::MeshError,
    },
    /// A PLY vertex group is missing, per face, or of another vertex count.
    #[error("{}: vertex group `{property}`: {message}", path.display())]
    Group {
        /// The PLY file.
        path: PathBuf,
        /// The vertex property.
        property: String,
        /// What is wrong.
        message: String,
    },
    /// The mesh's own thickness property cannot be read.
    #[error("cannot read the thickness property of {}", path.display())]
    Mesh {
        /// The mesh file.
        path: PathBuf,
        /// Why.
        #[source]
        source: balloon::mesh::MeshError,
    },
    /// What this system does not support.
    #[error("{0}")]
    Unsupported(String),
    /// The simulation refuses the anchors or loads.
    #[error(transparent)]
    Shell(#[from] balloon::shell::ShellError),
    /// The volumetric simulation refuses the anchors or loads.
    #[error(transparent)]
    Volumetric(#[from] balloon::volumetric::VolumetricError),
    /// The two-layer simulation refuses the anchors or loads.
    #[error(transparent)]
    TwoLayer(#[from] balloon::two_layer::TwoLayerError),
}

/// A coordinate axis.
fn parse_axis(s: &str) -> Result<usize, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        _ => Err(format!("`{s}` is not an axis (x, y or z)")),
    }
}

/// A finite number.
fn finite(s: &str) -> Result<f64, String> {
    check_real(s, End::Closed(-1e12), End::Closed(1e12))
}

/// A stiffness, N/m, in (0, 1e12] (`--pin-stiffness`).
pub fn stiffness(s: &str) -> Result<f64, String> {
    check_real(s, End::Open(0.0), End::Closed(1e12))
}

/// `n` comma-separated finite numbers.
fn numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s.split(',').map(finite).collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("`{s}`: expected {N} numbers, found {}", v.len()))
}

/// A rest thickness linear in one coordinate over the bounding box (`--thickness-rule`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearRule {
    /// The coordinate (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Thickness at the lowest face centroid, m.
    pub from: f64,
    /// Thickness at the highest face centroid, m.
    pub to: f64,
}

/// `AXIS:FROM:TO` with both thicknesses in (0, 1] m.
pub fn parse_rule(s: &str) -> Result<LinearRule, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [axis, from, to] = parts[..] else {
        return Err(format!("`{s}`: expected AXIS:FROM:TO, e.g. z:3e-4:6e-4"));
    };
    let thick = |t: &str| check_real(t, End::Open(0.0), End::Closed(1.0));
    Ok(LinearRule {
        axis: parse_axis(axis)?,
        from: thick(from)?,
        to: thick(to)?,
    })
}

/// A set of vertices of the rest mesh.
#[derive(Clone, Debug, PartialEq)]
pub enum Selector {
    /// These vertex indices.
    Indices(Vec<usize>),
    /// The indices in a file, one per line.
    File(PathBuf),
    /// Vertices whose coordinate `axis` is below (`above == false`) or above the value, m.
    HalfSpace {
        /// 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The bound, m.
        value: f64,
        /// Above rather than below.
        above: bool,
    },
    /// Vertices inside the box `[xmin, ymin, zmin, xmax, ymax, zmax]` (m, bounds included).
    Box([f64; 6]),
    /// The vertices whose vertex property `property` of the PLY file `path` is not zero (a
    /// vertex group; the file's vertices must be the mesh's, in order).
    PlyGroup {
        /// The PLY file.
        path: PathBuf,
        /// The vertex property.
        property: String,
    },
}

/// `indices:..`, `file:..`, `below:..`, `above:..`, `box:..` or `ply:PATH:PROPERTY`.
pub fn parse_selector(s: &str) -> Result<Selector, String> {
    let (kind, rest) = s.split_once(':').ok_or_else(|| {
        format!("`{s}`: expected indices:1,2,3, file:PATH, below:AXIS:VALUE, above:AXIS:VALUE, box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX or ply:PATH:PROPERTY")
    })?;
    match kind.trim() {
        "indices" => rest
            .split(',')
            .map(|i| {
                i.trim()
                    .parse::<usize>()
                    .map_err(|_| format!("`{i}` is not a vertex index"))
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Selector::Indices),
        "file" if !rest.is_empty() => Ok(Selector::File(PathBuf::from(rest))),
        "below" | "above" => {
            let (axis, value) = rest
                .split_once(':')
                .ok_or_else(|| format!("`{s}`: expected {kind}:AXIS:VALUE"))?;
            Ok(Selector::HalfSpace {
                axis: parse_axis(axis)?,
                value: finite(value)?,
                above: kind.trim() == "above",
            })
        }
        "box" => {
            let b = numbers::<6>(rest)?;
            if (0..3).any(|k| b[k] > b[k + 3]) {
                return Err(format!("`{s}`: a minimum is above its maximum"));
            }
            Ok(Selector::Box(b))
        }
        "ply" => match rest.rsplit_once(':') {
            Some((path, property)) if !path.is_empty() && !property.trim().is_empty() => {
                Ok(Selector::PlyGroup {
                    path: PathBuf::from(path),
                    property: property.trim().to_owned(),
                })
            }
            _ => Err(format!("`{s}`: expected ply:PATH:PROPERTY")),
        },
        other => Err(format!(
            "`{other}` is not a selector (indices, file, below, above, box, ply)"
        )),
    }
}

impl std::fmt::Display for Selector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Selector::Indices(i) => {
                let list: Vec<String> = i.iter().map(usize::to_string).collect();
                write!(f, "indices:{}", list.join(","))
            }
            Selector::File(p) => write!(f, "file:{}", p.display()),
            Selector::HalfSpace { axis, value, above } => write!(
                f,
                "{}:{}:{value:?}",
                if *above { "above" } else { "below" },
                ["x", "y", "z"][*axis]
            ),
            Selector::Box(b) => {
                let list: Vec<String> = b.iter().map(|v| format!("{v:?}")).collect();
                write!(f, "box:{}", list.join(","))
            }
            Selector::PlyGroup { path, property } => {
                write!(f, "ply:{}:{property}", path.display())
            }
        }
    }
}

impl Selector {
    /// The same selector with a relative file path joined to `base`.
    pub fn relative_to(self, base: &Path) -> Selector {
        match self {
            Selector::File(p) if p.is_relative() => Selector::File(base.join(p)),
            Selector::PlyGroup { path, property } if path.is_relative() => Selector::PlyGroup {
                path: base.join(path),
                property,
            },
            other => other,
        }
    }

    /// The same selector with its file path absolute (for the recorded scenario).
    pub fn absolute(self) -> Selector {
        match self {
            Selector::File(p) => Selector::File(std::path::absolute(&p).unwrap_or(p)),
            Selector::PlyGroup { path, property } => Selector::PlyGroup {
                path: std::path::absolute(&path).unwrap_or(path),
                property,
            },
            other => other,
        }
    }

    /// The selected vertices of `positions` (flat, m), sorted; an error when none is.
    pub fn select(&self, positions: &[f64]) -> Result<Vec<usize>, SelectionError> {
        let nv = positions.len() / 3;
        let p = |v: usize, k: usize| positions[3 * v + k];
        let picked: Vec<usize> = match self {
            Selector::Indices(list) => list.clone(),
            Selector::File(path) => read_indices(path)?,
            Selector::HalfSpace { axis, value, above } => (0..nv)
                .filter(|&v| {
                    if *above {
                        p(v, *axis) > *value
                    } else {
                        p(v, *axis) < *value
                    }
                })
                .collect(),
            Selector::Box(b) => (0..nv)
                .filter(|&v| (0..3).all(|k| p(v, k) >= b[k] && p(v, k) <= b[k + 3]))
                .collect(),
            Selector::PlyGroup { path, property } => ply_group(path, property, nv)?,
        };
        if let Some(&index) = picked.iter().find(|&&i| i >= nv) {
            return Err(SelectionError::Index {
                what: self.to_string(),
                index,
                vertices: nv,
            });
        }
        if picked.is_empty() {
            return Err(SelectionError::Empty(self.to_string()));
        }
        let mut picked = picked;
        picked.sort_unstable();
        picked.dedup();
        Ok(picked)
    }
}

/// The vertices of a PLY vertex group: those whose vertex property `property` is not zero. The
/// file must have `vertices` vertices (the mesh's).
fn ply_group(path: &Path, property: &str, vertices: usize) -> Result<Vec<usize>, SelectionError> {
    let group = |message: String| SelectionError::Group {
        path: path.to_path_buf(),
        property: property.to_owned(),
        message,
    };
    let (mesh, values) =
        balloon::mesh::io::read_ply_with_property(path, property).map_err(|source| {
            SelectionError::GroupFile {
                path: path.to_path_buf(),
                property: property.to_owned(),
                source,
            }
        })?;
    match values {
        balloon::mesh::io::PlyProperty::PerVertex(v) if mesh.num_vertices() == vertices => Ok(v
            .iter()
            .enumerate()
            .filter(|(_, x)| **x != 0.0)
            .map(|(i, _)| i)
            .collect()),
        balloon::mesh::io::PlyProperty::PerVertex(_) => Err(group(format!(
            "the file has {} vertices, the body {vertices}",
            mesh.num_vertices()
        ))),
        balloon::mesh::io::PlyProperty::PerFace(_) => Err(group(
            "is a face property; a vertex group is a vertex property".into(),
        )),
        balloon::mesh::io::PlyProperty::Absent => Err(group("no vertex has this property".into())),
    }
}

/// The non-empty, non-comment lines of a text file with their 1-based numbers.
fn data_lines(path: &Path) -> Result<Vec<(usize, String)>, SelectionError> {
    let text = std::fs::read_to_string(path).map_err(|source| SelectionError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(text
        .lines()
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.split('#').next().unwrap_or("").trim();
            (!l.is_empty()).then(|| (i + 1, l.to_owned()))
        })
        .collect())
}

/// Vertex indices, one per line.
fn read_indices(path: &Path) -> Result<Vec<usize>, SelectionError> {
    data_lines(path)?
        .into_iter()
        .map(|(line, l)| {
            l.parse::<usize>().map_err(|_| SelectionError::Line {
                path: path.to_path_buf(),
                line,
                message: format!("`{l}` is not a vertex index (a whole number >= 0)"),
            })
        })
        .collect()
}

/// An anchor (`--pin`): a selection, hard or with its own spring stiffness.
#[derive(Clone, Debug, PartialEq)]
pub struct Pin {
    /// The pinned vertices.
    pub selector: Selector,
    /// Spring stiffness, N/m (`@K`); `None` takes `--pin-stiffness`, or pins hard.
    pub stiffness: Option<f64>,
}

/// `SELECTOR[@K]`.
pub fn parse_pin(s: &str) -> Result<Pin, String> {
    let (sel, k) = match s.rsplit_once('@') {
        Some((sel, k)) => (sel, Some(stiffness(k)?)),
        None => (s, None),
    };
    Ok(Pin {
        selector: parse_selector(sel)?,
        stiffness: k,
    })
}

impl std::fmt::Display for Pin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.selector)?;
        if let Some(k) = self.stiffness {
            write!(f, "@{k:?}")?;
        }
        Ok(())
    }
}

/// What a load does.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadKind {
    /// Gravity, m/s^2, on every vertex (its lumped mass times g).
    Gravity([f64; 3]),
    /// A constant force, N, on each selected vertex (or in total, spread evenly).
    Force {
        /// The force.
        force: [f64; 3],
        /// The total over the selection rather than per vertex.
        total: bool,
    },
    /// The selected vertices pulled toward a point by zero-length springs.
    Grab {
        /// The point, m.
        target: [f64; 3],
        /// Stiffness per vertex, N/m.
        stiffness: f64,
    },
}

/// A load (`--load`), active for `start <= t < end`.
#[derive(Clone, Debug, PartialEq)]
pub struct Load {
    /// What it does.
    pub kind: LoadKind,
    /// Where (forces and grabs).
    pub on: Option<Selector>,
    /// From, s.
    pub start: f64,
    /// Until, s (infinite: for ever).
    pub end: f64,
}

/// `KEY=VALUE;...` (see the module docs).
pub fn parse_load(s: &str) -> Result<Load, String> {
    let mut kind = None;
    let (mut on, mut per, mut k, mut start, mut end) = (None, None, None, 0.0, f64::INFINITY);
    for part in s.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| format!("`{part}`: expected KEY=VALUE"))?;
        let value = value.trim();
        let set_kind = |kind: &mut Option<(&'static str, [f64; 3])>, name| {
            if kind.is_some() {
                return Err("a load has one of gravity, force or grab".to_owned());
            }
            *kind = Some((name, numbers::<3>(value)?));
            Ok(())
        };
        match key.trim() {
            "gravity" => set_kind(&mut kind, "gravity")?,
            "force" => set_kind(&mut kind, "force")?,
            "grab" => set_kind(&mut kind, "grab")?,
            "on" => on = Some(parse_selector(value)?),
            "per" => {
                per = Some(match value {
                    "vertex" => false,
                    "total" => true,
                    _ => return Err(format!("per=`{value}`: expected vertex or total")),
                })
            }
            "stiffness" => k = Some(stiffness(value)?),
            "start" => start = check_real(value, End::Closed(0.0), End::Closed(1e9))?,
            "end" => end = check_real(value, End::Closed(0.0), End::Closed(1e9))?,
            other => {
                return Err(format!(
                    "`{other}` is not a load key (gravity, force, grab, on, per, stiffness, start, end)"
                ));
            }
        }
    }
    let (name, v) = kind.ok_or_else(|| format!("`{s}`: no gravity=, force= or grab="))?;
    if end <= start {
        return Err(format!("`{s}`: end must be after start"));
    }
    let kind = match name {
        "gravity" => {
            if on.is_some() || per.is_some() || k.is_some() {
                return Err("gravity acts on every vertex: no on=, per= or stiffness=".into());
            }
            LoadKind::Gravity(v)
        }
        "force" => {
            if k.is_some() {
                return Err("a force has no stiffness=".into());
            }
            LoadKind::Force {
                force: v,
                total: per.unwrap_or(false),
            }
        }
        _ => {
            if per.is_some() {
                return Err("a grab has no per=".into());
            }
            LoadKind::Grab {
                target: v,
                stiffness: k.ok_or("a grab needs stiffness=K (N/m)")?,
            }
        }
    };
    if name != "gravity" && on.is_none() {
        return Err(format!("`{s}`: on=SELECTOR is missing"));
    }
    Ok(Load {
        kind,
        on,
        start,
        end,
    })
}

impl std::fmt::Display for Load {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = |a: &[f64; 3]| format!("{:?},{:?},{:?}", a[0], a[1], a[2]);
        match &self.kind {
            LoadKind::Gravity(g) => write!(f, "gravity={}", v(g))?,
            LoadKind::Force { force, total } => write!(
                f,
                "force={};per={}",
                v(force),
                if *total { "total" } else { "vertex" }
            )?,
            LoadKind::Grab { target, stiffness } => {
                write!(f, "grab={};stiffness={stiffness:?}", v(target))?
            }
        }
        if let Some(on) = &self.on {
            write!(f, ";on={on}")?;
        }
        if self.start > 0.0 {
            write!(f, ";start={:?}", self.start)?;
        }
        if self.end.is_finite() {
            write!(f, ";end={:?}", self.end)?;
        }
        Ok(())
    }
}

/// Rewrites a `--pin` or `--load` value so that a `file:` path is absolute (`relative_to`:
/// joined to that folder first), for scenario files and the recorded scenario. Values that do
/// not parse are returned unchanged (the parser reports them).
pub fn rewrite_paths(flag: &str, value: &str, relative_to: Option<&Path>) -> String {
    let fix = |s: Selector| match relative_to {
        Some(base) => s.relative_to(base),
        None => s.absolute(),
    };
    match flag {
        "pin" => parse_pin(value).map_or_else(
            |_| value.to_owned(),
            |p| {
                Pin {
                    selector: fix(p.selector),
                    ..p
                }
                .to_string()
            },
        ),
        "load" => parse_load(value).map_or_else(
            |_| value.to_owned(),
            |l| {
                Load {
                    on: l.on.map(fix),
                    ..l
                }
                .to_string()
            },
        ),
        _ => value.to_owned(),
    }
}

impl SetupArgs {
    /// The per-face rest thickness of `mesh` (already scaled) from `--thickness-file`,
    /// `--thickness-rule` or the `thickness` property of a PLY `mesh_spec`; `None` when none
    /// applies (the uniform --thickness).
    pub fn thickness(
        &self,
        mesh_spec: &str,
        mesh: &TriMesh,
    ) -> Result<Option<Vec<f64>>, SelectionError> {
        let (nf, nv) = (mesh.num_triangles(), mesh.num_vertices());
        let (what, values) = if let Some(path) = &self.thickness_file {
            let lines = data_lines(path)?;
            let mut values = Vec::with_capacity(lines.len());
            for (line, l) in lines {
                let v = l
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v > 0.0 && *v <= 1.0);
                values.push(v.ok_or_else(|| SelectionError::Line {
                    path: path.clone(),
                    line,
                    message: format!("`{l}` is not a thickness in (0, 1] m"),
                })?);
            }
            (path.display().to_string(), values)
        } else if let Some(rule) = self.thickness_rule {
            let c: Vec<f64> = mesh
                .triangles
                .iter()
                .map(|t| t.iter().map(|&v| mesh.vertices[v][rule.axis]).sum::<f64>() / 3.0)
                .collect();
            let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let span = if hi > lo { hi - lo } else { 1.0 };
            let values = c
                .iter()
                .map(|&x| rule.from + (rule.to - rule.from) * (x - lo) / span)
                .collect();
            return Ok(Some(values));
        } else if mesh_spec.to_ascii_lowercase().ends_with(".ply") {
            let path = PathBuf::from(mesh_spec);
            let (_, property) = balloon::mesh::io::read_ply_with_property(&path, "thickness")
                .map_err(|source| SelectionError::Mesh {
                    path: path.clone(),
                    source,
                })?;
            let what = format!("the `thickness` property of {mesh_spec}");
            match property {
                PlyProperty::Absent => return Ok(None),
                PlyProperty::PerFace(v) | PlyProperty::PerVertex(v) => (what, v),
            }
        } else {
            return Ok(None);
        };
        for (i, &v) in values.iter().enumerate() {
            if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                return Err(SelectionError::Thickness {
                    what,
                    place: format!("value {}", i + 1),
                    value: v,
                });
            }
        }
        if values.len() == nf {
            Ok(Some(values))
        } else if values.len() == nv {
            Ok(Some(
                mesh.triangles
                    .iter()
                    .map(|t| t.iter().map(|&v| values[v]).sum::<f64>() / 3.0)
                    .collect(),
            ))
        } else {
            Err(SelectionError::Count {
                what,
                count: values.len(),
                faces: nf,
                vertices: nv,
            })
        }
    }

    /// Sets the anchors on `sim` and returns the loads to apply before each step
    /// ([`ShellLoads::before_step`]; the loads of time 0 are already applied).
    pub fn apply<M: ShellMaterial>(
        &self,
        sim: &mut ShellSimulation<M>,
    ) -> Result<ShellLoads, SelectionError> {
        let rest = sim.rest_positions().to_vec();
        let mut hard = Vec::new();
        let mut springs = Vec::new();
        for pin in &self.pin {
            let vertices = pin.selector.select(&rest)?;
            match pin.stiffness.or(self.pin_stiffness) {
                None => hard.extend(vertices),
                Some(k) => springs.extend(vertices.into_iter().map(|v| AnchorSpring {
                    vertex: v,
                    anchor: [rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]],
                    stiffness: k,
                })),
            }
        }
        if !hard.is_empty() {
            sim.set_pinned_vertices(hard)?;
        }
        let loads = select_loads(&self.load, &rest, Selector::select)?;
        let mut out = ShellLoads {
            springs,
            loads,
            active: None,
        };
        out.before_step(sim)?;
        Ok(out)
    }
}

/// Each load with the vertices (or particles) its `on` selector picks from the rest positions
/// `rest` by `select` (the system's selection, with its own message for an empty one); an
/// empty list for a load without `on` (gravity, on everything).
fn select_loads(
    loads: &[Load],
    rest: &[f64],
    select: impl Fn(&Selector, &[f64]) -> Result<Vec<usize>, SelectionError>,
) -> Result<Vec<(Load, Vec<usize>)>, SelectionError> {
    loads
        .iter()
        .map(|l| {
            let picked = match &l.on {
                Some(s) => select(s, rest)?,
                None => Vec::new(),
            };
            Ok((l.clone(), picked))
        })
        .collect()
}

/// The part of a force load each selected vertex takes: all of it (`per=vertex`) or its share
/// of the total (`per=total`).
fn force_share(total: bool, picked: usize) -> f64 {
    if total { 1.0 / picked as f64 } else { 1.0 }
}

/// Adds a force load to the flat `forces` (N per dof) of the `picked` vertices.
fn spread_force(forces: &mut [f64], force: &[f64; 3], total: bool, picked: &[usize]) {
    let share = force_share(total, picked.len());
    for &v in picked {
        for d in 0..3 {
            forces[3 * v + d] += share * force[d];
        }
    }
}

/// Pins the hard `--pin` selections of a two-layer body (those without `@K` when there is no
/// `--pin-stiffness`; `balloon::two_layer::TwoLayerSimulation::fix_particles`). Spring anchors
/// are left to [`two_layer_loads`].
pub fn fix_two_layer(
    sim: &mut balloon::two_layer::TwoLayerSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
) -> Result<(), SelectionError> {
    let rest = sim.positions().to_vec();
    for pin in pins {
        if pin.stiffness.or(pin_stiffness).is_none() {
            let particles = pin.selector.select(&rest)?;
            sim.fix_particles(&particles)?;
        }
    }
    Ok(())
}

/// The spring anchors and scheduled loads of a two-layer run
/// (`balloon::two_layer::TwoLayerSimulation::set_loads`), updated before each step
/// ([`TwoLayerLoads::before_step`]).
#[derive(Debug)]
pub struct TwoLayerLoads {
    /// The `--pin ...@K` springs to the rest positions (always on).
    springs: Vec<balloon::two_layer::AnchorSpring>,
    /// The loads with their selected particles.
    loads: Vec<(Load, Vec<usize>)>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

/// Selects the spring anchors (`@K`, or every pin with `--pin-stiffness`) and the loads of a
/// two-layer run on the particles' positions at the start and applies those of time 0.
pub fn two_layer_loads(
    sim: &mut balloon::two_layer::TwoLayerSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    loads: &[Load],
) -> Result<TwoLayerLoads, SelectionError> {
    let rest = sim.positions().to_vec();
    let mut springs = Vec::new();
    for pin in pins {
        if let Some(k) = pin.stiffness.or(pin_stiffness) {
            springs.extend(pin.selector.select(&rest)?.into_iter().map(|i| {
                balloon::two_layer::AnchorSpring {
                    particle: i,
                    point: [rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]],
                    stiffness: k,
                }
            }));
        }
    }
    let loads = select_loads(loads, &rest, Selector::select)?;
    let mut out = TwoLayerLoads {
        springs,
        loads,
        active: None,
    };
    out.before_step(sim)?;
    Ok(out)
}

impl TwoLayerLoads {
    /// Sets the anchor springs and the forces of the loads active in the middle of the coming
    /// step (`start <= t < end`), when that set changed. Gravity loads add each particle's mass
    /// times g to its force.
    pub fn before_step(
        &mut self,
        sim: &mut balloon::two_layer::TwoLayerSimulation,
    ) -> Result<(), SelectionError> {
        if self.springs.is_empty() && self.loads.is_empty() {
            return Ok(());
        }
        let active = active_loads(&self.loads, sim.time(), sim.dt());
        if self.active.as_ref() == Some(&active) {
            return Ok(());
        }
        let masses = sim.model().masses.clone();
        let mut forces = vec![0.0; 3 * masses.len()];
        let mut springs = self.springs.clone();
        let mut any_force = false;
        for ((load, particles), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
            match &load.kind {
                LoadKind::Gravity(g) => {
                    any_force = true;
                    for (i, m) in masses.iter().enumerate() {
                        for d in 0..3 {
                            forces[3 * i + d] += m * g[d];
                        }
                    }
                }
                LoadKind::Force { force, total } => {
                    any_force = true;
                    spread_force(&mut forces, force, *total, particles);
                }
                LoadKind::Grab { target, stiffness } => {
                    springs.extend(particles.iter().map(|&i| balloon::two_layer::AnchorSpring {
                        particle: i,
                        point: *target,
                        stiffness: *stiffness,
                    }));
                }
            }
        }
        sim.set_loads(springs, any_force.then_some(&forces[..]))?;
        self.active = Some(active);
        Ok(())
    }
}

/// The anchor springs and scheduled loads of a shell run.
#[derive(Debug, Default)]
pub struct ShellLoads {
    /// The `--pin` springs (always on).
    springs: Vec<AnchorSpring>,
    /// The loads with their selected vertices.
    loads: Vec<(Load, Vec<usize>)>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

impl ShellLoads {
    /// Sets the external forces and anchor springs of the loads active at the simulation's
    /// current time (`start <= t < end`), when that set changed.
    pub fn before_step<M: ShellMaterial>(
        &mut self,
        sim: &mut ShellSimulation<M>,
    ) -> Result<(), SelectionError> {
        let active = active_loads(&self.loads, sim.time(), sim.dt());
        if self.active.as_ref() == Some(&active) {
            return Ok(());
        }
        let n = sim.positions().len();
        let mut forces = vec![0.0; n];
        let mut springs = self.springs.clone();
        let mut any_force = false;
        for ((load, vertices), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
            match &load.kind {
                LoadKind::Gravity(g) => {
                    any_force = true;
                    for (i, (f, m)) in forces.iter_mut().zip(sim.masses()).enumerate() {
                        *f += m * g[i % 3];
                    }
                }
                LoadKind::Force { force, total } => {
                    any_force = true;
                    spread_force(&mut forces, force, *total, vertices);
                }
                LoadKind::Grab { target, stiffness } => {
                    springs.extend(vertices.iter().map(|&v| AnchorSpring {
                        vertex: v,
                        anchor: *target,
                        stiffness: *stiffness,
                    }));
                }
            }
        }
        sim.set_external_forces(any_force.then_some(&forces[..]))?;
        sim.set_anchor_springs(springs)?;
        self.active = Some(active);
        Ok(())
    }
}

/// The flat rest positions (m) of the volumetric body's lattice particles, which the
/// selectors pick from.
fn particle_rest(sim: &VolumetricSimulation) -> Vec<f64> {
    sim.lattice()
        .tet_mesh
        .vertices
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect()
}

/// The particles `selector` picks from the flat rest positions `rest`; an empty selection is
/// an error naming the selector and the particles.
fn select_particles(selector: &Selector, rest: &[f64]) -> Result<Vec<usize>, SelectionError> {
    selector.select(rest).map_err(|e| match e {
        SelectionError::Empty(s) => SelectionError::Unsupported(format!(
            "`{s}` selects no particle of the body ({} particles)",
            rest.len() / 3
        )),
        other => other,
    })
}

/// Pins the hard `--pin` selections of a volumetric body (those without `@K` when there is no
/// `--pin-stiffness`): the selected lattice particles, picked by their rest positions, never
/// move (`VolumetricSimulation::set_fixed_particles`). Spring anchors are left to
/// [`volumetric_loads`].
pub fn fix_volumetric(
    sim: &mut VolumetricSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
) -> Result<(), SelectionError> {
    let rest = particle_rest(sim);
    for pin in pins {
        if pin.stiffness.or(pin_stiffness).is_none() {
            let particles = select_particles(&pin.selector, &rest)?;
            sim.set_fixed_particles(&particles)?;
        }
    }
    Ok(())
}

/// A zero-length spring pulling one particle toward a point.
#[derive(Clone, Copy, Debug)]
struct PointSpring {
    particle: usize,
    anchor: [f64; 3],
    stiffness: f64,
}

/// The spring anchors and scheduled loads of a volumetric run, applied through
/// `VolumetricSimulation::set_external_forces` (and `set_gravity`) before each step
/// ([`VolumetricLoads::before_step`]).
#[derive(Debug)]
pub struct VolumetricLoads {
    /// The `--pin ...@K` springs to the rest positions (always on).
    springs: Vec<PointSpring>,
    /// The loads with their selected particles.
    loads: Vec<(Load, Vec<usize>)>,
    /// Gravity when no gravity load is active (`--gravity`), m/s^2.
    gravity: [f64; 3],
    /// The constant forces of the active loads (N, one per particle) and the springs of the
    /// active grabs, as of the last change of the active set.
    constant: Vec<nalgebra::Vector3<f64>>,
    /// Whether any constant force is active.
    any_constant: bool,
    /// Anchor springs plus the springs of the active grabs.
    active_springs: Vec<PointSpring>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

/// Selects the spring anchors (`@K`, or every pin with `--pin-stiffness`) and the loads of a
/// volumetric run on its lattice particles (by their rest positions) and applies those of time
/// 0. A selection that picks no particle is an error naming the selector.
pub fn volumetric_loads(
    sim: &mut VolumetricSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    loads: &[Load],
) -> Result<VolumetricLoads, SelectionError> {
    let rest = particle_rest(sim);
    let mut springs = Vec::new();
    for pin in pins {
        if let Some(k) = pin.stiffness.or(pin_stiffness) {
            springs.extend(
                select_particles(&pin.selector, &rest)?
                    .into_iter()
                    .map(|v| PointSpring {
                        particle: v,
                        anchor: [rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]],
                        stiffness: k,
                    }),
            );
        }
    }
    let loads = select_loads(loads, &rest, select_particles)?;
    let mut out = VolumetricLoads {
        springs,
        loads,
        gravity: sim.body().params.gravity,
        constant: Vec::new(),
        any_constant: false,
        active_springs: Vec::new(),
        active: None,
    };
    out.before_step(sim)?;
    Ok(out)
}

impl VolumetricLoads {
    /// Whether there is nothing to apply (no spring anchor, no load).
    pub fn is_empty(&self) -> bool {
        self.springs.is_empty() && self.loads.is_empty()
    }

    /// Sets the gravity and external forces of the coming step: the loads active at its middle
    /// (`start <= t < end`), and the springs (anchors and grabs) at the current positions,
    /// `F = K (anchor - x)` per particle, evaluated explicitly like the cell springs (Eq. 1).
    /// A gravity load replaces `--gravity` while active (several add up).
    pub fn before_step(&mut self, sim: &mut VolumetricSimulation) -> Result<(), SelectionError> {
        if self.is_empty() {
            return Ok(());
        }
        let active = active_loads(&self.loads, sim.time(), sim.body().params.dt);
        if self.active.as_ref() != Some(&active) {
            let n = sim.positions().len();
            let mut forces = vec![nalgebra::Vector3::zeros(); n];
            let mut springs = self.springs.clone();
            let mut gravity: Option<[f64; 3]> = None;
            let mut any = false;
            for ((load, particles), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
                match &load.kind {
                    LoadKind::Gravity(g) => {
                        let sum = gravity.get_or_insert([0.0; 3]);
                        for d in 0..3 {
                            sum[d] += g[d];
                        }
                    }
                    LoadKind::Force { force, total } => {
                        any = true;
                        let share = force_share(*total, particles.len());
                        for &i in particles {
                            forces[i] += nalgebra::Vector3::from(*force) * share;
                        }
                    }
                    LoadKind::Grab { target, stiffness } => {
                        springs.extend(particles.iter().map(|&i| PointSpring {
                            particle: i,
                            anchor: *target,
                            stiffness: *stiffness,
                        }));
                    }
                }
            }
            sim.set_gravity(gravity.unwrap_or(self.gravity))?;
            self.constant = forces;
            self.any_constant = any;
            self.active_springs = springs;
            self.active = Some(active);
        }
        if self.active_springs.is_empty() {
            sim.set_external_forces(self.any_constant.then_some(&self.constant[..]))?;
            return Ok(());
        }
        let mut forces = self.constant.clone();
        let x = sim.positions();
        for s in &self.active_springs {
            forces[s.particle] +=
                (nalgebra::Vector3::from(s.anchor) - x[s.particle].coords) * s.stiffness;
        }
        sim.set_external_forces(Some(&forces))?;
        Ok(())
    }
}

/// Which of `loads` act during the step from `time` of size `dt`: those whose `[start, end)`
/// holds the middle of the step, so that a load scheduled at a step boundary is not missed by
/// round-off in the time (the same rule for the three systems).
fn active_loads<T>(loads: &[(Load, T)], time: f64, dt: f64) -> Vec<bool> {
    let t = time + 0.5 * dt;
    loads
        .iter()
        .map(|(l, _)| l.start <= t && t < l.end)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_print_and_read_back() {
        for s in [
            "indices:1,2,3",
            "file:neck.txt",
            "below:z:0.01",
            "above:x:-0.2",
            "box:0.0,0.0,0.0,1.0,1.0,1.0",
        ] {
            let sel = parse_selector(s).unwrap();
            assert_eq!(parse_selector(&sel.to_string()).unwrap(), sel, "{s}");
        }
        let p = parse_pin("below:y:0.5@250").unwrap();
        assert_eq!(p.stiffness, Some(250.0));
        assert_eq!(parse_pin(&p.to_string()).unwrap(), p);
        for s in [
            "gravity=0,0,-9.81",
            "force=0,0,-1;on=indices:4;per=total;start=0.5;end=1",
            "grab=0,0,0.3;on=above:z:0.09;stiffness=100;end=2",
        ] {
            let l = parse_load(s).unwrap();
            assert_eq!(parse_load(&l.to_string()).unwrap(), l, "{s}");
        }
        for (bad, what) in [
            ("below:w:0", "axis"),
            ("box:1,0,0,0,1,1", "minimum"),
            ("indices:1,x", "vertex index"),
            ("near:1", "selector"),
        ] {
            let e = parse_selector(bad).unwrap_err();
            assert!(e.contains(what), "{bad}: {e}");
        }
        assert!(parse_pin("below:z:0@0").is_err());
        for (bad, what) in [
            ("force=0,0,1", "on="),
            ("grab=0,0,1;on=indices:1", "stiffness"),
            ("gravity=0,0,-9.81;on=indices:1", "every vertex"),
            ("force=0,0;on=indices:1", "3 numbers"),
            ("force=0,0,1;on=indices:1;start=2;end=1", "after start"),
            ("wind=1,2,3", "not a load key"),
        ] {
            let e = parse_load(bad).unwrap_err();
            assert!(e.contains(what), "{bad}: {e}");
        }
        assert_eq!(parse_rule("Z:3e-4:6e-4").unwrap().axis, 2);
        assert!(parse_rule("z:0:1").is_err() && parse_rule("z:1").is_err());
    }

    #[test]
    fn selectors_pick_vertices_and_files_name_their_lines() {
        let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 1.0, 1.0];
        let sel = |s: &str| parse_selector(s).unwrap().select(&x);
        assert_eq!(sel("below:z:0.6").unwrap(), vec![0, 1]);
        assert_eq!(sel("above:y:0.5").unwrap(), vec![2]);
        assert_eq!(sel("box:0,0,0,1,0,1").unwrap(), vec![0, 1]);
        assert_eq!(sel("indices:2,0,2").unwrap(), vec![0, 2]);
        assert!(
            sel("indices:3")
                .unwrap_err()
                .to_string()
                .contains("vertex 3")
        );
        assert!(
            sel("below:z:-1")
                .unwrap_err()
                .to_string()
                .contains("no vertex")
        );
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("g.txt");
        std::fs::write(&f, "# neck\n1\n\n2 # top\n").unwrap();
        let s = Selector::File(f.clone());
        assert_eq!(s.select(&x).unwrap(), vec![1, 2]);
        std::fs::write(&f, "1\none\n").unwrap();
        let e = s.select(&x).unwrap_err().to_string();
        assert!(e.contains("g.txt:2:") && e.contains("one"), "{e}");
        let rel = rewrite_paths("pin", "file:g.txt@5", Some(dir.path()));
        assert_eq!(rel, format!("file:{}@5.0", f.display()));
    }

    #[test]
    fn a_ply_vertex_group_selects_its_nonzero_vertices_and_is_checked() {
        let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 1.0, 1.0];
        let dir = tempfile::tempdir().unwrap();
        let ply = |name: &str, element: &str, values: &[&str]| {
            let path = dir.path().join(name);
            let (vp, fp) = if element == "vertex" {
                ("property float neck\n", "")
            } else {
                ("", "property float neck\n")
            };
            let verts = ["0 0 0", "1 0 0.5", "0 1 1"];
            let mut text = format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\n{vp}element face 1\nproperty list uchar int vertex_indices\n\
                 {fp}end_header\n"
            );
            for (i, v) in verts.iter().enumerate() {
                let extra = if element == "vertex" {
                    format!(" {}", values[i])
                } else {
                    String::new()
                };
                text += &format!("{v}{extra}\n");
            }
            let extra = if element == "face" {
                format!(" {}", values[0])
            } else {
                String::new()
            };
            text += &format!("3 0 1 2{extra}\n");
            std::fs::write(&path, text).unwrap();
            path
        };
        let good = ply("g.ply", "vertex", &["0", "1", "2.5"]);
        let s = parse_selector(&format!("ply:{}:neck", good.display())).unwrap();
        assert_eq!(s.select(&x).unwrap(), vec![1, 2]);
        assert_eq!(parse_selector(&s.to_string()).unwrap(), s, "round trip");
        let err = |sel: String, x: &[f64]| {
            parse_selector(&sel)
                .unwrap()
                .select(x)
                .unwrap_err()
                .to_string()
        };
        assert!(err(format!("ply:{}:tail", good.display()), &x).contains("no vertex has"));
        assert!(
            err(format!("ply:{}:neck", good.display()), &x[..6]).contains("3 vertices, the body 2")
        );
        let face = ply("f.ply", "face", &["1"]);
        assert!(err(format!("ply:{}:neck", face.display()), &x).contains("face property"));
        let none = ply("z.ply", "vertex", &["0", "0", "0"]);
        assert!(err(format!("ply:{}:neck", none.display()), &x).contains("selects no vertex"));
        let e = err(
            format!("ply:{}:neck", dir.path().join("missing.ply").display()),
            &x,
        );
        assert!(e.contains("missing.ply") && e.contains("`neck`"), "{e}");
        assert!(parse_selector("ply:only").is_err());
        let rel = rewrite_paths("pin", "ply:g.ply:neck", Some(dir.path()));
        assert_eq!(rel, format!("ply:{}:neck", good.display()));
    }

    #[test]
    fn thickness_maps_per_face_per_vertex_by_rule_and_checked() {
        let mesh = balloon::mesh::generate::icosphere(1.0, 0).unwrap();
        let (nf, nv) = (mesh.num_triangles(), mesh.num_vertices());
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("t.txt");
        let args = SetupArgs {
            thickness_file: Some(f.clone()),
            ..Default::default()
        };
        let faces: String = (0..nf).map(|i| format!("{}e-4\n", 1 + i % 3)).collect();
        std::fs::write(&f, format!("# per face\n{faces}")).unwrap();
        let t = args.thickness("m.obj", &mesh).unwrap().unwrap();
        assert_eq!((t.len(), t[0], t[1]), (nf, 1e-4, 2e-4));
        std::fs::write(&f, "3e-4\n".repeat(nv)).unwrap();
        let t = args.thickness("m.obj", &mesh).unwrap().unwrap();
        assert!(t.iter().all(|&h| (h - 3e-4).abs() < 1e-18));
        std::fs::write(&f, "3e-4\n".repeat(nv + 1)).unwrap();
        let e = args.thickness("m.obj", &mesh).unwrap_err().to_string();
        assert!(e.contains(&format!("{} values", nv + 1)), "{e}");
        std::fs::write(&f, "3e-4\n-1\n").unwrap();
        let e = args.thickness("m.obj", &mesh).unwrap_err().to_string();
        assert!(e.contains("t.txt:2:") && e.contains("-1"), "{e}");
        let rule = SetupArgs {
            thickness_rule: Some(parse_rule("z:1e-4:3e-4").unwrap()),
            ..Default::default()
        };
        let t = rule.thickness("m.obj", &mesh).unwrap().unwrap();
        let (lo, hi) = t
            .iter()
            .fold((1.0f64, 0.0f64), |(a, b), &h| (a.min(h), b.max(h)));
        assert!((lo - 1e-4).abs() < 1e-15 && (hi - 3e-4).abs() < 1e-15);
        assert_eq!(
            SetupArgs::default().thickness("m.obj", &mesh).unwrap(),
            None
        );
    }
}
