//! ParaView data collection (`.pvd`): a time series listing frame files with their times.
//!
//! [`PvdWriter`] keeps the list in memory and rewrites the (small) file after every frame
//! through a temporary file and a rename, so a run that stops midway still leaves a valid
//! `.pvd` naming exactly the frames written so far. Frame paths are stored relative to the
//! `.pvd` file's folder, as ParaView expects.

use crate::MeshError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One entry of the collection.
#[derive(Clone, Debug, PartialEq)]
pub struct PvdEntry {
    /// Simulated time, s.
    pub time: f64,
    /// Frame file, relative to the `.pvd` folder.
    pub file: String,
    /// Part (block) of the time step: 0 for the main surface, further parts for other objects
    /// of the scene shown at the same time (ParaView loads the parts of a time as one
    /// multiblock).
    pub part: usize,
}

/// Writes a `.pvd` collection incrementally.
#[derive(Clone, Debug)]
pub struct PvdWriter {
    path: PathBuf,
    entries: Vec<PvdEntry>,
}

impl PvdWriter {
    /// A collection at `path`, written immediately with no entries (so it exists and is valid
    /// before the first frame).
    pub fn create(path: &Path) -> Result<Self, MeshError> {
        let w = Self {
            path: path.to_path_buf(),
            entries: Vec::new(),
        };
        w.flush()?;
        Ok(w)
    }

    /// Adds frame `file` (relative to the `.pvd` folder) at `time` as part 0 and rewrites the
    /// file.
    pub fn push(&mut self, time: f64, file: &str) -> Result<(), MeshError> {
        self.push_part(time, file, 0)
    }

    /// Adds `file` at `time` as part `part` (another object of the same time step, e.g. a rigid
    /// sphere beside the surface) and rewrites the file.
    pub fn push_part(&mut self, time: f64, file: &str, part: usize) -> Result<(), MeshError> {
        if !time.is_finite() {
            return Err(MeshError::InvalidParameter {
                name: "time",
                value: time.to_string(),
                reason: "frame times must be finite".into(),
            });
        }
        if file.is_empty() || file.contains(['"', '<', '>', '&']) {
            return Err(MeshError::InvalidParameter {
                name: "file",
                value: file.to_string(),
                reason: "frame file names must be non-empty without quotes, <, > or &".into(),
            });
        }
        self.entries.push(PvdEntry {
            time,
            file: file.to_string(),
            part,
        });
        self.flush()
    }

    /// The entries so far.
    pub fn entries(&self) -> &[PvdEntry] {
        &self.entries
    }

    /// The collection file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn flush(&self) -> Result<(), MeshError> {
        super::vtp::write_atomic(&self.path, pvd_string(&self.entries).as_bytes())
    }
}

/// The `.pvd` document for `entries`.
pub fn pvd_string(entries: &[PvdEntry]) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for e in entries {
        let _ = writeln!(
            s,
            "    <DataSet timestep=\"{:?}\" group=\"\" part=\"{}\" file=\"{}\"/>",
            e.time, e.part, e.file
        );
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    s
}

/// Reads a `.pvd` written by [`PvdWriter`] (times and files, in file order).
pub fn read_pvd(path: &Path) -> Result<Vec<PvdEntry>, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|e| super::io_err(path, e))?;
    if !text.contains("<VTKFile type=\"Collection\"") || !text.contains("</VTKFile>") {
        return Err(MeshError::Parse {
            path: path.to_path_buf(),
            location: "line 1".into(),
            message: "not a complete VTK Collection (.pvd) file".into(),
        });
    }
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(rest) = line.trim().strip_prefix("<DataSet") {
            let get = |key: &str| {
                let pat = format!(" {key}=\"");
                let s = rest.find(&pat)? + pat.len();
                let e = rest[s..].find('"')? + s;
                Some(rest[s..e].to_string())
            };
            let bad = |message: &str| MeshError::Parse {
                path: path.to_path_buf(),
                location: format!("line {}", i + 1),
                message: message.into(),
            };
            let time = get("timestep")
                .and_then(|t| t.parse::<f64>().ok())
                .ok_or_else(|| bad("DataSet without a numeric timestep"))?;
            let file = get("file").ok_or_else(|| bad("DataSet without a file"))?;
            let part = match get("part") {
                None => 0,
                Some(p) => p
                    .parse::<usize>()
                    .map_err(|_| bad("DataSet with a part that is not a number"))?,
            };
            out.push(PvdEntry { time, file, part });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_push_leaves_a_valid_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("series.pvd");
        let mut w = PvdWriter::create(&p).unwrap();
        assert!(read_pvd(&p).unwrap().is_empty());
        w.push(0.0, "frame_00000.vtp").unwrap();
        w.push(0.1 + 0.2, "frame_00010.vtp").unwrap();
        let e = read_pvd(&p).unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[1].time, 0.1 + 0.2);
        assert_eq!(e[1].file, "frame_00010.vtp");
        assert_eq!((e[0].part, e[1].part), (0, 0));
        w.push_part(0.3, "sphere_00010.vtp", 1).unwrap();
        let e = read_pvd(&p).unwrap();
        assert_eq!(
            (e[2].time, e[2].file.as_str(), e[2].part),
            (0.3, "sphere_00010.vtp", 1)
        );
        w.entries.pop();
        w.flush().unwrap();
        assert!(w.push(f64::NAN, "x.vtp").is_err());
        assert!(w.push(1.0, "a\"b.vtp").is_err());
        assert_eq!(
            read_pvd(&p).unwrap().len(),
            2,
            "rejected entries are not written"
        );
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        std::fs::write(&p, "<VTKFile type=\"Collection\">").unwrap();
        assert!(read_pvd(&p).is_err());
    }
}
