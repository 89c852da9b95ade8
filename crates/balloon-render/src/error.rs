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
    /// The flat positions array is not a whole number of `[x, y, z]` triples.
    #[error("bad surface: positions has length {len}, not a multiple of 3")]
    PositionsLength {
        /// Its length.
        len: usize,
    },
    /// A vertex has a NaN or infinite coordinate where every vertex must be finite.
    #[error(
        "bad surface: vertex {vertex} has a non-finite coordinate; POV-Ray cannot represent it"
    )]
    NonFiniteVertex {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "bad surface: triangle {triangle} refers to vertex {vertex}, but there are only {num_vertices} vertices"
    )]
    VertexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The vertex it names.
        vertex: usize,
        /// How many vertices there are.
        num_vertices: usize,
    },
    /// The per-vertex scalars do not match the vertices.
    #[error("bad surface: {len} scalars for {num_vertices} vertices (need one per vertex)")]
    ScalarCount {
        /// Number of scalars given.
        len: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// No vertex has finite coordinates (or there is no vertex), so there is nothing to frame.
    #[error("bad surface: no vertex has finite coordinates")]
    NothingToFrame,
    /// A per-vertex field of the surface (its vertex normals) could not be computed.
    #[error("bad surface: {0}")]
    Field(#[from] balloon_mesh::fields::FieldError),
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The PNG or GIF encoder failed (the encoder's own error is the source).
    #[error("{path}: cannot encode {format}: {source}")]
    Encode {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// `PNG` or `GIF`.
        format: &'static str,
        /// The encoder's error (`png::EncodingError` or `gif::EncodingError`).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Reading back a PNG or GIF failed (the decoder's own error is the source).
    #[error("{path}: cannot decode {format}: {source}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// `PNG` or `GIF`.
        format: &'static str,
        /// The decoder's error (`png::DecodingError` or `gif::DecodingError`).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A PNG read back is not 8-bit RGB or RGBA.
    #[error(
        "{path}: unsupported PNG layout {color_type} at {bit_depth} bits (8-bit RGB or RGBA only)"
    )]
    UnsupportedPng {
        /// The file.
        path: PathBuf,
        /// The PNG colour type, as the decoder names it.
        color_type: &'static str,
        /// Bits per sample.
        bit_depth: u8,
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
