//! Typed errors of the mesh crate.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong reading, validating or generating a mesh.
#[derive(Debug, Error)]
pub enum MeshError {
    /// The file could not be opened or read. Check the path and permissions.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The path names something that is not a regular file (a device, a FIFO, a directory).
    #[error("{path}: is {kind}, not a mesh file")]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is, in words.
        kind: &'static str,
    },
    /// The file is larger than the readers accept ([`crate::io::MAX_MESH_FILE_BYTES`]).
    #[error("{path}: file of {size} bytes is larger than the {limit}-byte limit for mesh files")]
    FileTooLarge {
        /// The file.
        path: PathBuf,
        /// Its size, bytes.
        size: u64,
        /// The limit, bytes.
        limit: u64,
    },
    /// The file's content is malformed at a given line (text formats) or byte offset (binary).
    /// The message is shown with control characters escaped and long tokens shortened, so a
    /// hostile file cannot write terminal escape sequences or megabytes to the terminal.
    #[error("{}:{location}: {}", path.display(), crate::io::printable(message))]
    Parse {
        /// The file.
        path: PathBuf,
        /// `line N` or `byte N`.
        location: String,
        /// What is wrong.
        message: String,
    },
    /// A parameter passed to a generator or helper is out of range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is invalid and what range is allowed.
        reason: String,
    },
    /// The file extension is not one of the supported mesh formats. Convert the mesh to OBJ,
    /// OFF, PLY or STL, or rename it if the extension is wrong.
    #[error("{path}: unsupported mesh format `{extension}` (supported: {supported})")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
        /// Its extension (empty when it has none).
        extension: String,
        /// The supported extensions for this operation.
        supported: &'static str,
    },
    /// `builtin:NAME` named no built-in mesh. Use one of the listed names.
    #[error("unknown built-in mesh `{name}` (known: {known})")]
    UnknownBuiltin {
        /// The name asked for.
        name: String,
        /// The known names, comma separated.
        known: String,
    },
    /// The mesh is not a valid closed, consistently outward-oriented 2-manifold without
    /// degenerate triangles. The message names the first defect and how many more there are;
    /// repair the mesh (e.g. with [`crate::validate::weld_vertices`],
    /// [`crate::validate::remove_degenerate_triangles`], [`crate::validate::orient_outward`]) or
    /// fix it in a modelling tool.
    #[error("invalid mesh: {first} (and {others} more defect(s))")]
    InvalidMesh {
        /// The first defect found, naming its triangle, edge or vertex.
        first: crate::validate::Defect,
        /// How many further defects were found.
        others: usize,
    },
    /// A tetrahedron refers to a vertex that does not exist. Fix the tetrahedral mesh generator or
    /// file.
    #[error(
        "tetrahedron {tet} refers to vertex {index} but there are only {num_vertices} vertices"
    )]
    TetIndexOutOfRange {
        /// The tetrahedron.
        tet: usize,
        /// The bad index.
        index: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
}
