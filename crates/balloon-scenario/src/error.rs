//! What is wrong with a scenario: its file (with the line and the key), a value out of range,
//! or keys that do not go together.

use crate::range::ValueError;
use std::path::PathBuf;

/// What is wrong with a scenario.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file cannot be read. Fix: check the path.
    #[error("cannot read the scenario {}", path.display())]
    Read {
        /// The scenario file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file holds no key at all (empty or only comments), which would run every default.
    /// Fix: the file's path, or give at least the mesh.
    #[error(
        "the scenario {} is empty (no key at all); a scenario file names at least its mesh \
         (`[mesh] path = ...`) or its system",
        path.display()
    )]
    Empty {
        /// The scenario file.
        path: PathBuf,
    },
    /// The file is not valid TOML. Fix: the line named.
    #[error("{}:{line}: not valid TOML: {message}", path.display())]
    Syntax {
        /// The scenario file.
        path: PathBuf,
        /// 1-based line of the error (0 if unknown).
        line: usize,
        /// The parser's message.
        message: String,
    },
    /// A JSON scenario is not valid JSON, or not an object of tables.
    #[error("{}:{line}: {message}", path.display())]
    Json {
        /// The scenario file.
        path: PathBuf,
        /// 1-based line of the error (0 if unknown).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A key or table of a file is unknown, has the wrong type or an invalid value. Fix: the
    /// key named, on the line named.
    #[error("{}:{line}: `{key}`: {message}", path.display())]
    Key {
        /// The scenario file.
        path: PathBuf,
        /// 1-based line of the key.
        line: usize,
        /// The key as `table.key` (or the table's name).
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A parameter has a value outside its range. Fix: a value in the range named.
    #[error(transparent)]
    Value(#[from] ValueError),
    /// Keys that do not go together (the message names them in backticks).
    #[error("{0}")]
    Invalid(String),
}
