//! Mesh readers and writers (OBJ, OFF, PLY, STL; VTK for tetrahedral meshes).

pub mod vtk;

use crate::{MeshError, TriMesh};
use std::io::Write;
use std::path::Path;

fn io_err(path: &Path, source: std::io::Error) -> MeshError {
    MeshError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `mesh` as a Wavefront OBJ file (`v` and `f` lines, 1-based indices).
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    let file = std::fs::File::create(path).map_err(|e| io_err(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let mut run = || -> std::io::Result<()> {
        for p in &mesh.vertices {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        for t in &mesh.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        w.flush()
    };
    run().map_err(|e| io_err(path, e))
}

/// Writes `mesh` as a binary little-endian PLY file (`vertex` x, y, z as float64; `face` as a
/// uchar count and int32 indices).
pub fn write_ply_binary(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    let file = std::fs::File::create(path).map_err(|e| io_err(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let mut run = || -> std::io::Result<()> {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            mesh.vertices.len(),
            mesh.triangles.len()
        )?;
        for p in &mesh.vertices {
            for c in [p.x, p.y, p.z] {
                w.write_all(&c.to_le_bytes())?;
            }
        }
        for t in &mesh.triangles {
            w.write_all(&[3u8])?;
            for &i in t {
                w.write_all(&(i as i32).to_le_bytes())?;
            }
        }
        w.flush()
    };
    run().map_err(|e| io_err(path, e))
}
