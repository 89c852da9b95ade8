//! Rest-thickness maps of a shell: a text file of thicknesses (one per face or one per
//! vertex), a rule linear in one coordinate, or a PLY mesh's own `thickness` property.
//!
//! ```
//! use balloon_scenario::selection::{parse_rule, thickness_map};
//! let mesh = balloon::mesh::generate::icosphere(1.0, 0).unwrap();
//! let rule = parse_rule("z:1e-4:3e-4").unwrap();
//! let t = thickness_map(None, Some(rule), "m.obj", &mesh).unwrap().unwrap();
//! assert_eq!(t.len(), mesh.num_triangles());
//! assert!(t.iter().all(|&h| (1e-4..=3e-4 + 1e-15).contains(&h)));
//! // Neither a file nor a rule, and a mesh that is not a PLY file: the uniform thickness.
//! assert_eq!(thickness_map(None, None, "m.obj", &mesh).unwrap(), None);
//! ```

use super::selector::{SelectionError, data_lines, parse_axis, spec_real};
use crate::range::{End, Real};
use balloon::mesh::TriMesh;
use balloon::mesh::io::PlyProperty;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A rest thickness linear in one coordinate over the bounding box (`thickness_rule`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RuleForm", into = "RuleForm")]
pub struct LinearRule {
    /// The coordinate (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Thickness at the lowest face centroid, m.
    pub from: f64,
    /// Thickness at the highest face centroid, m.
    pub to: f64,
}

/// `AXIS:FROM:TO` with both thicknesses in (0, 1] m.
pub fn parse_rule(s: &str) -> Result<LinearRule, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [axis, from, to] = parts[..] else {
        return Err(format!("`{s}`: expected AXIS:FROM:TO, e.g. z:3e-4:6e-4"));
    };
    let thick = |t: &str| spec_real(t, THICKNESS);
    Ok(LinearRule {
        axis: parse_axis(axis)?,
        from: thick(from)?,
        to: thick(to)?,
    })
}

/// The range of a rest thickness, m: (0, 1] (a thin shell).
pub const THICKNESS: Real = Real::new(End::Open(0.0), End::Closed(1.0));

impl std::fmt::Display for LinearRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{:?}:{:?}",
            ["x", "y", "z"][self.axis.min(2)],
            self.from,
            self.to
        )
    }
}

impl std::str::FromStr for LinearRule {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_rule(s)
    }
}

/// The serde form of a rule: `"AXIS:FROM:TO"` or `{ axis, from, to }`.
#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum RuleForm {
    Text(String),
    Table { axis: String, from: f64, to: f64 },
}

impl TryFrom<RuleForm> for LinearRule {
    type Error = String;
    fn try_from(f: RuleForm) -> Result<Self, String> {
        match f {
            RuleForm::Text(s) => parse_rule(&s),
            RuleForm::Table { axis, from, to } => parse_rule(&format!("{axis}:{from:?}:{to:?}")),
        }
    }
}

impl From<LinearRule> for RuleForm {
    fn from(r: LinearRule) -> Self {
        RuleForm::Text(r.to_string())
    }
}

/// The per-face rest thickness of `mesh` (already scaled) from a thickness `file` (one value
/// per line, `#` comments: one per face, or one per vertex averaged to the faces, told apart
/// by their count), a `rule`, or the `thickness` property of `mesh_spec` when it names a PLY
/// file; `None` when none applies (the uniform thickness). A file's error names its line.
pub fn thickness_map(
    file: Option<&Path>,
    rule: Option<LinearRule>,
    mesh_spec: &str,
    mesh: &TriMesh,
) -> Result<Option<Vec<f64>>, SelectionError> {
    {
        let (nf, nv) = (mesh.num_triangles(), mesh.num_vertices());
        let (what, values) = if let Some(path) = file {
            let lines = data_lines(path)?;
            let mut values = Vec::with_capacity(lines.len());
            for (line, l) in lines {
                let v = l
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v > 0.0 && *v <= 1.0);
                values.push(v.ok_or_else(|| SelectionError::Line {
                    path: path.to_path_buf(),
                    line,
                    message: format!("`{l}` is not a thickness in (0, 1] m"),
                })?);
            }
            (path.display().to_string(), values)
        } else if let Some(rule) = rule {
            let c: Vec<f64> = mesh
                .triangles
                .iter()
                .map(|t| t.iter().map(|&v| mesh.vertices[v][rule.axis]).sum::<f64>() / 3.0)
                .collect();
            let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let span = if hi > lo { hi - lo } else { 1.0 };
            let values = c
                .iter()
                .map(|&x| rule.from + (rule.to - rule.from) * (x - lo) / span)
                .collect();
            return Ok(Some(values));
        } else if mesh_spec.to_ascii_lowercase().ends_with(".ply") {
            let path = PathBuf::from(mesh_spec);
            let (_, property) = balloon::mesh::io::read_ply_with_property(&path, "thickness")
                .map_err(|source| SelectionError::Mesh {
                    path: path.clone(),
                    source,
                })?;
            let what = format!("the thickness property of {mesh_spec}");
            match property {
                PlyProperty::Absent => return Ok(None),
                PlyProperty::PerFace(v) | PlyProperty::PerVertex(v) => (what, v),
            }
        } else {
            return Ok(None);
        };
        for (i, &v) in values.iter().enumerate() {
            if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                return Err(SelectionError::Thickness {
                    what,
                    place: format!("value {}", i + 1),
                    value: v,
                });
            }
        }
        if values.len() == nf {
            Ok(Some(values))
        } else if values.len() == nv {
            Ok(Some(
                mesh.triangles
                    .iter()
                    .map(|t| t.iter().map(|&v| values[v]).sum::<f64>() / 3.0)
                    .collect(),
            ))
        } else {
            Err(SelectionError::Count {
                what,
                count: values.len(),
                faces: nf,
                vertices: nv,
            })
        }
    }
}
