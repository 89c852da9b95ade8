//! Mesh inputs shared by `validate` and `bench`: a folder of mesh files or the built-in models,
//! normalised to a common size; and the "every mesh loads, validates and inflates" cases.

use crate::report::Case;
use anyhow::{Context, Result};
use balloon::integrate::linear::LinearSolverKind;
use balloon::mesh::builtin::builtin;
use balloon::mesh::io::read_mesh;
use balloon::mesh::validate::{ValidationOptions, validate, validate_closed_manifold};
use balloon::mesh::{TriMesh, geometry};
use balloon::shell::ShellBalloon;
use std::path::{Path, PathBuf};

const G: &str = "meshes";

/// Mesh file extensions read from a folder.
const EXTENSIONS: &[&str] = &["obj", "off", "ply", "stl"];

/// A named mesh input: a file or a built-in model.
#[derive(Clone, Debug)]
pub enum Source {
    /// A built-in model by name (`balloon::mesh::builtin`).
    Builtin(&'static str),
    /// A mesh file.
    File(PathBuf),
}

impl Source {
    /// Display name: the built-in name or the file name.
    pub fn name(&self) -> String {
        match self {
            Source::Builtin(n) => format!("builtin:{n}"),
            Source::File(p) => p
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| p.display().to_string()),
        }
    }

    /// Loads the mesh (as stored: no scaling).
    pub fn load(&self) -> Result<TriMesh> {
        match self {
            Source::Builtin(n) => builtin(n).with_context(|| format!("built-in mesh {n}")),
            Source::File(p) => read_mesh(p).with_context(|| format!("reading {}", p.display())),
        }
    }
}

/// The shared real meshes (`<repo>/../shared/meshes`), when that folder exists.
pub fn shared_meshes_dir() -> Option<PathBuf> {
    let d = crate::workspace_root()
        .join("..")
        .join("shared")
        .join("meshes");
    d.is_dir().then_some(d)
}

/// Every mesh file (by extension, sorted by name) in `dir`.
pub fn folder(dir: &Path) -> Result<Vec<Source>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read the mesh folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        anyhow::bail!(
            "no mesh files ({}) in {}",
            EXTENSIONS.join(", "),
            dir.display()
        );
    }
    Ok(files.into_iter().map(Source::File).collect())
}

/// Scales and centres `mesh` so that the longest side of its bounding box is `size` (m), with
/// the box centre at the origin: real meshes come in arbitrary units.
pub fn normalise(mesh: &mut TriMesh, size: f64) {
    if let Some(b) = geometry::bounding_box(mesh) {
        let ext = b.max - b.min;
        let longest = ext.x.max(ext.y).max(ext.z);
        if longest > 0.0 {
            let c = nalgebra::center(&b.min, &b.max);
            for p in &mut mesh.vertices {
                *p = nalgebra::Point3::from((*p - c) * (size / longest));
            }
        }
    }
}

/// Loads, validates and inflates every mesh (pump gas, 3 Newton iterations with sparse
/// Cholesky, volume projection on) for `steps` steps of 10 ms: nothing may fail, the shell volume must stay
/// within the projection tolerance and the balloon must grow.
pub fn cases(sources: &[Source], steps: usize) -> Vec<Case> {
    let mut cases = Vec::new();
    for src in sources {
        let name = src.name();
        eprintln!("xtask validate: meshes / {name}");
        let mut mesh = match src.load() {
            Ok(m) => m,
            Err(e) => {
                cases.push(Case::error(G, format!("{name}: load"), format!("{e:#}")));
                continue;
            }
        };
        let report = validate(&mesh, &ValidationOptions::default());
        let closed = validate_closed_manifold(&mesh);
        cases.push(Case::check(
            G,
            format!(
                "{name}: {} v, {} f, closed oriented 2-manifold",
                mesh.num_vertices(),
                mesh.num_triangles()
            ),
            report.is_valid() && closed.is_ok(),
            match &closed {
                Ok(()) if report.is_valid() => "valid".to_string(),
                Ok(()) => format!("{} defects", report.defects.len()),
                Err(e) => e.to_string(),
            },
            "valid",
        ));
        if closed.is_err() {
            continue;
        }
        normalise(&mut mesh, 0.3);
        let run = || -> Result<(f64, f64)> {
            let mut sim = ShellBalloon::new(mesh.clone())
                .with_linear_solver(LinearSolverKind::Cholesky)
                .build()?;
            let mut worst: f64 = 0.0;
            for _ in 0..steps {
                let s = sim.step()?;
                worst = worst.max((s.shell_volume_ratio - 1.0).abs());
            }
            Ok((worst, sim.gas_volume() / sim.rest_gas_volume()))
        };
        match run() {
            Ok((worst, ratio)) => {
                cases.push(Case::at_most(
                    G,
                    format!(
                        "{name} (scaled to 0.3 m): {steps} pump steps, max |V_shell/V_shell0 - 1|"
                    ),
                    worst,
                    1e-9,
                ));
                cases.push(Case::at_least(
                    G,
                    format!("{name}: gas volume ratio after {steps} steps"),
                    ratio,
                    1.0,
                    "> 1 (inflated)",
                ));
            }
            Err(e) => cases.push(Case::error(G, format!("{name}: inflate"), format!("{e:#}"))),
        }
    }
    cases
}
