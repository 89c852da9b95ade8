//! Errors of the renderer.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong rendering or writing an image.
#[derive(Debug, Error)]
pub enum RenderError {
    /// An argument is out of range (image size, colour range, frame delay, ...).
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// What is allowed.
        reason: String,
    },
    /// The surface data is inconsistent (array lengths, indices, non-finite coordinates).
    #[error("bad surface: {0}")]
    BadSurface(String),
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The PNG or GIF encoder failed.
    #[error("{path}: cannot encode {format}: {message}")]
    Encode {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// `PNG` or `GIF`.
        format: &'static str,
        /// The encoder's message.
        message: String,
    },
}

impl RenderError {
    pub(crate) fn invalid(name: &'static str, value: impl ToString, reason: &str) -> Self {
        RenderError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: reason.to_string(),
        }
    }
}
