//! STL reader (ASCII and binary) and binary writer.
//!
//! Hand-written so that errors name the file and line (ASCII) or byte offset (binary). STL
//! stores a triangle soup; the reader welds vertices with identical positions (or closer than a
//! tolerance) so that the result is an indexed mesh.
//!
//! Binary detection: a file is binary when its size is exactly `84 + 50 n` for the triangle count
//! `n` stored at bytes 80..84, even if its 80-byte header starts with `solid` (many exporters do
//! that); otherwise it is ASCII when it starts with `solid`, and an error otherwise.

use super::text::{byte_err, line_err, parse_f64};
use crate::validate::weld_vertices;
use crate::{MeshError, TriMesh};
use nalgebra::Point3;
use std::io::Write;
use std::path::Path;

fn parse_binary(bytes: &[u8], path: &Path) -> Result<Vec<Point3<f64>>, MeshError> {
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    let mut soup = Vec::with_capacity(3 * n);
    for t in 0..n {
        let base = 84 + 50 * t;
        for c in 0..3 {
            let mut p = [0.0; 3];
            for k in 0..3 {
                let o = base + 12 + 12 * c + 4 * k;
                let v = f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
                if !v.is_finite() {
                    return Err(byte_err(
                        path,
                        o,
                        format!("triangle {t} corner {c}: non-finite coordinate"),
                    ));
                }
                p[k] = v as f64;
            }
            soup.push(Point3::new(p[0], p[1], p[2]));
        }
    }
    Ok(soup)
}

fn parse_ascii(text: &str, path: &Path) -> Result<Vec<Point3<f64>>, MeshError> {
    let mut soup = Vec::new();
    let mut facet: Vec<Point3<f64>> = Vec::new();
    let mut in_facet = false;
    let mut last = 1;
    for (i, line) in text.lines().enumerate() {
        let l = i + 1;
        last = l;
        let toks: Vec<&str> = line.split_whitespace().collect();
        match toks.first().copied() {
            Some("facet") => {
                if in_facet {
                    return Err(line_err(
                        path,
                        l,
                        "`facet` inside a facet (missing `endfacet`)",
                    ));
                }
                in_facet = true;
                facet.clear();
            }
            Some("vertex") => {
                if !in_facet {
                    return Err(line_err(path, l, "`vertex` outside a facet"));
                }
                if toks.len() < 4 {
                    return Err(line_err(path, l, "vertex needs 3 coordinates"));
                }
                facet.push(Point3::new(
                    parse_f64(path, l, toks[1], "x coordinate")?,
                    parse_f64(path, l, toks[2], "y coordinate")?,
                    parse_f64(path, l, toks[3], "z coordinate")?,
                ));
            }
            Some("endfacet") => {
                if !in_facet || facet.len() < 3 {
                    return Err(line_err(
                        path,
                        l,
                        format!(
                            "facet ends with {} vertices (at least 3 needed)",
                            facet.len()
                        ),
                    ));
                }
                for j in 1..facet.len() - 1 {
                    soup.extend_from_slice(&[facet[0], facet[j], facet[j + 1]]);
                }
                in_facet = false;
            }
            _ => {}
        }
    }
    if in_facet {
        return Err(line_err(
            path,
            last,
            "unexpected end of file inside a facet",
        ));
    }
    if soup.is_empty() {
        return Err(line_err(path, last, "no facets found"));
    }
    Ok(soup)
}

/// Parses STL `bytes` (ASCII or binary, see the module doc) and welds vertices closer than
/// `weld_tolerance` (m; `0.0` welds exactly equal positions only). `path` is only used in error
/// messages.
///
/// # Errors
/// [`MeshError::Parse`] naming `path` and the line or byte offset: a binary file whose size does
/// not match its triangle count, a truncated or malformed ASCII file, a bad or non-finite number,
/// no facets.
pub fn parse_stl(bytes: &[u8], path: &Path, weld_tolerance: f64) -> Result<TriMesh, MeshError> {
    // A UTF-8 byte-order mark may precede an ASCII file; a binary file is taken as it is.
    let body = super::strip_bom(bytes);
    let starts_solid = {
        let s = body
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(body.len());
        body[s..].starts_with(b"solid")
    };
    let binary_size = (bytes.len() >= 84)
        .then(|| 84 + 50 * u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64);
    let text = std::str::from_utf8(body).ok();
    // A binary file is essentially never valid UTF-8 containing `endfacet`; an ASCII file may
    // (rarely) have a size of the form 84 + 50 n.
    let ascii = starts_solid && text.is_some_and(|t| t.contains("endfacet"));
    let soup = if ascii {
        parse_ascii(text.unwrap_or(""), path)?
    } else if binary_size == Some(bytes.len() as u64) {
        parse_binary(bytes, path)?
    } else if starts_solid && let Some(text) = text {
        parse_ascii(text, path)?
    } else if let Some(expected) = binary_size {
        return Err(byte_err(
            path,
            80,
            format!(
                "binary STL announces {} triangles ({expected} bytes) but the file has {} bytes",
                (expected - 84) / 50,
                bytes.len()
            ),
        ));
    } else {
        return Err(byte_err(
            path,
            0,
            format!("not an STL file ({} bytes, no `solid` header)", bytes.len()),
        ));
    };
    if soup.is_empty() {
        return Err(byte_err(path, 84, "binary STL has no triangles"));
    }
    let n = soup.len() / 3;
    let mesh = TriMesh::new(
        soup,
        (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    );
    let welded = weld_vertices(&mesh, weld_tolerance.max(0.0)).0;
    if welded.triangles.is_empty() {
        return Err(byte_err(
            path,
            0,
            format!(
                "all {n} facets are degenerate (corners that coincide after welding): the file \
                 describes no surface"
            ),
        ));
    }
    super::refuse_all_degenerate(path, welded, || "byte 0".to_string())
}

/// Writes the binary STL of `mesh` to `w` (80-byte header, count, per triangle the unit normal,
/// three corners as `f32` and a zero attribute word).
pub(crate) fn write_stl_to(w: &mut impl Write, mesh: &TriMesh) -> std::io::Result<()> {
    let mut header = [b' '; 80];
    header[..19].copy_from_slice(b"balloon binary STL ");
    w.write_all(&header)?;
    w.write_all(&(mesh.num_triangles() as u32).to_le_bytes())?;
    let normals = crate::geometry::face_normals(mesh);
    for (t, n) in mesh.triangles.iter().zip(normals) {
        for c in [n.x, n.y, n.z] {
            w.write_all(&(c as f32).to_le_bytes())?;
        }
        for &i in t {
            let p = mesh.vertices[i];
            for c in [p.x, p.y, p.z] {
                w.write_all(&(c as f32).to_le_bytes())?;
            }
        }
        w.write_all(&[0, 0])?;
    }
    Ok(())
}
