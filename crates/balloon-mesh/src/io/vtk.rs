//! Legacy VTK (ASCII, version 3.0) unstructured-grid writer for tetrahedral meshes, with optional
//! per-cell and per-point scalar fields. ParaView, VisIt and `meshio` open these files.
//!
//! ```
//! use balloon_mesh::{TetMesh, io::vtk::write_tet_vtk_to};
//! use nalgebra::Point3;
//! let mesh = TetMesh::new(
//!     vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)],
//!     vec![[0, 1, 2, 3]],
//! );
//! let mut out = Vec::new();
//! write_tet_vtk_to(&mut out, &mesh, &[("volume", &[1.0 / 6.0])], &[]).unwrap();
//! assert!(String::from_utf8(out).unwrap().contains("CELL_TYPES 1\n10\n"));
//! ```

use crate::{MeshError, TetMesh};
use std::io::Write;
use std::path::Path;

/// VTK cell type of a linear tetrahedron.
pub const VTK_TETRA: u8 = 10;

fn check_fields(
    fields: &[(&str, &[f64])],
    expected: usize,
    what: &'static str,
) -> Result<(), MeshError> {
    for (name, values) in fields {
        if name.is_empty() || name.chars().any(|c| c.is_whitespace()) {
            return Err(MeshError::InvalidParameter {
                name: what,
                value: format!("{name:?}"),
                reason: "a VTK field name must be non-empty without whitespace".into(),
            });
        }
        if values.len() != expected {
            return Err(MeshError::InvalidParameter {
                name: what,
                value: format!("{name} ({} values)", values.len()),
                reason: format!("expected {expected} values"),
            });
        }
    }
    Ok(())
}

/// Writes `mesh` as a legacy VTK unstructured grid to `w`.
///
/// * `cell_scalars`: `(name, values)` with one value per tetrahedron (`CELL_DATA`);
/// * `point_scalars`: `(name, values)` with one value per vertex (`POINT_DATA`).
///
/// Names must be non-empty without whitespace; a wrong length or name, or a tetrahedron index out
/// of range, is an [`MeshError::InvalidParameter`] naming the field or tetrahedron.
pub fn write_tet_vtk_to<W: Write>(
    mut w: W,
    mesh: &TetMesh,
    cell_scalars: &[(&str, &[f64])],
    point_scalars: &[(&str, &[f64])],
) -> Result<(), MeshError> {
    check_fields(cell_scalars, mesh.tets.len(), "cell_scalars")?;
    check_fields(point_scalars, mesh.vertices.len(), "point_scalars")?;
    for (t, tet) in mesh.tets.iter().enumerate() {
        if let Some(&bad) = tet.iter().find(|&&i| i >= mesh.vertices.len()) {
            return Err(MeshError::InvalidParameter {
                name: "tets",
                value: format!("tetrahedron {t} vertex {bad}"),
                reason: format!("the mesh has {} vertices", mesh.vertices.len()),
            });
        }
    }
    let io = |e: std::io::Error| MeshError::Io {
        path: "<vtk stream>".into(),
        source: e,
    };
    let mut run = || -> std::io::Result<()> {
        writeln!(w, "# vtk DataFile Version 3.0")?;
        writeln!(w, "balloon tetrahedral mesh")?;
        writeln!(w, "ASCII")?;
        writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
        writeln!(w, "POINTS {} double", mesh.vertices.len())?;
        for p in &mesh.vertices {
            writeln!(w, "{} {} {}", p.x, p.y, p.z)?;
        }
        writeln!(w, "CELLS {} {}", mesh.tets.len(), 5 * mesh.tets.len())?;
        for t in &mesh.tets {
            writeln!(w, "4 {} {} {} {}", t[0], t[1], t[2], t[3])?;
        }
        writeln!(w, "CELL_TYPES {}", mesh.tets.len())?;
        for _ in &mesh.tets {
            writeln!(w, "{VTK_TETRA}")?;
        }
        for (header, fields, n) in [
            ("CELL_DATA", cell_scalars, mesh.tets.len()),
            ("POINT_DATA", point_scalars, mesh.vertices.len()),
        ] {
            if fields.is_empty() {
                continue;
            }
            writeln!(w, "{header} {n}")?;
            for (name, values) in fields {
                writeln!(w, "SCALARS {name} double 1")?;
                writeln!(w, "LOOKUP_TABLE default")?;
                for v in *values {
                    writeln!(w, "{v}")?;
                }
            }
        }
        w.flush()
    };
    run().map_err(io)
}

/// Writes `mesh` as a legacy VTK file at `path` (see [`write_tet_vtk_to`]); I/O errors name the
/// path.
pub fn write_tet_vtk(
    path: &Path,
    mesh: &TetMesh,
    cell_scalars: &[(&str, &[f64])],
    point_scalars: &[(&str, &[f64])],
) -> Result<(), MeshError> {
    let file = std::fs::File::create(path).map_err(|e| MeshError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    write_tet_vtk_to(
        std::io::BufWriter::new(file),
        mesh,
        cell_scalars,
        point_scalars,
    )
    .map_err(|e| match e {
        MeshError::Io { source, .. } => MeshError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => other,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn two_tets() -> TetMesh {
        TetMesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
                Point3::new(1.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2, 3], [1, 2, 3, 4]],
        )
    }

    #[test]
    fn written_file_parses_back_to_the_same_mesh_and_fields() {
        let mesh = two_tets();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtk");
        write_tet_vtk(
            &path,
            &mesh,
            &[("volume_error", &[0.5, -1.25])],
            &[("speed", &[0.0, 1.0, 2.0, 3.0, 4.5])],
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[4], "POINTS 5 double");
        let pts: Vec<f64> = lines[5..10]
            .iter()
            .flat_map(|l| l.split_whitespace().map(|s| s.parse::<f64>().unwrap()))
            .collect();
        let flat: Vec<f64> = mesh.vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        assert_eq!(pts, flat);
        assert_eq!(lines[10], "CELLS 2 10");
        assert_eq!(lines[12], "4 1 2 3 4");
        assert_eq!(lines[13], "CELL_TYPES 2");
        let cd = lines.iter().position(|l| *l == "CELL_DATA 2").unwrap();
        assert_eq!(lines[cd + 1], "SCALARS volume_error double 1");
        assert_eq!(lines[cd + 4].parse::<f64>().unwrap(), -1.25);
        let pd = lines.iter().position(|l| *l == "POINT_DATA 5").unwrap();
        assert_eq!(lines[pd + 7].parse::<f64>().unwrap(), 4.5);
    }

    #[test]
    fn bad_fields_and_paths_are_named() {
        let mesh = two_tets();
        let e = write_tet_vtk_to(Vec::new(), &mesh, &[("v", &[1.0])], &[]).unwrap_err();
        assert!(e.to_string().contains("cell_scalars"), "{e}");
        let e = write_tet_vtk_to(Vec::new(), &mesh, &[], &[("a b", &[0.0; 5])]).unwrap_err();
        assert!(e.to_string().contains("point_scalars"), "{e}");
        let mut broken = mesh.clone();
        broken.tets[1][3] = 9;
        let e = write_tet_vtk_to(Vec::new(), &broken, &[], &[]).unwrap_err();
        assert!(e.to_string().contains("tetrahedron 1"), "{e}");
        let e = write_tet_vtk(Path::new("/nonexistent/dir/m.vtk"), &mesh, &[], &[]).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/dir/m.vtk"), "{e}");
    }
}
