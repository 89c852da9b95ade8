//! The `[design]` table of a scenario file: an inverse design (`balloon design`,
//! `docs/design.md`), the rest shape whose static equilibrium under a gauge pressure is a
//! target surface.
//!
//! A scenario file with a `[design]` table holds only that table. Its keys are the flags of
//! `balloon design` with `_` for `-`: `target` (a mesh path relative to the file, or
//! `builtin:NAME`; required), `pressure` (Pa, required), `thickness`, `scale`, the material
//! keys of `[shell]` (`material`, `young`, `poisson`, `mu`, ...), `tolerance`,
//! `tangential_weight`, `fallback`, `fallback_iterations` and `out` (a folder relative to the file). Every error names the file,
//! the line and the key.
//!
//! ```
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("d.toml");
//! std::fs::write(&path, "[design]\ntarget = \"builtin:icosphere\"\npressure = -4\n").unwrap();
//! let e = balloon_scenario::design::read(&path).unwrap_err();
//! assert!(e.to_string().ends_with("d.toml:3: `design.pressure`: invalid value '-4': a \
//!     positive gauge pressure in Pa, at most 1e9"), "{e}");
//! std::fs::write(&path, "[design]\ntarget = \"builtin:icosphere\"\npressure = 4000\n").unwrap();
//! let d = balloon_scenario::design::read(&path).unwrap().unwrap();
//! assert_eq!(d.pressure, 4000.0);
//! ```

use crate::error::ScenarioError;
use crate::file::{Source, Span, parse, type_name};
use crate::material::{MaterialChoice, MaterialSpec};
use std::path::{Path, PathBuf};

/// The `[design]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignScenario {
    /// The target: a mesh path (joined to the file's folder) or `builtin[:NAME]`.
    pub target: String,
    /// Gauge pressure at the target shape, Pa.
    pub pressure: f64,
    /// Rest wall thickness, m [default: 3e-4, as `balloon design`].
    pub thickness: f64,
    /// The target's coordinates times this factor are metres [default: 1].
    pub scale: f64,
    /// The material keys.
    pub material: MaterialSpec,
    /// Relative equilibrium residual at which the design stops [default: the library's].
    pub tolerance: Option<f64>,
    /// Weight of the tangential regulariser [default: 0].
    pub tangential_weight: f64,
    /// When the shape optimisation runs: `"unconverged"`, `"always"` or `"off"` [default:
    /// the library's, `"unconverged"`].
    pub fallback: Option<String>,
    /// Steps allowed to the shape optimisation, 1 to 100000 [default: the library's].
    pub fallback_iterations: Option<usize>,
    /// Output folder (joined to the file's folder).
    pub out: Option<PathBuf>,
}

/// The keys of `[design]`, in the order the errors list them.
pub const DESIGN_KEYS: &[&str] = &[
    "target",
    "pressure",
    "thickness",
    "scale",
    "material",
    "material_preset",
    "young",
    "poisson",
    "mu",
    "c1",
    "c2",
    "jm",
    "ogden_mu",
    "ogden_alpha",
    "yeoh",
    "tolerance",
    "tangential_weight",
    "fallback",
    "fallback_iterations",
    "out",
];

/// A number in `(lo, hi]` (or `[lo, hi]` with `closed`), else what is allowed.
fn in_range(x: f64, lo: f64, hi: f64, closed: bool, what: &str) -> Result<f64, String> {
    let ok = x.is_finite() && x <= hi && if closed { x >= lo } else { x > lo };
    if ok { Ok(x) } else { Err(what.to_owned()) }
}

/// Whether the file at `path` is a design scenario (has a `[design]` table).
///
/// # Errors
/// A file that cannot be read or parsed.
pub fn is_design(path: &Path) -> Result<bool, ScenarioError> {
    let (_, _, doc) = parse(path)?;
    Ok(doc.as_table().contains_key("design"))
}

/// Reads the `[design]` table of the scenario file at `path` (TOML, or JSON with the same
/// table): `None` when the file has no `[design]` table. Values are range-checked with their
/// lines; the material keys together by [`MaterialSpec::resolve`].
///
/// # Errors
/// [`ScenarioError::Key`] naming the file, the line and the key: another table beside
/// `[design]`, an unknown key, a value of the wrong type or out of range, a missing `target` or
/// `pressure`, material keys that do not go together.
pub fn read(path: &Path) -> Result<Option<DesignScenario>, ScenarioError> {
    let (text, lines, doc) = parse(path)?;
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    let root = doc.as_table();
    let Some(item) = root.get("design") else {
        return Ok(None);
    };
    let table_span: Span = root.key("design").and_then(|k| k.span());
    if let Some((other, _)) = root.iter().find(|(k, _)| *k != "design") {
        let span = root.key(other).and_then(|k| k.span());
        return Err(src.key_error(
            span,
            other,
            "a scenario with a [design] table holds only that table (its keys are the flags of \
             `balloon design`)"
                .to_owned(),
        ));
    }
    let table = item.as_table_like().ok_or_else(|| {
        src.key_error(
            table_span.clone(),
            "design",
            "expected a table `[design]`".to_owned(),
        )
    })?;
    let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let mut d = DesignScenario {
        target: String::new(),
        pressure: f64::NAN,
        thickness: 3.0e-4,
        scale: 1.0,
        material: MaterialSpec::default(),
        tolerance: None,
        tangential_weight: 0.0,
        fallback: None,
        fallback_iterations: None,
        out: None,
    };
    let (mut has_target, mut has_pressure) = (false, false);
    let mut material_span: Span = None;
    for (key, value) in table.iter() {
        let span: Span = table.key(key).and_then(|k| k.span());
        let full = format!("design.{key}");
        let err = |m: String| src.key_error(span.clone(), &full, m);
        let Some(value) = value.as_value() else {
            return Err(err("expected a value, found a table".to_owned()));
        };
        let literal = value
            .as_str()
            .map_or_else(|| value.to_string().trim().to_owned(), str::to_owned);
        let invalid = |why: String| err(format!("invalid value '{literal}': {why}"));
        let number = || -> Result<f64, ScenarioError> {
            match value {
                toml_edit::Value::Float(f) => Ok(*f.value()),
                toml_edit::Value::Integer(i) => Ok(*i.value() as f64),
                v => Err(err(format!("expected a number, found {}", type_name(v)))),
            }
        };
        let numbers = || -> Result<Vec<f64>, ScenarioError> {
            match value {
                toml_edit::Value::Array(a) => a
                    .iter()
                    .map(|v| match v {
                        toml_edit::Value::Float(f) => Ok(*f.value()),
                        toml_edit::Value::Integer(i) => Ok(*i.value() as f64),
                        v => Err(err(format!("expected numbers, found {}", type_name(v)))),
                    })
                    .collect(),
                _ => number().map(|x| vec![x]),
            }
        };
        let text = || -> Result<&str, ScenarioError> {
            value
                .as_str()
                .ok_or_else(|| err(format!("expected a string, found {}", type_name(value))))
        };
        let path_of = |s: &str| base.join(s).to_string_lossy().into_owned();
        match key {
            "target" => {
                let s = text()?;
                d.target = if s.starts_with("builtin") {
                    s.to_owned()
                } else {
                    path_of(s)
                };
                has_target = true;
            }
            "pressure" => {
                d.pressure = in_range(
                    number()?,
                    0.0,
                    1e9,
                    false,
                    "a positive gauge pressure in Pa, at most 1e9",
                )
                .map_err(invalid)?;
                has_pressure = true;
            }
            "thickness" => {
                d.thickness =
                    in_range(number()?, 0.0, 1.0, false, "in (0, 1] m").map_err(invalid)?;
            }
            "scale" => {
                d.scale = in_range(number()?, 0.0, 1e6, false, "in (0, 1e6]").map_err(invalid)?;
            }
            "tolerance" => {
                d.tolerance = Some(
                    in_range(number()?, 0.0, 1.0, false, "in (0, 1)")
                        .and_then(|t| {
                            if t < 1.0 {
                                Ok(t)
                            } else {
                                Err("in (0, 1)".into())
                            }
                        })
                        .map_err(invalid)?,
                );
            }
            "tangential_weight" => {
                d.tangential_weight =
                    in_range(number()?, 0.0, 1e6, true, "in [0, 1e6]").map_err(invalid)?;
            }
            "fallback" => {
                let s = text()?;
                if !["unconverged", "always", "off"].contains(&s) {
                    return Err(invalid("\"unconverged\", \"always\" or \"off\"".into()));
                }
                d.fallback = Some(s.to_owned());
            }
            "fallback_iterations" => {
                let n = in_range(number()?, 1.0, 1e5, true, "a whole number from 1 to 100000")
                    .and_then(|n| {
                        if n.fract() == 0.0 {
                            Ok(n)
                        } else {
                            Err("a whole number from 1 to 100000".into())
                        }
                    })
                    .map_err(invalid)?;
                d.fallback_iterations = Some(n as usize);
            }
            "out" => d.out = Some(PathBuf::from(path_of(text()?))),
            "material" => {
                let s = text()?;
                d.material.material = Some(s.parse::<MaterialChoice>().map_err(invalid)?);
                material_span = span.clone();
            }
            "material_preset" => {
                let s = text()?;
                d.material.material_preset = Some(
                    s.parse::<balloon::material::membrane::MembranePreset>()
                        .map_err(|e| invalid(e.to_string()))?,
                );
                material_span = span.clone();
            }
            "young" => d.material.young = Some(number()?),
            "poisson" => d.material.poisson = Some(number()?),
            "mu" => d.material.mu = Some(number()?),
            "c1" => d.material.c1 = Some(number()?),
            "c2" => d.material.c2 = Some(number()?),
            "jm" => d.material.jm = Some(number()?),
            "ogden_mu" => d.material.ogden_mu = Some(numbers()?),
            "ogden_alpha" => d.material.ogden_alpha = Some(numbers()?),
            "yeoh" => d.material.yeoh = Some(numbers()?),
            _ => {
                return Err(err(format!(
                    "unknown key (the keys of [design] are {})",
                    DESIGN_KEYS.join(", ")
                )));
            }
        }
    }
    for (given, key) in [(has_target, "target"), (has_pressure, "pressure")] {
        if !given {
            return Err(src.key_error(
                table_span.clone(),
                &format!("design.{key}"),
                "missing: [design] needs `target` and `pressure`".to_owned(),
            ));
        }
    }
    d.material
        .resolve()
        .map_err(|m| src.key_error(material_span.or(table_span), "design.material", m))?;
    Ok(Some(d))
}
