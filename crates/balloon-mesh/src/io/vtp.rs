//! VTK XML PolyData (`.vtp`): a triangle surface with named point and cell data arrays, the
//! frame format ParaView reads natively (pair it with a [`crate::io::pvd`] time series).
//!
//! Written: `Points` (Float64 x 3), `Polys` (Int64 `connectivity` and `offsets`), or `Verts`
//! (one per point) when there are no triangles, and Float64 `DataArray`s of 1 (scalars) or 3
//! (vectors) components under `PointData` and `CellData`. Two encodings: [`VtkEncoding::Ascii`]
//! (numbers in their shortest round-trip form, so values read back exactly) and
//! [`VtkEncoding::Base64`] (VTK's inline `binary` format: base64 of a UInt64 byte count followed
//! by the little-endian values). Files are written to a temporary name and renamed.
//!
//! [`read_vtp`] parses exactly what [`write_vtp`] writes (both encodings) for tests and tools; it
//! is not a general VTK reader.

use crate::MeshError;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Encoding of the data arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VtkEncoding {
    /// Human-readable decimal numbers.
    Ascii,
    /// Inline base64 binary (about 3x smaller, faster to read).
    #[default]
    Base64,
}

/// A named data array to attach to points or cells: `components` values per point / cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtpArray<'a> {
    /// Array name shown in ParaView.
    pub name: &'a str,
    /// Values per tuple: 1 (scalar) or 3 (vector).
    pub components: usize,
    /// Flat values, `components` per tuple.
    pub values: &'a [f64],
}

impl<'a> VtpArray<'a> {
    /// One value per tuple.
    pub fn scalars(name: &'a str, values: &'a [f64]) -> Self {
        Self {
            name,
            components: 1,
            values,
        }
    }

    /// Three values per tuple (flat `[x0, y0, z0, x1, ...]`).
    pub fn vectors(name: &'a str, values: &'a [f64]) -> Self {
        Self {
            name,
            components: 3,
            values,
        }
    }
}

fn invalid(name: &'static str, value: impl ToString, reason: impl Into<String>) -> MeshError {
    MeshError::InvalidParameter {
        name,
        value: value.to_string(),
        reason: reason.into(),
    }
}

fn check_arrays(
    kind: &'static str,
    arrays: &[VtpArray<'_>],
    tuples: usize,
) -> Result<(), MeshError> {
    for a in arrays {
        if a.components != 1 && a.components != 3 {
            return Err(invalid(
                kind,
                a.name,
                format!("{} components; use 1 or 3", a.components),
            ));
        }
        if a.values.len() != a.components * tuples {
            return Err(invalid(
                kind,
                a.name,
                format!(
                    "{} values, expected {} ({} per tuple x {tuples})",
                    a.values.len(),
                    a.components * tuples,
                    a.components
                ),
            ));
        }
        if a.name.is_empty() || a.name.contains(['"', '<', '>', '&']) {
            return Err(invalid(
                kind,
                a.name,
                "array names must be non-empty without quotes, <, > or &",
            ));
        }
    }
    Ok(())
}

/// The `.vtp` document text. `positions`: flat (3 per point); `triangles`: vertex indices;
/// `point_data` / `cell_data`: arrays with one tuple per point / per triangle. With no
/// triangles the points are written as vertex cells and `cell_data` must be empty.
pub fn vtp_string(
    positions: &[f64],
    triangles: &[[usize; 3]],
    point_data: &[VtpArray<'_>],
    cell_data: &[VtpArray<'_>],
    encoding: VtkEncoding,
) -> Result<String, MeshError> {
    if !positions.len().is_multiple_of(3) {
        return Err(invalid(
            "positions",
            positions.len(),
            "length must be a multiple of 3",
        ));
    }
    let n = positions.len() / 3;
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v >= n) {
            return Err(invalid(
                "triangles",
                format!("triangle {t}"),
                format!("refers to vertex {v}, but there are only {n} vertices"),
            ));
        }
    }
    check_arrays("point_data", point_data, n)?;
    if triangles.is_empty() && !cell_data.is_empty() {
        return Err(invalid(
            "cell_data",
            cell_data[0].name,
            "cell data needs triangles",
        ));
    }
    check_arrays("cell_data", cell_data, triangles.len())?;
    let mut s = String::with_capacity(64 * n + 32 * triangles.len() + 1024);
    s.push_str("<?xml version=\"1.0\"?>\n");
    s.push_str("<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n");
    s.push_str("  <PolyData>\n");
    let (verts, polys) = if triangles.is_empty() {
        (n, 0)
    } else {
        (0, triangles.len())
    };
    let _ = writeln!(
        s,
        "    <Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"{verts}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{polys}\">"
    );
    for (tag, arrays) in [("PointData", point_data), ("CellData", cell_data)] {
        let scalars = arrays.iter().find(|a| a.components == 1).map(|a| a.name);
        let vectors = arrays.iter().find(|a| a.components == 3).map(|a| a.name);
        let _ = write!(s, "      <{tag}");
        if let Some(name) = scalars {
            let _ = write!(s, " Scalars=\"{name}\"");
        }
        if let Some(name) = vectors {
            let _ = write!(s, " Vectors=\"{name}\"");
        }
        s.push_str(">\n");
        for a in arrays {
            float_array(&mut s, Some(a.name), a.components, a.values, encoding);
        }
        let _ = writeln!(s, "      </{tag}>");
    }
    s.push_str("      <Points>\n");
    float_array(&mut s, None, 3, positions, encoding);
    s.push_str("      </Points>\n");
    let (tag, connectivity, offsets): (&str, Vec<i64>, Vec<i64>) = if triangles.is_empty() {
        ("Verts", (0..n as i64).collect(), (1..=n as i64).collect())
    } else {
        (
            "Polys",
            triangles.iter().flatten().map(|&v| v as i64).collect(),
            (1..=triangles.len() as i64).map(|k| 3 * k).collect(),
        )
    };
    let _ = writeln!(s, "      <{tag}>");
    int_array(&mut s, "connectivity", &connectivity, encoding);
    int_array(&mut s, "offsets", &offsets, encoding);
    let _ = writeln!(s, "      </{tag}>");
    s.push_str("    </Piece>\n  </PolyData>\n</VTKFile>\n");
    Ok(s)
}

fn float_array(
    s: &mut String,
    name: Option<&str>,
    components: usize,
    values: &[f64],
    encoding: VtkEncoding,
) {
    let _ = write!(s, "        <DataArray type=\"Float64\"");
    if let Some(name) = name {
        let _ = write!(s, " Name=\"{name}\"");
    }
    let _ = write!(s, " NumberOfComponents=\"{components}\"");
    // `{:?}` prints the shortest text that reads back to the same f64.
    array_body(s, values, components.max(1) * 4, encoding, |s, v| {
        let _ = write!(s, "{v:?}");
    });
}

fn int_array(s: &mut String, name: &str, values: &[i64], encoding: VtkEncoding) {
    let _ = write!(s, "        <DataArray type=\"Int64\" Name=\"{name}\"");
    array_body(s, values, 12, encoding, |s, v| {
        let _ = write!(s, "{v}");
    });
}

/// An 8-byte number a `DataArray` holds (Float64 or Int64).
trait Word: Copy {
    fn le_bytes(self) -> [u8; 8];
}

impl Word for f64 {
    fn le_bytes(self) -> [u8; 8] {
        self.to_le_bytes()
    }
}

impl Word for i64 {
    fn le_bytes(self) -> [u8; 8] {
        self.to_le_bytes()
    }
}

/// The rest of a `DataArray` start tag, its values (ASCII `per_line` to a line, or base64 of a
/// UInt64 byte count followed by the little-endian values) and the end tag.
fn array_body<T: Word>(
    s: &mut String,
    values: &[T],
    per_line: usize,
    encoding: VtkEncoding,
    ascii: impl Fn(&mut String, T),
) {
    match encoding {
        VtkEncoding::Ascii => {
            s.push_str(" format=\"ascii\">\n");
            for chunk in values.chunks(per_line) {
                s.push_str("          ");
                for (i, &v) in chunk.iter().enumerate() {
                    if i > 0 {
                        s.push(' ');
                    }
                    ascii(s, v);
                }
                s.push('\n');
            }
        }
        VtkEncoding::Base64 => {
            s.push_str(" format=\"binary\">\n          ");
            let mut bytes = Vec::with_capacity(8 + 8 * values.len());
            bytes.extend_from_slice(&(8 * values.len() as u64).to_le_bytes());
            for &v in values {
                bytes.extend_from_slice(&v.le_bytes());
            }
            base64_encode(&bytes, s);
            s.push('\n');
        }
    }
    s.push_str("        </DataArray>\n");
}

/// Writes [`vtp_string`] to `path` (temporary file, then rename).
pub fn write_vtp(
    path: &Path,
    positions: &[f64],
    triangles: &[[usize; 3]],
    point_data: &[VtpArray<'_>],
    cell_data: &[VtpArray<'_>],
    encoding: VtkEncoding,
) -> Result<(), MeshError> {
    let text = vtp_string(positions, triangles, point_data, cell_data, encoding)?;
    write_atomic(path, text.as_bytes())
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename; errors
/// name `path` and leave no temporary file.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    // On any failure (disk full, a folder where the file should be) the temporary file is
    // removed, so a failed write leaves nothing behind.
    let result = std::fs::write(&tmp, bytes)
        .map_err(|e| super::io_err(path, e))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| super::io_err(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

fn base64_encode(bytes: &[u8], out: &mut String) {
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let v = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(B64[((v >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
}

fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let mut acc = 0u32;
    let mut bits = 0;
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            b'=' | b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// A `.vtp` file read back by [`read_vtp`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VtpData {
    /// Flat point coordinates.
    pub positions: Vec<f64>,
    /// Triangles (empty when the file has vertex cells only).
    pub triangles: Vec<[usize; 3]>,
    /// Point data: name -> (components, flat values).
    pub point_data: BTreeMap<String, (usize, Vec<f64>)>,
    /// Cell data: name -> (components, flat values).
    pub cell_data: BTreeMap<String, (usize, Vec<f64>)>,
}

fn attr<'a>(tag: &'a str, key: &str) -> Option<&'a str> {
    let pat = format!(" {key}=\"");
    let start = tag.find(&pat)? + pat.len();
    let end = tag[start..].find('"')? + start;
    Some(&tag[start..end])
}

/// Parses a `.vtp` written by [`write_vtp`] (either encoding). Errors name the file and the
/// line of the offending `DataArray`.
pub fn parse_vtp(text: &str, path: &Path) -> Result<VtpData, MeshError> {
    let err = |pos: usize, message: String| MeshError::Parse {
        path: path.to_path_buf(),
        location: format!("line {}", text[..pos].matches('\n').count() + 1),
        message,
    };
    if !text.contains("<VTKFile type=\"PolyData\"") {
        return Err(err(0, "not a VTK XML PolyData file".into()));
    }
    let mut data = VtpData::default();
    let mut connectivity = Vec::new();
    let mut offsets = Vec::new();
    let mut has_polys = false;
    let mut pos = 0;
    while let Some(off) = text[pos..].find("<DataArray") {
        let start = pos + off;
        let tag_end = text[start..]
            .find('>')
            .map(|e| start + e)
            .ok_or_else(|| err(start, "unterminated DataArray tag".into()))?;
        let tag = &text[start..tag_end];
        let body_end = text[tag_end..]
            .find("</DataArray>")
            .map(|e| tag_end + e)
            .ok_or_else(|| err(start, "DataArray without </DataArray>".into()))?;
        let body = &text[tag_end + 1..body_end];
        pos = body_end;
        // The section is the last one opened before this array.
        let before = &text[..start];
        let section = ["<PointData", "<CellData", "<Points", "<Polys", "<Verts"]
            .iter()
            .filter_map(|s| before.rfind(s).map(|p| (p, *s)))
            .max()
            .map(|(_, s)| s)
            .ok_or_else(|| err(start, "DataArray outside any section".into()))?;
        let ty = attr(tag, "type").unwrap_or("");
        let format = attr(tag, "format").unwrap_or("ascii");
        let comps: usize = attr(tag, "NumberOfComponents")
            .unwrap_or("1")
            .parse()
            .map_err(|_| err(start, "bad NumberOfComponents".into()))?;
        let values: Vec<f64> = match (format, ty) {
            ("ascii", _) => body
                .split_ascii_whitespace()
                .map(|w| w.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| err(start, format!("bad number: {e}")))?,
            ("binary", "Float64" | "Int64") => {
                let bytes =
                    base64_decode(body).ok_or_else(|| err(start, "invalid base64 data".into()))?;
                if bytes.len() < 8 {
                    return Err(err(start, "binary data shorter than its header".into()));
                }
                let len = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
                if bytes.len() != 8 + len || !len.is_multiple_of(8) {
                    return Err(err(
                        start,
                        format!("header says {len} bytes, found {}", bytes.len() - 8),
                    ));
                }
                bytes[8..]
                    .chunks_exact(8)
                    .map(|c| {
                        let a: [u8; 8] = c.try_into().expect("8 bytes");
                        if ty == "Float64" {
                            f64::from_le_bytes(a)
                        } else {
                            i64::from_le_bytes(a) as f64
                        }
                    })
                    .collect()
            }
            _ => return Err(err(start, format!("unsupported DataArray {ty} / {format}"))),
        };
        if !values.len().is_multiple_of(comps.max(1)) {
            return Err(err(
                start,
                "value count is not a multiple of the components".into(),
            ));
        }
        let name = attr(tag, "Name").unwrap_or("").to_string();
        match section {
            "<PointData" => {
                data.point_data.insert(name, (comps, values));
            }
            "<CellData" => {
                data.cell_data.insert(name, (comps, values));
            }
            "<Points" => data.positions = values,
            _ => {
                has_polys |= section == "<Polys";
                match name.as_str() {
                    "connectivity" => connectivity = values,
                    "offsets" => offsets = values,
                    _ => {}
                }
            }
        }
    }
    if has_polys {
        let mut prev = 0usize;
        for &o in &offsets {
            let o = o as usize;
            if o != prev + 3 || o > connectivity.len() {
                return Err(err(0, "only triangles are supported".into()));
            }
            data.triangles.push([
                connectivity[prev] as usize,
                connectivity[prev + 1] as usize,
                connectivity[prev + 2] as usize,
            ]);
            prev = o;
        }
    }
    Ok(data)
}

/// Reads a `.vtp` file written by [`write_vtp`].
pub fn read_vtp(path: &Path) -> Result<VtpData, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|e| super::io_err(path, e))?;
    parse_vtp(&text, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips() {
        for n in 0usize..10 {
            let bytes: Vec<u8> = (0..n).map(|i| (i * 37 + 5) as u8).collect();
            let mut s = String::new();
            base64_encode(&bytes, &mut s);
            assert_eq!(s.len(), 4 * n.div_ceil(3));
            assert_eq!(base64_decode(&s).unwrap(), bytes);
        }
        let mut s = String::new();
        base64_encode(b"Man", &mut s);
        assert_eq!(s, "TWFu");
        assert!(base64_decode("ab$c").is_none());
    }

    #[test]
    fn both_encodings_read_back_exactly() {
        let x = [
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.1,
            0.2,
            1.0 / 3.0,
        ];
        let tris = [[0, 1, 2], [0, 2, 3]];
        let v = [
            1.5,
            -2.0,
            1e-300,
            0.0,
            0.0,
            0.0,
            7.0,
            8.0,
            9.0,
            -1.0,
            f64::MAX,
            3.0,
        ];
        let th = [3e-4, 2.5e-4];
        for enc in [VtkEncoding::Ascii, VtkEncoding::Base64] {
            let s = vtp_string(
                &x,
                &tris,
                &[
                    VtpArray::vectors("velocity", &v),
                    VtpArray::scalars("id", &[0.0, 1.0, 2.0, 3.0]),
                ],
                &[VtpArray::scalars("thickness", &th)],
                enc,
            )
            .unwrap();
            let d = parse_vtp(&s, Path::new("t.vtp")).unwrap();
            assert_eq!(d.positions, x);
            assert_eq!(d.triangles, tris);
            assert_eq!(d.point_data["velocity"], (3, v.to_vec()));
            assert_eq!(d.point_data["id"].1, vec![0.0, 1.0, 2.0, 3.0]);
            assert_eq!(d.cell_data["thickness"], (1, th.to_vec()));
        }
        // Points only: vertex cells.
        let s = vtp_string(&x, &[], &[], &[], VtkEncoding::Ascii).unwrap();
        assert!(s.contains("NumberOfVerts=\"4\"") && s.contains("<Verts>"));
        assert!(
            parse_vtp(&s, Path::new("p.vtp"))
                .unwrap()
                .triangles
                .is_empty()
        );
    }

    #[test]
    fn bad_input_is_named() {
        let x = [0.0; 9];
        let e = vtp_string(&x, &[[0, 1, 3]], &[], &[], VtkEncoding::Ascii).unwrap_err();
        assert!(e.to_string().contains("vertex 3"), "{e}");
        let e = vtp_string(
            &x,
            &[[0, 1, 2]],
            &[VtpArray::vectors("velocity", &[0.0; 6])],
            &[],
            VtkEncoding::Ascii,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("velocity") && e.to_string().contains("expected 9"),
            "{e}"
        );
        let e = vtp_string(
            &x,
            &[],
            &[],
            &[VtpArray::scalars("t", &[])],
            VtkEncoding::Ascii,
        )
        .unwrap_err();
        assert!(e.to_string().contains("needs triangles"), "{e}");
        let good = vtp_string(&x, &[[0, 1, 2]], &[], &[], VtkEncoding::Base64).unwrap();
        let broken = good.replacen(
            "format=\"binary\">\n          ",
            "format=\"binary\">\n          AAAA",
            1,
        );
        let e = parse_vtp(&broken, Path::new("b.vtp")).unwrap_err();
        assert!(e.to_string().starts_with("b.vtp:line "), "{e}");
    }
}
