//! Typed errors of the mesh crate.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong reading, validating or generating a mesh.
#[derive(Debug, Error)]
pub enum MeshError {
    /// The file could not be opened or read. Check the path and permissions.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file's content is malformed at a given line (text formats) or byte offset (binary).
    #[error("{path}:{location}: {message}")]
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
}
