//! The `[mesh]` table: a mesh file or a built-in mesh, scaled to metres and moved by an affine
//! map.
//!
//! ```
//! use balloon_scenario::mesh::MeshSpec;
//! let spec = MeshSpec {
//!     path: "builtin:icosphere".into(),
//!     scale: 2.0,
//!     transform: Some(vec![1.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
//! };
//! let mesh = spec.load().unwrap();
//! let x: Vec<f64> = mesh.vertices.iter().map(|p| p.x).collect();
//! let mid = (x.iter().copied().fold(f64::INFINITY, f64::min)
//!     + x.iter().copied().fold(f64::NEG_INFINITY, f64::max)) / 2.0;
//! assert!((mid - 0.5).abs() < 1e-12); // centred on x = 0.5 after the map
//! ```

use balloon::mesh::{MeshError, TriMesh};
use serde::{Deserialize, Serialize};

/// Number of values of `transform`: a 3x4 matrix.
pub const TRANSFORM_LEN: usize = 12;

/// The `[mesh]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeshSpec {
    /// A mesh file (.obj, .off, .ply, .stl) or `builtin[:NAME]`.
    pub path: String,
    /// Multiply mesh coordinates by this factor (mesh units -> metres).
    pub scale: f64,
    /// Affine map applied after `scale`: a 3x4 matrix row by row, `x -> A x + t` (m).
    pub transform: Option<Vec<f64>>,
}

impl Default for MeshSpec {
    fn default() -> Self {
        Self {
            path: "builtin".into(),
            scale: 1.0,
            transform: None,
        }
    }
}

/// A mesh that cannot be loaded or placed.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file cannot be read, or the built-in mesh does not exist.
    #[error("cannot load mesh `{path}`")]
    Read {
        /// The mesh's path or built-in name.
        path: String,
        /// Why.
        #[source]
        source: MeshError,
    },
    /// `transform` is not a valid map (the message names it).
    #[error("{0}")]
    Transform(String),
}

impl MeshSpec {
    /// The mesh read from `path`, not scaled nor moved.
    pub fn read(&self) -> Result<TriMesh, LoadError> {
        balloon::mesh::load(&self.path).map_err(|source| LoadError::Read {
            path: self.path.clone(),
            source,
        })
    }

    /// The mesh read, scaled and moved ([`MeshSpec::place`]).
    pub fn load(&self) -> Result<TriMesh, LoadError> {
        let mut mesh = self.read()?;
        self.place(&mut mesh).map_err(LoadError::Transform)?;
        Ok(mesh)
    }

    /// Scales `mesh` by `scale` (when it is not 1) and applies `transform`; an invalid
    /// `transform` is an error naming it ([`MeshSpec::check_transform`]).
    pub fn place(&self, mesh: &mut TriMesh) -> Result<(), String> {
        if self.scale != 1.0 {
            mesh.scale(self.scale);
        }
        match &self.transform {
            Some(t) => apply_transform(mesh, t),
            None => Ok(()),
        }
    }

    /// `transform` has 12 numbers and keeps the orientation.
    pub fn check_transform(&self) -> Result<(), String> {
        match &self.transform {
            Some(t) => affine(t).map(drop),
            None => Ok(()),
        }
    }
}

/// The matrix `A` and vector `t` of a 3x4 map, checked.
fn affine(m: &[f64]) -> Result<(nalgebra::Matrix3<f64>, nalgebra::Vector3<f64>), String> {
    if m.len() != TRANSFORM_LEN {
        return Err(format!(
            "`transform` takes {TRANSFORM_LEN} numbers (a 3x4 matrix, row by row: A | t), \
             found {}",
            m.len()
        ));
    }
    let a = nalgebra::Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let t = nalgebra::Vector3::new(m[3], m[7], m[11]);
    let det = a.determinant();
    if !(det.is_finite() && det > 0.0) {
        return Err(format!(
            "`transform`: the 3x3 part has determinant {det:e}; it must be positive (a \
             rotation, scaling or shear keeping the orientation, not a mirror)"
        ));
    }
    Ok((a, t))
}

/// Applies an affine map to `mesh`: the 12 numbers are a 3x4 matrix written row by row,
/// `[a11, a12, a13, t1, a21, a22, a23, t2, a31, a32, a33, t3]`, mapping each vertex `x` to
/// `A x + t` (m). `A` must keep the orientation (determinant > 0), so that closed surfaces keep
/// their outward normals and positive volumes; a rotation by an angle `q` about z is
/// `[cos q, -sin q, 0, tx, sin q, cos q, 0, ty, 0, 0, 1, tz]`, a translation
/// `[1, 0, 0, tx, 0, 1, 0, ty, 0, 0, 1, tz]`.
///
/// ```
/// let mut mesh = balloon::mesh::generate::icosphere(1.0, 1).unwrap();
/// let before = mesh.vertices[3];
/// let t = [1.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, -2.0];
/// balloon_scenario::mesh::apply_transform(&mut mesh, &t).unwrap();
/// assert_eq!(mesh.vertices[3].x, before.x + 0.5);
/// assert_eq!(mesh.vertices[3].z, before.z - 2.0);
/// let mirror = [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
/// assert!(balloon_scenario::mesh::apply_transform(&mut mesh, &mirror).is_err());
/// ```
pub fn apply_transform(mesh: &mut TriMesh, transform: &[f64]) -> Result<(), String> {
    let (a, t) = affine(transform)?;
    for p in &mut mesh.vertices {
        p.coords = a * p.coords + t;
    }
    Ok(())
}
