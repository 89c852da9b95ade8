//! Stanford PLY reader (ASCII, binary little- and big-endian).
//!
//! Hand-written so that errors name the file and the line (header, ASCII body) or byte offset
//! (binary body). Handles any scalar type (`char`/`int8`, `uchar`/`uint8`, `short`/`int16`,
//! `ushort`/`uint16`, `int`/`int32`, `uint`/`uint32`, `float`/`float32`, `double`/`float64`) for
//! `x`, `y`, `z`; the face list `vertex_indices` or `vertex_index` with any count and index types,
//! polygons fan-triangulated; `comment` and `obj_info` lines; unknown elements and properties
//! (including lists) skipped with their declared types.

use super::text::{byte_err, line_err};
use crate::{MeshError, TriMesh};
use nalgebra::Point3;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }
}

#[derive(Clone, Debug)]
enum Prop {
    Scalar { ty: Ty, name: String },
    List { count: Ty, item: Ty, name: String },
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// A source of values: ASCII tokens or binary bytes.
trait Source {
    fn value(&mut self, ty: Ty, what: &dyn Fn() -> String) -> Result<f64, MeshError>;
    fn location(&self) -> String;
}

struct Ascii<'a> {
    path: &'a Path,
    tokens: std::iter::Peekable<Box<dyn Iterator<Item = (usize, &'a str)> + 'a>>,
    line: usize,
}

impl Source for Ascii<'_> {
    fn value(&mut self, ty: Ty, what: &dyn Fn() -> String) -> Result<f64, MeshError> {
        let Some((l, tok)) = self.tokens.next() else {
            return Err(line_err(
                self.path,
                self.line,
                format!("unexpected end of file reading {}", what()),
            ));
        };
        self.line = l;
        let v: f64 = tok
            .parse()
            .map_err(|_| line_err(self.path, l, format!("{} `{tok}` is not a number", what())))?;
        if !v.is_finite() || (ty.is_int() && v.fract() != 0.0) {
            return Err(line_err(
                self.path,
                l,
                format!("{} `{tok}` is not a valid {ty:?}", what()),
            ));
        }
        Ok(v)
    }

    fn location(&self) -> String {
        format!("line {}", self.line)
    }
}

struct Binary<'a> {
    path: &'a Path,
    data: &'a [u8],
    pos: usize,
    big: bool,
}

impl Source for Binary<'_> {
    fn value(&mut self, ty: Ty, what: &dyn Fn() -> String) -> Result<f64, MeshError> {
        let n = ty.size();
        if self.pos + n > self.data.len() {
            return Err(byte_err(
                self.path,
                self.pos,
                format!(
                    "unexpected end of file reading {} ({} bytes left, {n} needed)",
                    what(),
                    self.data.len() - self.pos
                ),
            ));
        }
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
        if self.big {
            b[..n].reverse();
        }
        self.pos += n;
        Ok(match ty {
            Ty::I8 => b[0] as i8 as f64,
            Ty::U8 => b[0] as f64,
            Ty::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Ty::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Ty::F64 => f64::from_le_bytes(b),
        })
    }

    fn location(&self) -> String {
        format!("byte {}", self.pos)
    }
}

fn header(bytes: &[u8], path: &Path) -> Result<(Format, Vec<Element>, usize, usize), MeshError> {
    // The header is ASCII up to and including the `end_header` line.
    let mut pos = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() {
            return Err(line_err(
                path,
                line_no.max(1),
                "unexpected end of file in the header (no `end_header`)",
            ));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e);
        line_no += 1;
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        let line = std::str::from_utf8(raw)
            .map_err(|_| line_err(path, line_no, "header line is not text"))?
            .trim_end_matches('\r');
        let toks: Vec<&str> = line.split_whitespace().collect();
        if line_no == 1 {
            if toks != ["ply"] {
                return Err(line_err(
                    path,
                    1,
                    "not a PLY file: the first line must be `ply`",
                ));
            }
            continue;
        }
        let Some(&kw) = toks.first() else { continue };
        match kw {
            "format" => {
                format = Some(match toks.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Little,
                    Some("binary_big_endian") => Format::Big,
                    other => {
                        return Err(line_err(
                            path,
                            line_no,
                            format!("unknown PLY format `{}`", other.unwrap_or("")),
                        ));
                    }
                })
            }
            "comment" | "obj_info" => {}
            "element" => {
                if toks.len() != 3 {
                    return Err(line_err(path, line_no, "expected `element NAME COUNT`"));
                }
                let count = toks[2].parse().map_err(|_| {
                    line_err(
                        path,
                        line_no,
                        format!("element count `{}` is not a non-negative integer", toks[2]),
                    )
                })?;
                elements.push(Element {
                    name: toks[1].to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(line_err(path, line_no, "`property` before any `element`"));
                };
                let ty = |s: &str| {
                    Ty::parse(s).ok_or_else(|| {
                        line_err(path, line_no, format!("unknown property type `{s}`"))
                    })
                };
                match toks.as_slice() {
                    ["property", "list", c, i, name] => el.props.push(Prop::List {
                        count: ty(c)?,
                        item: ty(i)?,
                        name: name.to_string(),
                    }),
                    ["property", t, name] => el.props.push(Prop::Scalar {
                        ty: ty(t)?,
                        name: name.to_string(),
                    }),
                    _ => {
                        return Err(line_err(
                            path,
                            line_no,
                            "expected `property TYPE NAME` or `property list TYPE TYPE NAME`",
                        ));
                    }
                }
            }
            "end_header" => break,
            other => {
                return Err(line_err(
                    path,
                    line_no,
                    format!("unknown header keyword `{other}`"),
                ));
            }
        }
    }
    let format =
        format.ok_or_else(|| line_err(path, line_no, "the header has no `format` line"))?;
    Ok((format, elements, pos, line_no))
}

/// A scalar property of a PLY file's vertices or faces, read with the mesh by
/// [`parse_ply_with_property`].
#[derive(Clone, Debug, PartialEq)]
pub enum PlyProperty {
    /// Neither the vertices nor the faces have the property.
    Absent,
    /// One value per vertex.
    PerVertex(Vec<f64>),
    /// One value per triangle (a polygon's value repeated for each triangle of its fan).
    PerFace(Vec<f64>),
}

fn read_body(
    src: &mut dyn Source,
    elements: &[Element],
    path: &Path,
    cap: usize,
    want: Option<&str>,
) -> Result<(TriMesh, PlyProperty), MeshError> {
    let mut property = PlyProperty::Absent;
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut nv = None;
    let mut corners = Vec::new();
    for el in elements {
        let is_vertex = el.name == "vertex";
        let is_face = el.name == "face";
        let find = |n: &str| {
            el.props
                .iter()
                .position(|p| matches!(p, Prop::Scalar { name, .. } if name == n))
        };
        let (ix, iy, iz) = (find("x"), find("y"), find("z"));
        // The wanted property of this element (vertex properties win over face ones).
        let iw = want
            .and_then(find)
            .filter(|_| (is_vertex || is_face) && !matches!(property, PlyProperty::PerVertex(_)));
        let mut wanted = Vec::new();
        let mut value = 0.0;
        if is_vertex && (ix.is_none() || iy.is_none() || iz.is_none()) {
            return Err(MeshError::Parse {
                path: path.to_path_buf(),
                location: "header".into(),
                message: "element `vertex` lacks one of the properties x, y, z".into(),
            });
        }
        let list_idx = el.props.iter().position(
            |p| matches!(p, Prop::List { name, .. } if name == "vertex_indices" || name == "vertex_index"),
        );
        if is_vertex {
            vertices.reserve(el.count.min(cap));
        }
        let mut xyz = [0.0; 3];
        // An element without properties occupies no bytes, whatever its (untrusted) count.
        let count = if el.props.is_empty() { 0 } else { el.count };
        for k in 0..count {
            let triangles_before = triangles.len();
            for (pi, prop) in el.props.iter().enumerate() {
                match prop {
                    Prop::Scalar { ty, name } => {
                        let v = src.value(*ty, &|| format!("{} {k} property {name}", el.name))?;
                        if Some(pi) == iw {
                            value = v;
                            if is_vertex {
                                wanted.push(v);
                            }
                        }
                        if is_vertex {
                            if Some(pi) == ix {
                                xyz[0] = v;
                            } else if Some(pi) == iy {
                                xyz[1] = v;
                            } else if Some(pi) == iz {
                                xyz[2] = v;
                            }
                        }
                    }
                    Prop::List { count, item, name } => {
                        let n =
                            src.value(*count, &|| format!("{} {k} list count of {name}", el.name))?;
                        if !(0.0..=1e6).contains(&n) || n.fract() != 0.0 {
                            return Err(MeshError::Parse {
                                path: path.to_path_buf(),
                                location: src.location(),
                                message: format!(
                                    "{} {k}: list `{name}` has invalid length {n}",
                                    el.name
                                ),
                            });
                        }
                        let n = n as usize;
                        let take = is_face && Some(pi) == list_idx;
                        corners.clear();
                        for c in 0..n {
                            let v = src
                                .value(*item, &|| format!("{} {k} index {c} of {name}", el.name))?;
                            if take {
                                let nvert = nv.unwrap_or(0);
                                if v < 0.0 || v >= nvert as f64 || v.fract() != 0.0 {
                                    return Err(MeshError::Parse {
                                        path: path.to_path_buf(),
                                        location: src.location(),
                                        message: format!(
                                            "face {k}: vertex index {v} out of range ({} vertices)",
                                            nv.map_or("no".into(), |x| x.to_string())
                                        ),
                                    });
                                }
                                corners.push(v as usize);
                            }
                        }
                        if take {
                            if n < 3 {
                                return Err(MeshError::Parse {
                                    path: path.to_path_buf(),
                                    location: src.location(),
                                    message: format!(
                                        "face {k} has {n} corners (at least 3 needed)"
                                    ),
                                });
                            }
                            for j in 1..n - 1 {
                                triangles.push([corners[0], corners[j], corners[j + 1]]);
                            }
                        }
                    }
                }
            }
            if is_face && iw.is_some() {
                wanted.extend(std::iter::repeat_n(
                    value,
                    triangles.len() - triangles_before,
                ));
            }
            if is_vertex {
                if !xyz.iter().all(|c| c.is_finite()) {
                    return Err(MeshError::Parse {
                        path: path.to_path_buf(),
                        location: src.location(),
                        message: format!("vertex {k} has a non-finite coordinate"),
                    });
                }
                vertices.push(Point3::new(xyz[0], xyz[1], xyz[2]));
            }
        }
        if is_vertex {
            nv = Some(el.count);
        }
        if iw.is_some() {
            property = if is_vertex {
                PlyProperty::PerVertex(wanted)
            } else {
                PlyProperty::PerFace(wanted)
            };
        }
    }
    if triangles.is_empty() {
        return Err(MeshError::Parse {
            path: path.to_path_buf(),
            location: src.location(),
            message: "no faces found (no `face` element with a `vertex_indices` list)".into(),
        });
    }
    Ok((TriMesh::new(vertices, triangles), property))
}

/// Parses PLY `bytes`; `path` is only used in error messages.
///
/// # Errors
/// [`MeshError::Parse`] naming `path` and the header/ASCII line or binary byte offset: a bad
/// header, a truncated body, a bad number, a face index out of range, a face before the
/// vertices, or no faces.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    Ok(parse_ply_with_property(bytes, path, "")?.0)
}

/// Parses PLY `bytes` like [`parse_ply`] and also reads the scalar property `name` of the
/// `vertex` element or, if the vertices lack it, of the `face` element (e.g. a `thickness`
/// map); [`PlyProperty::Absent`] when neither has it.
///
/// # Errors
/// Those of [`parse_ply`].
pub fn parse_ply_with_property(
    bytes: &[u8],
    path: &Path,
    name: &str,
) -> Result<(TriMesh, PlyProperty), MeshError> {
    let want = (!name.is_empty()).then_some(name);
    let (mesh, property) = parse_ply_body(super::strip_bom(bytes), path, want)?;
    Ok((
        super::refuse_all_degenerate(path, mesh, || "header".to_string())?,
        property,
    ))
}

fn parse_ply_body(
    bytes: &[u8],
    path: &Path,
    want: Option<&str>,
) -> Result<(TriMesh, PlyProperty), MeshError> {
    let (format, elements, body, header_lines) = header(bytes, path)?;
    let cap = bytes.len() / 4 + 1;
    match format {
        Format::Ascii => {
            let text = std::str::from_utf8(&bytes[body..]).map_err(|e| {
                byte_err(path, body + e.valid_up_to(), "ASCII PLY body is not text")
            })?;
            let it: Box<dyn Iterator<Item = (usize, &str)>> =
                Box::new(text.lines().enumerate().flat_map(move |(i, l)| {
                    l.split_whitespace().map(move |t| (header_lines + i + 1, t))
                }));
            let mut src = Ascii {
                path,
                tokens: it.peekable(),
                line: header_lines,
            };
            read_body(&mut src, &elements, path, cap, want)
        }
        Format::Little | Format::Big => {
            let mut src = Binary {
                path,
                data: bytes,
                pos: body,
                big: format == Format::Big,
            };
            read_body(&mut src, &elements, path, cap, want)
        }
    }
}
