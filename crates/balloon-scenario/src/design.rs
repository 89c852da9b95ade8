//! The `[design]` table of a scenario file: an inverse design (`balloon design`,
//! `docs/design.md`), the rest shape whose static equilibrium under a gauge pressure is a
//! target surface.
//!
//! A scenario file with a `[design]` table holds only that table. Its keys are the flags of
//! `balloon design` with `_` for `-`: `target` (a mesh path relative to the file, or
//! `builtin:NAME`; required), `pressure` (Pa; or `gas_amount`, the load as an amount of ideal
//! gas `nRT` in J, with its `ambient` pressure in Pa), `thickness`, `scale`, the material
//! keys of `[shell]` (`material`, `young`, `poisson`, `mu`, ...), the solve's options
//! ([`DESIGN_OPTIONS`]: `tolerance`, `tangential_weight`, `fallback`, `fallback_iterations`,
//! `accept_distance`, `method`, `shape_weight`, `shape_stages`, `newton_polish`, `warm_start`,
//! `bending_weight`, `inverse_bending_weight`, `inverse_bending_stages`, the wall's bending
//! stiffness `bending` (as `[shell] bending`), and the wall-thickness fit's
//! `fit_thickness`, `thickness_min`, `thickness_max`, `thickness_iterations`; and
//! `conditioning`, `conditioning_modes`, `conditioning_iterations`), `rest` (a rest
//! shape to keep instead of designing one, relative to the file) and `out` (a folder
//! relative to the file). Every error names the file, the line and the key.
//!
//! The solve's options are set on [`balloon_design::DesignParams`] by one function,
//! [`set_design_option`], which the Python package uses too, so a key means the same and is
//! checked the same way in a scenario file and in `balloon.design(...)`.
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
use balloon_design::{DesignParams, FallbackMethod, FallbackMode};
use std::path::{Path, PathBuf};

/// The `[design]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignScenario {
    /// The target: a mesh path (joined to the file's folder) or `builtin[:NAME]`.
    pub target: String,
    /// Gauge pressure at the target shape, Pa (NaN when the load is `gas_amount`).
    pub pressure: f64,
    /// The load as an amount of ideal gas instead, `nRT` in J.
    pub gas_amount: Option<f64>,
    /// Ambient pressure of the gas amount, Pa [default: 101325].
    pub ambient: Option<f64>,
    /// Rest wall thickness, m [default: 3e-4, as `balloon design`].
    pub thickness: f64,
    /// The target's coordinates times this factor are metres [default: 1].
    pub scale: f64,
    /// The material keys.
    pub material: MaterialSpec,
    /// The solve's parameters: the library's defaults with the table's [`DESIGN_OPTIONS`] set.
    pub params: DesignParams,
    /// A rest shape to keep instead of designing one (a mesh path joined to the file's folder,
    /// read with the target's `scale`; the target's connectivity): its wall is fitted with
    /// `fit_thickness` and it is checked.
    pub rest: Option<String>,
    /// Output folder (joined to the file's folder).
    pub out: Option<PathBuf>,
    /// Replace the files of an earlier design in `out` [default: false, such a folder is
    /// refused].
    pub overwrite: bool,
}

/// The keys of `[design]`, in the order the errors list them.
pub const DESIGN_KEYS: &[&str] = &[
    "target",
    "pressure",
    "gas_amount",
    "ambient",
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
    "accept_distance",
    "method",
    "shape_weight",
    "shape_stages",
    "newton_polish",
    "warm_start",
    "bending_weight",
    "inverse_bending_weight",
    "inverse_bending_stages",
    "bending",
    "fit_thickness",
    "thickness_min",
    "thickness_max",
    "thickness_iterations",
    "conditioning",
    "conditioning_modes",
    "conditioning_iterations",
    "rest",
    "out",
    "overwrite",
];

/// The options of the design solve (keys of `[design]` and of Python's `balloon.design`), with
/// what each sets in [`DesignParams`] and the values it takes; [`set_design_option`] sets them.
pub const DESIGN_OPTIONS: &[(&str, &str)] = &[
    (
        "tolerance",
        "relative equilibrium residual at which the inverse solve stops (`inverse.tolerance`)",
    ),
    (
        "tangential_weight",
        "weight of the inverse solve's tangential regulariser (`inverse.tangential_weight`; 0: \
         none, the design exact)",
    ),
    (
        "fallback",
        "when the shape optimisation runs after the inverse solve (`fallback.mode`)",
    ),
    (
        "fallback_iterations",
        "steps allowed to the shape optimisation (`fallback.max_iterations`)",
    ),
    (
        "accept_distance",
        "a design whose inverse has no exact answer still answers its target when its forward \
         check lies within this fraction of the target's bounding-box diagonal \
         (`accept_distance`; 0: only an exact design; docs/design.md)",
    ),
    (
        "method",
        "the shape optimisation's outer loop (`fallback.method`; docs/design.md D15, D13)",
    ),
    (
        "shape_weight",
        "weight gamma_0 of the rest-mesh shape term in the shape optimisation \
         (`fallback.shape_weight`; 0: off; docs/design.md D16)",
    ),
    (
        "shape_stages",
        "stages of the shape optimisation with the shape term (`fallback.shape_stages`)",
    ),
    (
        "newton_polish",
        "hand the optimised rest shape to the inverse's Newton solve (`fallback.newton_polish`)",
    ),
    (
        "bending_weight",
        "weight kappa_0 of the rest-mesh bending term in the shape optimisation \
         (`fallback.bending_weight`; 0: off; stages as `shape_stages`; docs/design.md D17)",
    ),
    (
        "inverse_bending_weight",
        "weight of the rest-mesh bending term in the inverse solve's continuation \
         (`inverse.bending_weight`; 0: off; docs/design.md D17)",
    ),
    (
        "inverse_bending_stages",
        "stages of the inverse solve with the bending term (`inverse.bending_stages`)",
    ),
    (
        "bending",
        "the wall's bending stiffness as a factor on a plate's of its material and thickness, \
         as `[shell] bending` and `balloon inflate --bending` (`wall_bending`; 0: none, the \
         wall of Wang et al. 2015; docs/design.md D20)",
    ),
    (
        "warm_start",
        "start each forward solve of the shape optimisation from the last equilibrium \
         and of the thickness fit (`fallback.warm_start`, `thickness.warm_start`; faster, see \
         docs/design.md)",
    ),
    (
        "fit_thickness",
        "after the rest shape, fit the wall's rest thickness per face to the target with that \
         rest shape fixed (`thickness.enabled`; docs/design.md D18)",
    ),
    (
        "thickness_min",
        "smallest thickness the fit may give a face, m (`thickness.lower`; default a quarter \
         of the wall)",
    ),
    (
        "thickness_max",
        "largest thickness the fit may give a face, m (`thickness.upper`; default four times \
         the wall)",
    ),
    (
        "thickness_iterations",
        "steps allowed to the thickness fit (`thickness.max_iterations`)",
    ),
    (
        "conditioning",
        "after the check, the smallest singular values of the inverse's Jacobian at the rest \
         shape: how well the target determines it (`conditioning.enabled`; docs/design.md D19)",
    ),
    (
        "conditioning_modes",
        "singular values the conditioning report seeks (`conditioning.modes`)",
    ),
    (
        "conditioning_iterations",
        "block inverse iterations of the conditioning report (`conditioning.iterations`)",
    ),
];

/// A value of a design option as a front end read it.
#[derive(Clone, Debug, PartialEq)]
pub enum OptionValue {
    /// A number (an integer is given as its value).
    Number(f64),
    /// A string.
    Text(String),
    /// A boolean.
    Bool(bool),
}

/// Why [`set_design_option`] refused a value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptionError {
    /// A value of the wrong kind; this kind was expected (`"a number"`, ...).
    Expected(&'static str),
    /// A value of the right kind out of range; this is what is allowed.
    Invalid(&'static str),
}

/// Sets the design option `key` ([`DESIGN_OPTIONS`]) to `value` in `params`; `Ok(false)` when
/// `key` is not a design option (nothing changed).
///
/// ```
/// use balloon_scenario::design::{OptionError, OptionValue, set_design_option};
/// let mut p = balloon_design::DesignParams::default();
/// assert_eq!(set_design_option(&mut p, "shape_weight", &OptionValue::Number(10.0)), Ok(true));
/// assert_eq!(p.fallback.shape_weight, 10.0);
/// assert_eq!(set_design_option(&mut p, "method", &OptionValue::Text("lbfgs".into())), Ok(true));
/// assert_eq!(p.fallback.method, balloon_design::FallbackMethod::Lbfgs);
/// assert_eq!(
///     set_design_option(&mut p, "shape_stages", &OptionValue::Number(2.5)),
///     Err(OptionError::Invalid("a whole number from 1 to 20"))
/// );
/// assert_eq!(set_design_option(&mut p, "thickness", &OptionValue::Number(1.0)), Ok(false));
/// ```
///
/// # Errors
/// [`OptionError`]: a value of the wrong kind, or out of range (nothing changed).
pub fn set_design_option(
    params: &mut DesignParams,
    key: &str,
    value: &OptionValue,
) -> Result<bool, OptionError> {
    let number = || match value {
        OptionValue::Number(x) => Ok(*x),
        _ => Err(OptionError::Expected("a number")),
    };
    let text = || match value {
        OptionValue::Text(s) => Ok(s.as_str()),
        _ => Err(OptionError::Expected("a string")),
    };
    let flag = || match value {
        OptionValue::Bool(b) => Ok(*b),
        _ => Err(OptionError::Expected("true or false")),
    };
    let real = |lo: f64, hi: f64, closed: bool, what: &'static str| {
        in_range(number()?, lo, hi, closed, what).map_err(|_| OptionError::Invalid(what))
    };
    let whole = |lo: f64, hi: f64, what: &'static str| {
        let x = number()?;
        if x.fract() == 0.0 && x >= lo && x <= hi {
            Ok(x as usize)
        } else {
            Err(OptionError::Invalid(what))
        }
    };
    match key {
        "tolerance" => {
            let t = real(0.0, 1.0, false, "in (0, 1)")?;
            if t >= 1.0 {
                return Err(OptionError::Invalid("in (0, 1)"));
            }
            params.inverse.tolerance = t;
        }
        "tangential_weight" => {
            params.inverse.tangential_weight = real(0.0, 1e6, true, "in [0, 1e6]")?;
        }
        "fallback" => {
            params.fallback.mode = text()?
                .parse::<FallbackMode>()
                .map_err(|_| OptionError::Invalid("\"unconverged\", \"always\" or \"off\""))?;
        }
        "fallback_iterations" => {
            params.fallback.max_iterations = whole(1.0, 1e5, "a whole number from 1 to 100000")?;
        }
        "accept_distance" => {
            params.accept_distance = real(0.0, 1.0, true, "in [0, 1]")?;
        }
        "method" => {
            params.fallback.method = match text()?.trim().to_ascii_lowercase().as_str() {
                "gauss-newton" | "gauss_newton" => FallbackMethod::GaussNewton,
                "lbfgs" | "l-bfgs" => FallbackMethod::Lbfgs,
                _ => return Err(OptionError::Invalid("\"gauss-newton\" or \"lbfgs\"")),
            };
        }
        "shape_weight" => {
            params.fallback.shape_weight = real(0.0, 1e6, true, "in [0, 1e6]")?;
        }
        "shape_stages" => {
            params.fallback.shape_stages = whole(1.0, 20.0, "a whole number from 1 to 20")?;
        }
        "newton_polish" => params.fallback.newton_polish = flag()?,
        "bending_weight" => {
            params.fallback.bending_weight = real(0.0, 1e6, true, "in [0, 1e6]")?;
        }
        "inverse_bending_weight" => {
            params.inverse.bending_weight = real(0.0, 1e6, true, "in [0, 1e6]")?;
        }
        "inverse_bending_stages" => {
            params.inverse.bending_stages = whole(1.0, 20.0, "a whole number from 1 to 20")?;
        }
        "bending" => {
            params.wall_bending = real(0.0, 1e6, true, "in [0, 1e6]")?;
        }
        "warm_start" => {
            params.fallback.warm_start = flag()?;
            params.thickness.warm_start = params.fallback.warm_start;
        }
        "fit_thickness" => params.thickness.enabled = flag()?,
        "conditioning" => params.conditioning.enabled = flag()?,
        "conditioning_modes" => {
            params.conditioning.modes = whole(1.0, 64.0, "a whole number from 1 to 64")?;
        }
        "conditioning_iterations" => {
            params.conditioning.iterations = whole(1.0, 1000.0, "a whole number from 1 to 1000")?;
        }
        "thickness_min" => {
            params.thickness.lower = Some(real(0.0, 1.0, false, "in (0, 1] m")?);
        }
        "thickness_max" => {
            params.thickness.upper = Some(real(0.0, 1.0, false, "in (0, 1] m")?);
        }
        "thickness_iterations" => {
            params.thickness.max_iterations = whole(1.0, 1e5, "a whole number from 1 to 100000")?;
        }
        _ => return Ok(false),
    }
    Ok(true)
}

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
        gas_amount: None,
        ambient: None,
        thickness: 3.0e-4,
        scale: 1.0,
        material: MaterialSpec::default(),
        params: DesignParams::default(),
        rest: None,
        out: None,
        overwrite: false,
    };
    let (mut has_target, mut has_pressure) = (false, false);
    let mut material_span: Span = None;
    let (mut gas_span, mut ambient_span): (Span, Span) = (None, None);
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
            "gas_amount" => {
                d.gas_amount = Some(
                    in_range(number()?, 0.0, 1e12, false, "a positive amount nRT in J")
                        .map_err(invalid)?,
                );
                has_pressure = true;
                gas_span = span.clone();
            }
            "ambient" => {
                d.ambient = Some(
                    in_range(
                        number()?,
                        0.0,
                        1e7,
                        false,
                        "a positive pressure in Pa, at most 1e7",
                    )
                    .map_err(invalid)?,
                );
                ambient_span = span.clone();
            }
            "thickness" => {
                d.thickness =
                    in_range(number()?, 0.0, 1.0, false, "in (0, 1] m").map_err(invalid)?;
            }
            "scale" => {
                d.scale = in_range(number()?, 0.0, 1e6, false, "in (0, 1e6]").map_err(invalid)?;
            }
            "out" => d.out = Some(PathBuf::from(path_of(text()?))),
            "overwrite" => {
                d.overwrite = value.as_bool().ok_or_else(|| {
                    err(format!(
                        "expected true or false, found {}",
                        type_name(value)
                    ))
                })?;
            }
            "rest" => {
                let s = text()?;
                d.rest = Some(if s.starts_with("builtin") {
                    s.to_owned()
                } else {
                    path_of(s)
                });
            }
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
                let option = match value {
                    toml_edit::Value::Float(f) => OptionValue::Number(*f.value()),
                    toml_edit::Value::Integer(i) => OptionValue::Number(*i.value() as f64),
                    toml_edit::Value::String(t) => OptionValue::Text(t.value().clone()),
                    toml_edit::Value::Boolean(b) => OptionValue::Bool(*b.value()),
                    v if DESIGN_OPTIONS.iter().any(|(k, _)| *k == key) => {
                        return Err(err(format!(
                            "expected a single value, found {}",
                            type_name(v)
                        )));
                    }
                    _ => OptionValue::Bool(false),
                };
                let known =
                    set_design_option(&mut d.params, key, &option).map_err(|e| match e {
                        OptionError::Expected(kind) => {
                            err(format!("expected {kind}, found {}", type_name(value)))
                        }
                        OptionError::Invalid(allowed) => invalid(allowed.to_owned()),
                    })?;
                if known {
                    continue;
                }
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
                "missing: [design] needs `target` and `pressure` (or `gas_amount`)".to_owned(),
            ));
        }
    }
    if d.gas_amount.is_some() && !d.pressure.is_nan() {
        return Err(src.key_error(
            gas_span,
            "design.gas_amount",
            "give the key pressure or the key gas_amount, not both".to_owned(),
        ));
    }
    if d.ambient.is_some() && d.gas_amount.is_none() {
        return Err(src.key_error(
            ambient_span,
            "design.ambient",
            "the key ambient is the ambient pressure of the key gas_amount, which is not given"
                .to_owned(),
        ));
    }
    d.material
        .resolve()
        .map_err(|m| src.key_error(material_span.or(table_span), "design.material", m))?;
    Ok(Some(d))
}
