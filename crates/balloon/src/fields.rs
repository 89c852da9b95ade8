//! Derived per-face and per-vertex fields of a triangle surface, for output and display: the
//! geometric fields of [`balloon_mesh::fields`] (stretches, normals, speeds, face -> vertex
//! averaging) and the per-vertex gas pressure force of [`balloon_gas::vertex_pressure_forces`],
//! gathered under one path for the CLI, the viewer and `xtask`.
//!
//! ```
//! use balloon::fields::{face_area_stretch, face_max_stretch};
//! let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
//! let x: Vec<f64> = rest.iter().map(|c| 2.0 * c).collect();
//! let tris = [[0, 1, 2]];
//! assert!((face_area_stretch(&rest, &x, &tris).unwrap()[0] - 2.0).abs() < 1e-12);
//! assert!((face_max_stretch(&rest, &x, &tris).unwrap()[0] - 2.0).abs() < 1e-12);
//! ```

pub use balloon_gas::vertex_pressure_forces as pressure_forces;
pub use balloon_mesh::fields::{
    FieldError, face_area_stretch, face_area_stretch_or_nan, face_areas, face_max_stretch,
    face_max_stretch_or_nan, face_to_vertex, vertex_area_normal_sums, vertex_normals,
    vertex_speeds,
};
