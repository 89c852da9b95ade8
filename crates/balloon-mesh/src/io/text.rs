//! Shared helpers of the text readers: located errors and number parsing.

use crate::MeshError;
use std::path::Path;

/// A parse error at `line` (1-based) of `path`.
pub(crate) fn line_err(path: &Path, line: usize, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: path.to_path_buf(),
        location: format!("line {line}"),
        message: message.into(),
    }
}

/// A parse error at byte `offset` of `path`.
pub(crate) fn byte_err(path: &Path, offset: usize, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: path.to_path_buf(),
        location: format!("byte {offset}"),
        message: message.into(),
    }
}

/// Parses a finite `f64` token, naming `what` in the error.
pub(crate) fn parse_f64(path: &Path, line: usize, tok: &str, what: &str) -> Result<f64, MeshError> {
    match tok.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(line_err(
            path,
            line,
            format!("{what} `{tok}` is not finite"),
        )),
        Err(_) => Err(line_err(
            path,
            line,
            format!("{what} `{tok}` is not a number"),
        )),
    }
}

/// Parses a non-negative count or index token.
pub(crate) fn parse_usize(
    path: &Path,
    line: usize,
    tok: &str,
    what: &str,
) -> Result<usize, MeshError> {
    tok.parse::<usize>().map_err(|_| {
        line_err(
            path,
            line,
            format!("{what} `{tok}` is not a non-negative integer"),
        )
    })
}

/// Non-empty lines with their 1-based numbers, comments (`#` to end of line) removed, split into
/// whitespace-separated tokens.
pub(crate) fn token_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, l)| {
        let l = l.split('#').next().unwrap_or("");
        let toks: Vec<&str> = l.split_whitespace().collect();
        (!toks.is_empty()).then_some((i + 1, toks))
    })
}
