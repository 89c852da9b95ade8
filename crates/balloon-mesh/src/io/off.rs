//! Object File Format (OFF) reader and writer.
//!
//! Hand-written so that every error names the file and line. Handles OFF as the Princeton shape
//! benchmark and ModelNet write it: the header keyword `OFF` (also `COFF`, `NOFF`, `CNOFF`,
//! `STOFF`, ...) optionally followed on the same line by the counts, or glued to them
//! (`OFF490 518 0`); comments `#`; blank lines; counts `V F [E]`; vertex lines whose values after
//! `x y z` (colours, normals, texture coordinates) are ignored; faces `n i_1 ... i_n [colour]`
//! of any size `n >= 3`, fan-triangulated; 0-based indices. Lines after the last face are
//! ignored.

use super::text::{line_err, parse_f64, parse_usize, token_lines};
use crate::{MeshError, TriMesh};
use nalgebra::Point3;
use std::io::Write;
use std::path::Path;

/// Parses OFF `bytes`; `path` is only used in error messages.
///
/// # Errors
/// [`MeshError::Parse`] naming `path` and the line: a missing header, bad counts, a truncated
/// file (fewer vertices or faces than the header announces), a bad number, a face with fewer
/// than 3 corners or an index out of range.
pub fn parse_off(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    let text = String::from_utf8_lossy(super::strip_bom(bytes));
    let mut lines = token_lines(&text);
    let Some((hline, htoks)) = lines.next() else {
        return Err(line_err(path, 1, "empty file: expected an `OFF` header"));
    };
    let head = htoks[0];
    let kw_len = head
        .find(|c: char| c.is_ascii_digit())
        .unwrap_or(head.len());
    let (kw, glued) = head.split_at(kw_len);
    if !kw.ends_with("OFF") || !kw.chars().all(|c| c.is_ascii_uppercase()) || kw.starts_with('4') {
        return Err(line_err(
            path,
            hline,
            format!("expected an `OFF` header, found `{head}`"),
        ));
    }
    let mut counts: Vec<(usize, &str)> = Vec::new();
    if !glued.is_empty() {
        counts.push((hline, glued));
    }
    counts.extend(htoks[1..].iter().map(|t| (hline, *t)));
    let mut last_line = hline;
    while counts.is_empty() {
        let Some((l, toks)) = lines.next() else {
            return Err(line_err(
                path,
                last_line,
                "unexpected end of file: expected the counts `V F E`",
            ));
        };
        last_line = l;
        counts.extend(toks.into_iter().map(|t| (l, t)));
    }
    if counts.len() < 2 {
        return Err(line_err(
            path,
            counts[0].0,
            "expected the counts `V F E` (at least V and F)",
        ));
    }
    let nv = parse_usize(path, counts[0].0, counts[0].1, "vertex count")?;
    let nf = parse_usize(path, counts[1].0, counts[1].1, "face count")?;
    let cap = bytes.len() / 4 + 1;
    let mut vertices = Vec::with_capacity(nv.min(cap));
    for k in 0..nv {
        let Some((l, toks)) = lines.next() else {
            return Err(line_err(
                path,
                last_line,
                format!("unexpected end of file: expected vertex {k} of {nv}"),
            ));
        };
        last_line = l;
        if toks.len() < 3 {
            return Err(line_err(
                path,
                l,
                format!("vertex {k} needs 3 coordinates, found {}", toks.len()),
            ));
        }
        let x = parse_f64(path, l, toks[0], "x coordinate")?;
        let y = parse_f64(path, l, toks[1], "y coordinate")?;
        let z = parse_f64(path, l, toks[2], "z coordinate")?;
        vertices.push(Point3::new(x, y, z));
    }
    let mut triangles = Vec::with_capacity(nf.min(cap));
    let mut corners = Vec::new();
    for k in 0..nf {
        let Some((l, toks)) = lines.next() else {
            return Err(line_err(
                path,
                last_line,
                format!("unexpected end of file: expected face {k} of {nf}"),
            ));
        };
        last_line = l;
        let n = parse_usize(path, l, toks[0], "face size")?;
        if n < 3 {
            return Err(line_err(
                path,
                l,
                format!("face {k} has {n} corners (at least 3 needed)"),
            ));
        }
        if n > toks.len() - 1 {
            return Err(line_err(
                path,
                l,
                format!(
                    "face {k} announces {n} corners but lists {}",
                    toks.len() - 1
                ),
            ));
        }
        corners.clear();
        for tok in &toks[1..=n] {
            let i = parse_usize(path, l, tok, "vertex index")?;
            if i >= nv {
                return Err(line_err(
                    path,
                    l,
                    format!("face {k}: vertex index {i} out of range ({nv} vertices)"),
                ));
            }
            corners.push(i);
        }
        for j in 1..n - 1 {
            triangles.push([corners[0], corners[j], corners[j + 1]]);
        }
    }
    if triangles.is_empty() {
        return Err(line_err(path, last_line, "no faces found"));
    }
    super::refuse_all_degenerate(path, TriMesh::new(vertices, triangles), || {
        format!("line {last_line}")
    })
}

/// Writes the OFF text of `mesh` to `w` (`OFF`, counts, `x y z` lines, `3 a b c` lines; values
/// printed with Rust's shortest round-trip formatting, so reading back gives identical floats).
pub(crate) fn write_off_to(w: &mut impl Write, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(w, "OFF")?;
    writeln!(w, "{} {} 0", mesh.num_vertices(), mesh.num_triangles())?;
    for p in &mesh.vertices {
        writeln!(w, "{:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    for t in &mesh.triangles {
        writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
    }
    Ok(())
}
