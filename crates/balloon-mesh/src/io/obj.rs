//! Wavefront OBJ reader.
//!
//! Hand-written rather than taken from a crate so that every error names the file and line.
//! Handles: `v x y z [w]` and `v x y z r g b` (extra values ignored); `vt`, `vn`, `vp`, `o`, `g`,
//! `s`, `usemtl`, `mtllib`, `l`, `p` and unknown statements ignored; `f` with `v`, `v/vt`, `v//vn`
//! and `v/vt/vn` corners; 1-based and negative (relative to the vertices read so far) indices;
//! polygons of any size, fan-triangulated `(0, i, i + 1)`; comments `#`; CRLF line ends.

use super::text::{line_err, parse_f64, token_lines};
use crate::{MeshError, TriMesh};
use nalgebra::Point3;
use std::path::Path;

/// Parses OBJ `bytes` (non-UTF-8 bytes are replaced); `path` is only used in error messages.
///
/// # Errors
/// [`MeshError::Parse`] naming `path` and the line: a vertex with fewer than 3 coordinates, a
/// non-numeric or non-finite coordinate, a face with fewer than 3 corners, an index that is 0,
/// not an integer or out of range, or a file without faces.
pub fn parse_obj(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    let text = String::from_utf8_lossy(super::strip_bom(bytes));
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut corners = Vec::new();
    for (line, toks) in token_lines(&text) {
        match toks[0] {
            "v" => {
                if toks.len() < 4 {
                    return Err(line_err(
                        path,
                        line,
                        format!("vertex needs 3 coordinates, found {}", toks.len() - 1),
                    ));
                }
                let x = parse_f64(path, line, toks[1], "x coordinate")?;
                let y = parse_f64(path, line, toks[2], "y coordinate")?;
                let z = parse_f64(path, line, toks[3], "z coordinate")?;
                vertices.push(Point3::new(x, y, z));
            }
            "f" | "fo" => {
                corners.clear();
                for tok in &toks[1..] {
                    let idx = tok.split('/').next().unwrap_or("");
                    let i: i64 = idx.parse().map_err(|_| {
                        line_err(
                            path,
                            line,
                            format!(
                                "face corner `{tok}` does not start with an integer vertex index"
                            ),
                        )
                    })?;
                    let n = vertices.len() as i64;
                    let resolved = if i > 0 { i - 1 } else { n + i };
                    if i == 0 || resolved < 0 || resolved >= n {
                        return Err(line_err(
                            path,
                            line,
                            format!("face index {i} is out of range ({n} vertices defined so far)"),
                        ));
                    }
                    corners.push(resolved as usize);
                }
                if corners.len() < 3 {
                    return Err(line_err(
                        path,
                        line,
                        format!("face needs at least 3 corners, found {}", corners.len()),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if triangles.is_empty() {
        let last = text.lines().count();
        return Err(line_err(
            path,
            last.max(1),
            "no faces found (empty or not an OBJ mesh)",
        ));
    }
    super::refuse_all_degenerate(path, TriMesh::new(vertices, triangles), || {
        format!("line {}", text.lines().count().max(1))
    })
}
