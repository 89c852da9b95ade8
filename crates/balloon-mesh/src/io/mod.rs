//! Mesh readers and writers (OBJ, OFF, PLY, STL; VTK for tetrahedral meshes).
//!
//! | format | read | write |
//! |---|---|---|
//! | Wavefront OBJ | [`read_obj`] | [`write_obj`] |
//! | OFF (also COFF/NOFF, Princeton benchmark quirks) | [`read_off`] | [`write_off`] |
//! | PLY ASCII / binary LE / binary BE | [`read_ply`] | [`write_ply_binary`] (LE) |
//! | STL ASCII / binary | [`read_stl`], [`read_stl_with_tolerance`] | [`write_stl_binary`] |
//!
//! [`read_mesh`] and [`write_mesh`] pick the format from the extension (case-insensitive). The
//! readers are hand-written so that every error names the file and the line (text) or byte
//! offset (binary); the `parse_*` functions read from memory. See `docs/mesh-io.md`.

mod input;
pub mod obj;
pub mod off;
pub mod ply;
pub mod pvd;
pub mod stl;
mod text;
pub mod vtk;
pub mod vtp;

pub use input::{InputFileError, MAX_TEXT_INPUT_BYTES, read_input_file, read_input_text, was_read};
pub use obj::parse_obj;
pub use off::parse_off;
pub use ply::{PlyProperty, parse_ply, parse_ply_with_property};
pub use pvd::{PvdEntry, PvdWriter, read_pvd};
pub use stl::parse_stl;
pub use vtp::{VtkEncoding, VtpArray, VtpData, read_vtp, write_vtp};

use crate::{MeshError, TriMesh};
use std::io::Write;
use std::path::Path;

fn io_err(path: &Path, source: std::io::Error) -> MeshError {
    MeshError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Largest mesh file the readers accept, bytes (1 GiB: several times the largest scanned models;
/// a larger file is refused before it is read instead of exhausting memory).
pub const MAX_MESH_FILE_BYTES: u64 = 1 << 30;

/// Reads a whole mesh file after checking what it is ([`read_input_file`]): only regular files
/// (a symlink is followed) of at most [`MAX_MESH_FILE_BYTES`] are read, so a device
/// (`/dev/zero`), a FIFO or a directory is refused by its type and a huge (or sparse) file by its
/// size, before any allocation.
fn read_bytes(path: &Path) -> Result<Vec<u8>, MeshError> {
    read_input_file(path, MAX_MESH_FILE_BYTES).map_err(|e| match e {
        InputFileError::Io { path, source } => MeshError::Io { path, source },
        InputFileError::NotAFile { path, kind } => MeshError::NotAFile { path, kind },
        InputFileError::TooLarge { path, size, limit } => {
            MeshError::FileTooLarge { path, size, limit }
        }
    })
}

fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Reads a Wavefront OBJ file (see [`obj`] for what is handled).
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    parse_obj(&read_bytes(path)?, path)
}

/// Reads an OFF file (see [`off`] for what is handled).
pub fn read_off(path: &Path) -> Result<TriMesh, MeshError> {
    parse_off(&read_bytes(path)?, path)
}

/// Reads a PLY file (see [`ply`] for what is handled).
pub fn read_ply(path: &Path) -> Result<TriMesh, MeshError> {
    parse_ply(&read_bytes(path)?, path)
}

/// Reads a PLY file and its scalar vertex or face property `name` (see
/// [`parse_ply_with_property`]).
pub fn read_ply_with_property(
    path: &Path,
    name: &str,
) -> Result<(TriMesh, PlyProperty), MeshError> {
    parse_ply_with_property(&read_bytes(path)?, path, name)
}

/// Reads an STL file, welding exactly coincident vertices (see [`stl`]).
pub fn read_stl(path: &Path) -> Result<TriMesh, MeshError> {
    parse_stl(&read_bytes(path)?, path, 0.0)
}

/// Reads an STL file, welding vertices closer than `tolerance` (m).
pub fn read_stl_with_tolerance(path: &Path, tolerance: f64) -> Result<TriMesh, MeshError> {
    parse_stl(&read_bytes(path)?, path, tolerance)
}

/// Reads a mesh, choosing the format from the extension (`.obj`, `.off`, `.ply`, `.stl`,
/// case-insensitive).
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for another extension, [`MeshError::NotAFile`] for a
/// directory or special file, [`MeshError::Io`] when the file cannot be read,
/// [`MeshError::Parse`] (file and line or byte) when it is malformed.
pub fn read_mesh(path: &Path) -> Result<TriMesh, MeshError> {
    match extension(path).as_str() {
        "obj" => read_obj(path),
        "off" => read_off(path),
        "ply" => read_ply(path),
        "stl" => read_stl(path),
        ext => {
            // A directory (`.`, `meshes/`) has no extension either: say what it is.
            if let Ok(meta) = std::fs::metadata(path)
                && !meta.is_file()
            {
                return Err(MeshError::NotAFile {
                    path: path.to_path_buf(),
                    kind: input::file_kind(&meta.file_type()),
                });
            }
            Err(MeshError::UnsupportedFormat {
                path: path.to_path_buf(),
                extension: ext.to_string(),
                supported: ".obj, .off, .ply, .stl",
            })
        }
    }
}

/// Writes a mesh, choosing the format from the extension: `.obj`, `.off`, `.ply` (binary
/// little-endian) or `.stl` (binary, `f32` coordinates).
///
/// # Errors
/// [`MeshError::UnsupportedFormat`] for another extension, [`MeshError::Io`] on write failure.
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    match extension(path).as_str() {
        "obj" => write_obj(path, mesh),
        "off" => write_off(path, mesh),
        "ply" => write_ply_binary(path, mesh),
        "stl" => write_stl_binary(path, mesh),
        ext => Err(MeshError::UnsupportedFormat {
            path: path.to_path_buf(),
            extension: ext.to_string(),
            supported: ".obj, .off, .ply, .stl",
        }),
    }
}

fn write_with(
    path: &Path,
    f: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), MeshError> {
    let file = std::fs::File::create(path).map_err(|e| io_err(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    f(&mut w)
        .and_then(|()| w.flush())
        .map_err(|e| io_err(path, e))
}

/// Writes `mesh` as a Wavefront OBJ file (`v` and `f` lines, 1-based indices).
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    write_with(path, |w| {
        for p in &mesh.vertices {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        for t in &mesh.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    })
}

/// Writes `mesh` as an OFF file (coordinates round-trip exactly).
pub fn write_off(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    write_with(path, |w| off::write_off_to(w, mesh))
}

/// Writes `mesh` as a binary STL file (triangle soup, `f32` coordinates: about 7 significant
/// digits survive).
pub fn write_stl_binary(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    write_with(path, |w| stl::write_stl_to(w, mesh))
}

/// Writes `mesh` as a binary little-endian PLY file (`vertex` x, y, z as float64; `face` as a
/// uchar count and int32 indices).
pub fn write_ply_binary(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    write_ply_binary_with_face_property(path, mesh, None)
}

/// [`write_ply_binary`] with a scalar float64 property of the faces, `(name, one value per
/// triangle)`, after the vertex indices (for example a `thickness` map, which
/// [`read_ply_with_property`] reads back).
///
/// # Errors
/// [`MeshError::InvalidParameter`] naming the property when its values are not one per
/// triangle or its name is not one word; the write's errors.
pub fn write_ply_binary_with_face_property(
    path: &Path,
    mesh: &TriMesh,
    property: Option<(&str, &[f64])>,
) -> Result<(), MeshError> {
    if let Some((name, values)) = property
        && (values.len() != mesh.triangles.len()
            || name.is_empty()
            || name.chars().any(|c| c.is_whitespace()))
    {
        return Err(MeshError::InvalidParameter {
            name: "property",
            value: format!("`{name}` ({} values)", values.len()),
            reason: format!(
                "one value per triangle ({}) and a name of one word",
                mesh.triangles.len()
            ),
        });
    }
    write_with(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\n",
            mesh.vertices.len(),
            mesh.triangles.len()
        )?;
        if let Some((name, _)) = property {
            writeln!(w, "property double {name}")?;
        }
        writeln!(w, "end_header")?;
        for p in &mesh.vertices {
            for c in [p.x, p.y, p.z] {
                w.write_all(&c.to_le_bytes())?;
            }
        }
        for (k, t) in mesh.triangles.iter().enumerate() {
            w.write_all(&[3u8])?;
            for &i in t {
                w.write_all(&(i as i32).to_le_bytes())?;
            }
            if let Some((_, values)) = property {
                w.write_all(&values[k].to_le_bytes())?;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests;

/// Longest token (run of non-space characters) shown whole in a parse message; longer ones are
/// cut to this many characters and the number of bytes left out is named.
const MAX_SHOWN_TOKEN_CHARS: usize = 48;
/// Longest parse message shown, characters (after escaping).
const MAX_SHOWN_MESSAGE_CHARS: usize = 400;

/// `message` made safe to print: control characters (escape sequences, NUL, bell, carriage
/// return) escaped as `\u{..}`, tokens longer than 48 characters cut with the byte count left
/// out, and the whole cut at 400 characters. Parse messages quote tokens from the file, which
/// may be hostile or binary.
pub(crate) fn printable(message: &str) -> String {
    let is_gap = |c: char| c.is_whitespace() && !c.is_control();
    let mut out = String::with_capacity(message.len().min(MAX_SHOWN_MESSAGE_CHARS + 32));
    let (mut shown, mut token_chars) = (0usize, 0usize);
    let mut chars = message.char_indices().peekable();
    while let Some((at, c)) = chars.next() {
        if shown >= MAX_SHOWN_MESSAGE_CHARS {
            out.push_str(&format!("...({} more bytes)", message.len() - at));
            break;
        }
        if is_gap(c) {
            token_chars = 0;
        } else {
            token_chars += 1;
        }
        if token_chars > MAX_SHOWN_TOKEN_CHARS {
            // Leave out the rest of this token.
            let mut end = message.len();
            while let Some(&(j, d)) = chars.peek() {
                if is_gap(d) {
                    end = j;
                    break;
                }
                chars.next();
            }
            out.push_str(&format!("...({} more bytes)", end - at));
            shown += 16;
            token_chars = 0;
            continue;
        }
        if c.is_control() {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
        shown += 1;
    }
    out
}

/// `bytes` without a leading UTF-8 byte-order mark (`EF BB BF`), which some Windows editors
/// write at the start of text files.
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Refuses a parsed mesh whose triangles all have zero area (repeated corners or collinear
/// points): such a file describes no surface, and reporting it as a valid mesh would hide that.
pub(crate) fn refuse_all_degenerate(
    path: &Path,
    mesh: TriMesh,
    location: impl FnOnce() -> String,
) -> Result<TriMesh, MeshError> {
    let any_area = mesh.triangles.iter().any(|t| {
        let [a, b, c] = t.map(|i| mesh.vertices[i]);
        (b - a).cross(&(c - a)).norm_squared() > 0.0
    });
    if any_area || mesh.triangles.is_empty() {
        return Ok(mesh);
    }
    Err(MeshError::Parse {
        path: path.to_path_buf(),
        location: location(),
        message: format!(
            "all {} faces have zero area (repeated or collinear corners): the file describes no \
             surface",
            mesh.num_triangles()
        ),
    })
}
