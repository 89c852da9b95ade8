//! Triangle and tetrahedral meshes for the `balloon` toolkit.
//!
//! **For:** reading the meshes users actually have (OBJ, OFF, PLY, STL), validating them with
//! errors that name the file, line and element, topology (edges, adjacency, components, genus),
//! geometry (areas, normals, enclosed volume and its gradient), procedural generators (spheres,
//! torus, box, implicit shapes, the built-in teddy) and the triangle-soup to tetrahedral-lattice
//! generator of Diziol, Bender and Bayer (Diziol, Bender and Bayer 2011, Sec. 3).
//!
//! **Not for:** physics. Nothing here knows about materials, forces or time.
//!
//! Features: `parallel` (default on) runs the lattice generator's loops on rayon and makes
//! [`parallel::prelude`] rayon's prelude; without it the same calls run sequentially with
//! identical results.
//!
//! | module | what |
//! |---|---|
//! | [`load`], [`builtin()`] | a mesh from a path, `builtin` (the teddy) or `builtin:NAME` |
//! | [`io`] | OBJ, OFF, PLY, STL readers (errors name file + line/byte) and writers |
//! | [`validate`] | [`validate::validate_closed_manifold`], defect reports, weld / orient / clean |
//! | [`topology`] | edges, CSR adjacency, one-rings, components, Euler characteristic, genus |
//! | [`geometry`] | areas, normals, enclosed volume (Wang et al. 2015, Eq. 13) and its gradient |
//! | [`fields`] | checked per-face / per-vertex fields for output: stretches, normals, speeds |
//! | [`generate`] | spheres, torus, box, implicit surfaces, the procedural teddy |
//! | [`tet`], [`lattice`] | tetrahedral meshes and the lattice generator of Diziol, Bender and Bayer 2011 |
//!
//! ```
//! let mesh = balloon_mesh::load("builtin:icosphere").unwrap();
//! balloon_mesh::validate::validate_closed_manifold(&mesh).unwrap();
//! let v = balloon_mesh::geometry::enclosed_volume(&mesh);
//! assert!((v - 4.0 / 3.0 * std::f64::consts::PI * 1e-3).abs() < 1e-5);
//! ```
//!
//! ```
//! use balloon_mesh::TriMesh;
//! use nalgebra::Point3;
//! let tet = TriMesh::new(
//!     vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0),
//!          Point3::new(0.0, 1.0, 0.0), Point3::new(0.0, 0.0, 1.0)],
//!     vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
//! );
//! assert_eq!(tet.num_triangles(), 4);
//! ```

pub mod builtin;
pub mod error;
pub mod fields;
pub mod generate;
pub mod geometry;
pub mod io;
pub mod lattice;
pub mod mesh;
pub mod parallel;
pub mod tet;
pub mod topology;
pub mod validate;

pub use builtin::{builtin, load};
pub use error::MeshError;
pub use mesh::TriMesh;
pub use tet::TetMesh;
