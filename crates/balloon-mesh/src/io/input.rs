//! Reading an input file without blocking or exhausting memory: every file the programs read
//! (meshes, scenario files, thickness maps, vertex lists) goes through [`read_input_file`],
//! which refuses what is not a regular file (a FIFO would block in `open`, `/dev/zero` would be
//! read until memory runs out, a directory cannot be read) and what is larger than the caller's
//! limit, by the file's metadata before it is opened; the read is capped too, in case the file
//! grows in between. Symbolic links are followed, so a link to a device is refused as the device.
//!
//! The files read are remembered ([`was_read`]), so that an output folder that is cleaned
//! before a run never deletes one of the run's inputs.
//!
//! ```
//! use balloon_mesh::io::{InputFileError, MAX_TEXT_INPUT_BYTES, read_input_file};
//! let dir = std::env::temp_dir();
//! let err = read_input_file(&dir, MAX_TEXT_INPUT_BYTES).unwrap_err();
//! assert!(matches!(err, InputFileError::NotAFile { kind: "a directory", .. }));
//! ```

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use thiserror::Error;

/// Largest text input (scenario file, thickness map, vertex list) the programs read, bytes
/// (64 MiB: a vertex list of the largest meshes is a few MB).
pub const MAX_TEXT_INPUT_BYTES: u64 = 64 << 20;

/// Why an input file was not read.
#[derive(Debug, Error)]
pub enum InputFileError {
    /// The file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The path names something that is not a regular file (a device, a FIFO, a directory).
    #[error("{}: is {kind}, not a regular file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is, in words ("a FIFO (named pipe)", "a directory", ...).
        kind: &'static str,
    },
    /// The file is larger than the limit for its kind.
    #[error("{}: file of {size} bytes is larger than the {limit}-byte limit", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size, bytes.
        size: u64,
        /// The limit, bytes.
        limit: u64,
    },
}

impl InputFileError {
    /// The error without its path, as an I/O error (for callers whose own error names the
    /// path): a file that is not regular is `InvalidInput`, one over the limit `FileTooLarge`.
    pub fn into_io(self) -> std::io::Error {
        use std::io::{Error, ErrorKind};
        match self {
            Self::Io { source, .. } => source,
            Self::NotAFile { kind, .. } => Error::new(
                ErrorKind::InvalidInput,
                format!("is {kind}, not a regular file"),
            ),
            Self::TooLarge { size, limit, .. } => Error::new(
                ErrorKind::FileTooLarge,
                format!("file of {size} bytes is larger than the {limit}-byte limit"),
            ),
        }
    }
}

/// Canonical paths of the files read so far by this process.
static READ: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

/// Whether `path` (any spelling of it) is a file this process has read as an input.
pub fn was_read(path: &Path) -> bool {
    let Ok(canonical) = std::fs::canonicalize(path) else {
        return false;
    };
    READ.lock().is_ok_and(|r| r.contains(&canonical))
}

/// Reads the whole file at `path` when it is a regular file of at most `limit` bytes (see the
/// module documentation); anything else is an error naming `path`, returned before the file is
/// opened.
pub fn read_input_file(path: &Path, limit: u64) -> Result<Vec<u8>, InputFileError> {
    let io = |source| InputFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    let kind = meta.file_type();
    if !kind.is_file() {
        return Err(InputFileError::NotAFile {
            path: path.to_path_buf(),
            kind: file_kind(&kind),
        });
    }
    let too_big = |size| InputFileError::TooLarge {
        path: path.to_path_buf(),
        size,
        limit,
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    if let (Ok(canonical), Ok(mut read)) = (std::fs::canonicalize(path), READ.lock()) {
        read.insert(canonical);
    }
    Ok(bytes)
}

/// [`read_input_file`] for a UTF-8 text file (invalid UTF-8 is an [`InputFileError::Io`] of
/// kind `InvalidData`).
pub fn read_input_text(path: &Path, limit: u64) -> Result<String, InputFileError> {
    let bytes = read_input_file(path, limit)?;
    String::from_utf8(bytes).map_err(|e| InputFileError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })
}

/// A name for a file type that is not a regular file.
pub(crate) fn file_kind(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    if kind.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn devices_fifos_directories_and_big_files_are_refused_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        // A FIFO with no writer would block `open` for ever: refused by its type.
        let e = read_input_file(&fifo, 100).unwrap_err();
        assert!(e.to_string().contains("pipe: is a FIFO"), "{e}");
        let link = dir.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = read_input_file(&link, 100).unwrap_err();
        assert!(e.to_string().contains("zero: is a character device"), "{e}");
        let e = read_input_file(dir.path(), 100).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        let big = dir.path().join("big.txt");
        std::fs::write(&big, [b'x'; 101]).unwrap();
        let e = read_input_file(&big, 100).unwrap_err();
        assert!(
            e.to_string()
                .contains("big.txt: file of 101 bytes is larger than the 100-byte limit"),
            "{e}"
        );
        assert!(!was_read(&big));
        let small = dir.path().join("small.txt");
        std::fs::write(&small, "ok").unwrap();
        assert_eq!(read_input_text(&small, 100).unwrap(), "ok");
        assert!(was_read(&dir.path().join(".").join("small.txt")));
    }
}
