//! Selectors: the vertices (or particles) of a rest shape picked by index, by a file of
//! indices, by a half-space, by a box or by a PLY vertex group; and the spec parsers shared by
//! thickness rules, anchors and loads.

use crate::range::{End, NOT_A_NUMBER, Real};
use std::path::{Path, PathBuf};

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
    /// Hard pins hold every vertex of the mesh (every particle of a volumetric or two-layer
    /// body): nothing can move, so a run or a static solve would "converge" on the unchanged
    /// shape. Pin fewer vertices, or anchor them with springs.
    #[error(
        "`pin` holds all {count} {what} ({selections}), so nothing can move and the shape \
         would stay as it is; pin fewer, or give the pins a stiffness (`pin_stiffness`, \
         or `@K` on a pin) to hold them with springs"
    )]
    AllPinned {
        /// Vertices or particles of the body (all of them pinned).
        count: usize,
        /// What they are: "vertices of the mesh", "particles of the lattice", ...
        what: &'static str,
        /// The hard pins' selections, quoted and joined (`` `below:z:0` ``).
        selections: String,
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
pub(crate) fn parse_axis(s: &str) -> Result<usize, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        _ => Err(format!("`{s}` is not an axis (x, y or z)")),
    }
}

/// A number of a spec written as text, in `range`: the reason names the range (`not a number;
/// expected a finite number in (0, 1]`, `must be a finite number in (0, 1]`).
pub(crate) fn spec_real(s: &str, range: Real) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| {
        format!(
            "{NOT_A_NUMBER}; expected a finite number in {}",
            range.interval()
        )
    })?;
    if range.contains(v) {
        Ok(v)
    } else {
        Err(range.reason())
    }
}

/// A finite number.
fn finite(s: &str) -> Result<f64, String> {
    spec_real(s, Real::new(End::Closed(-1e12), End::Closed(1e12)))
}

/// The range of an anchor's or a grab's stiffness, N/m: (0, 1e12].
pub const STIFFNESS: Real = Real::new(End::Open(0.0), End::Closed(1e12));

/// A stiffness, N/m, in (0, 1e12] (`pin_stiffness`, an anchor's `@K`, a grab's `stiffness=`).
pub fn stiffness(s: &str) -> Result<f64, String> {
    spec_real(s, STIFFNESS)
}

/// `n` comma-separated finite numbers.
pub(crate) fn numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s.split(',').map(finite).collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("`{s}`: expected {N} numbers, found {}", v.len()))
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
pub(crate) fn data_lines(path: &Path) -> Result<Vec<(usize, String)>, SelectionError> {
    // A FIFO, a device or a directory is refused before it is opened, a file over the limit
    // before it is read.
    let text = balloon::mesh::io::read_input_text(path, balloon::mesh::io::MAX_TEXT_INPUT_BYTES)
        .map_err(|e| SelectionError::Read {
            path: path.to_path_buf(),
            source: e.into_io(),
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
