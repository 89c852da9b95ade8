//! `balloon run SCENARIO.toml [FLAGS...]`: a run described by a scenario file.
//!
//! `[system] kind` selects the system: `shell` (the default, `balloon inflate`), `connect`
//! (`balloon connect`, keys [`CONNECT_KEYS`]: the shell's and a `[connect]` table, which also
//! selects it when there is no `kind`; read with [`connect_scenario_args`]), `volumetric`
//! (`balloon volumetric`, keys [`VOLUMETRIC_KEYS`]) or `two-layer` (`balloon two-layer`, keys
//! [`TWO_LAYER_KEYS`]); each system's keys are its command's flags.
//!
//! A scenario file holds the flags of a system's command grouped in tables, with the flag names
//! written with `_` for `-` (`frame_every = 5` is `--frame-every 5`). For the shell (`[system]
//! kind = "shell"`, the default) the tables are `[mesh]` (`path`, `scale`), `[shell]` (material
//! and wall), `[gas]` (`model` is `--gas`), `[run]` (time stepping, integrator and solver) and
//! `[output]`; [`SHELL_KEYS`] lists every key. Paths are relative to the scenario file.
//!
//! The file is turned into the argument list of `balloon inflate` and parsed by the same clap
//! parser ([`InflateArgs`]), so names, units, defaults and ranges are those of the flags by
//! construction. Flags after the file name override the file's keys. Each key of the file is
//! also checked on its own first, so that an unknown key, a wrong type or an out-of-range value
//! is reported with the file, the line and the key.
//!
//! A run with `--out DIR` records itself in `DIR/scenario.toml` ([`record`]): every value
//! resolved (defaults explicit, the mesh path absolute, the program version), so that
//! `balloon run DIR/scenario.toml --out DIR2` repeats the run.

use crate::cmd_connect::ConnectArgs;
use crate::cmd_inflate::InflateArgs;
use crate::cmd_two_layer::TwoLayerArgs;
use crate::cmd_volumetric::VolumetricArgs;
use anyhow::Result;
use clap::{ArgMatches, CommandFactory, Parser};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use toml_edit::{Item, Value};

/// Arguments of `balloon run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Scenario file (TOML, or JSON with the same tables as objects when it ends in `.json`): `[system] kind` (`shell`, `connect`, `volumetric` or `two-layer`) and tables
    /// (for the shell `[mesh]`, `[shell]`, `[gas]`, `[run]`, `[output]`) whose keys are the
    /// flags of that system's command with `_` for `-` (docs/scenarios.md). Paths in it are
    /// relative to the file.
    pub scenario: PathBuf,
    /// Flags of the system's command that override the file's values (e.g. `--dt 0.005 --out
    /// run2`).
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "FLAGS"
    )]
    pub overrides: Vec<String>,
}

/// The parser of `balloon inflate`'s flags, on their own (the argument list built from a
/// scenario file is parsed with it).
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
struct ShellCli {
    #[command(flatten)]
    args: InflateArgs,
}

/// The parser of `balloon connect`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
struct ConnectCli {
    #[command(flatten)]
    args: ConnectArgs,
}

/// The parser of `balloon volumetric`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
struct VolumetricCli {
    #[command(flatten)]
    args: VolumetricArgs,
}

/// The parser of `balloon two-layer`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
struct TwoLayerCli {
    #[command(flatten)]
    args: TwoLayerArgs,
}

/// The TOML type a key takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `true` gives the flag, `false` leaves it out.
    Bool,
    /// A flag with a default of its own (`--flag[=true|false]`, absent: the program decides):
    /// `true` gives `--flag=true`, `false` gives `--flag=false`.
    Switch,
    /// An integer or a float.
    Number,
    /// A list of numbers (a single number is a list of one): the comma-separated flags.
    Numbers,
    /// A string (a choice such as `"stvk"`, or a spec such as `"0,100,last"`).
    Text,
    /// A string naming a file or folder, relative to the scenario file.
    Path,
    /// A number or a string (`conductance = 5.0` or `conductance = "instant"`).
    NumberOrText,
    /// `--thickness-rule`: a string `AXIS:FROM:TO` or a table `{ axis, from, to }`.
    Rule,
    /// A repeatable flag written as an array of tables (`[[anchors]]` is `--pin`, `[[loads]]`
    /// is `--load`), one table per value: a selector and options as keys
    /// (`crate::cmd_run::table_value`), or the flag's value itself as `spec`.
    Tables,
}

/// One key of a scenario file: `[table] key`, the clap argument it sets, its type, and whether
/// the recorded scenario (`DIR/scenario.toml`) repeats it.
#[derive(Clone, Copy, Debug)]
pub struct ScenarioKey {
    /// Table name (`run` for `[run]`).
    pub table: &'static str,
    /// Key in the table (the flag's name with `_` for `-`, except `mesh.path` and `gas.model`).
    pub key: &'static str,
    /// The clap argument id (the field of [`InflateArgs`]).
    pub id: &'static str,
    /// The TOML type.
    pub kind: Kind,
    /// Whether the value is part of the recorded scenario; `false` for where and how the
    /// output is written (`out`, `overwrite`, `json`), which do not change the run.
    pub recorded: bool,
}

const fn k(table: &'static str, key: &'static str, id: &'static str, kind: Kind) -> ScenarioKey {
    ScenarioKey {
        table,
        key,
        id,
        kind,
        recorded: true,
    }
}

const fn unrecorded(
    table: &'static str,
    key: &'static str,
    id: &'static str,
    kind: Kind,
) -> ScenarioKey {
    ScenarioKey {
        recorded: false,
        ..k(table, key, id, kind)
    }
}

use Kind::{Bool, Number, NumberOrText, Numbers, Path as PathKind, Rule, Switch, Tables, Text};

/// Every key of a shell scenario, in the order the recorded scenario writes them. Each flag of
/// `balloon inflate` has exactly one key (a unit test checks it).
pub const SHELL_KEYS: &[ScenarioKey] = &[
    k("mesh", "path", "mesh", PathKind),
    k("mesh", "scale", "scale", Number),
    k("mesh", "transform", "transform", Numbers),
    k("shell", "material", "material", Text),
    k("shell", "material_preset", "material_preset", Text),
    k("shell", "young", "young", Number),
    k("shell", "poisson", "poisson", Number),
    k("shell", "mu", "mu", Number),
    k("shell", "c1", "c1", Number),
    k("shell", "c2", "c2", Number),
    k("shell", "jm", "jm", Number),
    k("shell", "ogden_mu", "ogden_mu", Numbers),
    k("shell", "ogden_alpha", "ogden_alpha", Numbers),
    k("shell", "yeoh", "yeoh", Numbers),
    k("shell", "thickness", "thickness", Number),
    k("shell", "thickness_file", "thickness_file", PathKind),
    k("shell", "thickness_rule", "thickness_rule", Rule),
    k("shell", "pin_stiffness", "pin_stiffness", Number),
    k("shell", "density", "density", Number),
    k("shell", "volume_projection", "volume_projection", Text),
    k("gas", "model", "gas", Text),
    k("gas", "pressure", "pressure", Number),
    k("gas", "ambient", "ambient", Number),
    k("gas", "pump_rate", "pump_rate", Number),
    k("gas", "gamma", "gamma", Number),
    k("gas", "leak_conductance", "leak_conductance", Number),
    k("gas", "supply_pressure", "supply_pressure", Number),
    k("gas", "volume_ratio", "volume_ratio", Number),
    k("gas", "volume_ratios", "volume_ratios", Text),
    k("run", "dt", "dt", Number),
    k("run", "steps", "steps", Number),
    k("run", "static", "static_solve", Bool),
    k("run", "until_converged", "until_converged", Bool),
    k("run", "speed_tol", "speed_tol", Number),
    k("run", "volume_tol", "volume_tol", Number),
    k("run", "mass_damping", "mass_damping", Number),
    k("run", "stiffness_damping", "stiffness_damping", Number),
    k("run", "newton_iters", "newton_iters", Number),
    k("run", "newton_tol", "newton_tol", Number),
    k("run", "linear_solver", "linear_solver", Text),
    k("run", "tangent", "tangent", Text),
    k("run", "pcg_preconditioner", "pcg_preconditioner", Text),
    k("run", "cg_tol", "cg_tol", Number),
    k("run", "inexact_forcing", "inexact_forcing", Number),
    k("run", "cg_max_iters", "cg_max_iters", Number),
    k("run", "follower_term", "follower_term", Switch),
    unrecorded("output", "out", "out", PathKind),
    unrecorded("output", "overwrite", "overwrite", Bool),
    unrecorded("output", "json", "json", Bool),
    k("output", "format", "format", Text),
    k("output", "frame_every", "frame_every", Number),
    k("output", "render", "render", Text),
    k("output", "color", "color", Text),
    k("output", "gif", "gif", Bool),
    k("output", "pov", "pov", Bool),
    k("output", "image_size", "image_size", Text),
    k("output", "color_range", "color_range", Text),
    k("anchors", "", "pin", Tables),
    k("loads", "", "load", Tables),
];

/// The keys of the `[connect]` table of a connected-balloons scenario (`balloon connect`).
const CONNECT_TABLE: &[ScenarioKey] = &[
    k("connect", "copies", "copies", Number),
    k("connect", "stretches", "stretches", Numbers),
    k("connect", "pressures", "pressures", Numbers),
    k("connect", "tubes", "tubes", Text),
    k("connect", "conductance", "conductance", NumberOrText),
    k("connect", "until_settled", "until_settled", Bool),
];

/// `a` followed by `b`, in a constant.
const fn concat<const N: usize>(a: &[ScenarioKey], b: &[ScenarioKey]) -> [ScenarioKey; N] {
    let mut out = [a[0]; N];
    let mut i = 0;
    while i < N {
        out[i] = if i < a.len() { a[i] } else { b[i - a.len()] };
        i += 1;
    }
    out
}

/// Every key of a connected-balloons scenario (`balloon connect`): the shell's keys
/// ([`SHELL_KEYS`]) and the `[connect]` table.
pub const CONNECT_KEYS: &[ScenarioKey] =
    &concat::<{ SHELL_KEYS.len() + CONNECT_TABLE.len() }>(SHELL_KEYS, CONNECT_TABLE);

/// Every key of a volumetric scenario (`balloon volumetric`, seed 003).
pub const VOLUMETRIC_KEYS: &[ScenarioKey] = &[
    k("mesh", "path", "mesh", PathKind),
    k("mesh", "scale", "scale", Number),
    k("mesh", "transform", "transform", Numbers),
    k("lattice", "resolution", "resolution", Number),
    k("lattice", "cells", "cells", Number),
    k("lattice", "voxels_per_cell", "voxels_per_cell", Number),
    k("lattice", "rays", "rays", Number),
    k("lattice", "band_voxels", "band_voxels", Number),
    k("lattice", "p_in", "p_in", Number),
    k("lattice", "p_subs", "p_subs", Number),
    k("lattice", "density_threshold", "density_threshold", Number),
    k("lattice", "fill_iterations", "fill_iterations", Number),
    k(
        "lattice",
        "smoothing_iterations",
        "smoothing_iterations",
        Number,
    ),
    k("lattice", "smoothing_weight", "smoothing_weight", Number),
    k("body", "soft_diagonals", "soft_diagonals", Bool),
    k("body", "edge_stiffness", "edge_stiffness", Number),
    k("body", "diagonal_stiffness", "diagonal_stiffness", Number),
    k("body", "damping", "damping", Number),
    k("body", "diagonal_damping", "diagonal_damping", Number),
    k("body", "density", "density", Number),
    k("body", "lumped_masses", "lumped_masses", Bool),
    k("body", "pin_stiffness", "pin_stiffness", Number),
    k("run", "scene", "scene", Text),
    k("run", "gravity", "gravity", Number),
    k("run", "restitution", "restitution", Number),
    k("run", "dt", "dt", Number),
    k("run", "steps", "steps", Number),
    k("run", "tolerance", "tolerance", Number),
    k("run", "over_relaxation", "over_relaxation", NumberOrText),
    k("run", "correction", "correction", Text),
    k("run", "volume_solver", "volume_solver", Text),
    unrecorded("output", "out", "out", PathKind),
    unrecorded("output", "overwrite", "overwrite", Bool),
    unrecorded("output", "json", "json", Bool),
    k("output", "format", "format", Text),
    k("output", "frame_every", "frame_every", Number),
    k("output", "lattice_frames", "lattice_frames", Bool),
    k("output", "render", "render", Text),
    k("output", "color", "color", Text),
    k("output", "gif", "gif", Bool),
    k("output", "pov", "pov", Bool),
    k("output", "image_size", "image_size", Text),
    k("output", "color_range", "color_range", Text),
    k("anchors", "", "pin", Tables),
    k("loads", "", "load", Tables),
];

/// Every key of a two-layer scenario (`balloon two-layer`, seed 004).
pub const TWO_LAYER_KEYS: &[ScenarioKey] = &[
    k("body", "dim", "dim", Number),
    k("body", "sphere", "sphere", Text),
    k("body", "level", "level", Number),
    k("body", "slices", "slices", Number),
    k("body", "stacks", "stacks", Number),
    k("body", "particles", "particles", Number),
    k("body", "length", "length", Number),
    k("body", "inner_radius", "inner_radius", Number),
    k("body", "outer_radius", "outer_radius", Number),
    k("body", "inner_mass", "inner_mass", Number),
    k("body", "outer_mass", "outer_mass", Number),
    k("body", "k_structural", "k_structural", Number),
    k("body", "k_radius", "k_radius", Number),
    k("body", "k_shear", "k_shear", Number),
    k("body", "k_shear_left", "k_shear_left", Number),
    k("body", "k_shear_right", "k_shear_right", Number),
    k("body", "damping", "damping", Number),
    k("body", "damping_structural", "damping_structural", Number),
    k("body", "damping_radius", "damping_radius", Number),
    k("body", "damping_shear", "damping_shear", Number),
    k(
        "body",
        "valence_normalization",
        "valence_normalization",
        Bool,
    ),
    k("gas", "pressure", "pressure", Number),
    k("gas", "inner_pressure", "inner_pressure", Number),
    k("run", "gravity", "gravity", Number),
    k("run", "box", "box_size", Number),
    k("run", "no_box", "no_box", Bool),
    k("run", "restitution", "restitution", Number),
    k("run", "integrator", "integrator", Text),
    k("run", "dt", "dt", Number),
    k("run", "steps", "steps", Number),
    k("run", "drag", "drag", Text),
    k("run", "drag_stiffness", "drag_stiffness", Number),
    k("run", "drag_damping", "drag_damping", Number),
    k("run", "pin_stiffness", "pin_stiffness", Number),
    unrecorded("output", "out", "out", PathKind),
    unrecorded("output", "overwrite", "overwrite", Bool),
    unrecorded("output", "json", "json", Bool),
    k("output", "format", "format", Text),
    k("output", "frame_every", "frame_every", Number),
    k("output", "render", "render", Text),
    k("output", "color", "color", Text),
    k("output", "gif", "gif", Bool),
    k("output", "pov", "pov", Bool),
    k("output", "image_size", "image_size", Text),
    k("output", "color_range", "color_range", Text),
    k("anchors", "", "pin", Tables),
    k("loads", "", "load", Tables),
];

/// A system a scenario can select with `[system] kind`: its keys and its flags' parser.
#[derive(Clone, Copy)]
pub struct System {
    /// The `kind` value (`shell`, `volumetric`, `two-layer`).
    pub kind: &'static str,
    /// Its keys.
    pub keys: &'static [ScenarioKey],
    /// Its flags' parser.
    command: fn() -> clap::Command,
}

/// The shell balloon (`balloon inflate`).
pub const SHELL: System = System {
    kind: "shell",
    keys: SHELL_KEYS,
    command: ShellCli::command,
};
/// Connected shell balloons (`balloon connect`).
pub const CONNECT: System = System {
    kind: "connect",
    keys: CONNECT_KEYS,
    command: ConnectCli::command,
};
/// The volumetric body (`balloon volumetric`).
pub const VOLUMETRIC: System = System {
    kind: "volumetric",
    keys: VOLUMETRIC_KEYS,
    command: VolumetricCli::command,
};
/// The two-layer body (`balloon two-layer`).
pub const TWO_LAYER: System = System {
    kind: "two-layer",
    keys: TWO_LAYER_KEYS,
    command: TwoLayerCli::command,
};

/// The systems a scenario can select with `[system] kind`.
const SYSTEMS: &[System] = &[SHELL, CONNECT, VOLUMETRIC, TWO_LAYER];

/// What is wrong with a scenario file.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file cannot be read.
    #[error("cannot read the scenario {}", path.display())]
    Read {
        /// The scenario file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML.
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
    /// A key or table is unknown, has the wrong type or an invalid value.
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
    /// A flag given after the scenario file (an override) is invalid on its own: the file is
    /// not to blame.
    #[error("command line (a flag after the scenario file): {message}")]
    Override {
        /// The parser's message, naming the flag (e.g. `invalid value '-1' for '--dt <DT>'`).
        message: String,
    },
    /// The combined arguments (file and command line) do not parse.
    #[error("{}: {message}", path.display())]
    Arguments {
        /// The scenario file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
}

/// A scenario file's text with its path, for errors with lines.
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
    /// For a JSON scenario, the JSON line of each line of `text` (its TOML translation).
    lines: Option<&'a [usize]>,
}

impl Source<'_> {
    /// The 1-based line of byte offset `at` (0 if unknown).
    fn line(&self, span: Option<std::ops::Range<usize>>) -> usize {
        let line = span.map_or(0, |s| {
            self.text[..s.start.min(self.text.len())]
                .bytes()
                .filter(|&b| b == b'\n')
                .count()
                + 1
        });
        match self.lines {
            Some(map) if line > 0 => map.get(line - 1).copied().unwrap_or(0),
            _ => line,
        }
    }

    fn key_error(
        &self,
        span: Option<std::ops::Range<usize>>,
        key: &str,
        message: String,
    ) -> ScenarioError {
        ScenarioError::Key {
            path: self.path.to_path_buf(),
            line: self.line(span),
            key: key.to_owned(),
            message,
        }
    }
}

/// One key of the file turned into arguments: its flag (`None` for the positional mesh) and
/// the arguments.
struct FileArg {
    long: Option<String>,
    args: Vec<String>,
}

/// The long flag name of argument `id` (`None` for the positional mesh).
fn long_of(cmd: &clap::Command, id: &str) -> Option<String> {
    cmd.get_arguments()
        .find(|a| a.get_id() == id)
        .and_then(|a| a.get_long())
        .map(str::to_owned)
}

/// The first line of a clap error without its `error: ` prefix.
fn clap_message(e: &clap::Error) -> String {
    let text = e.to_string();
    let line = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    line.strip_prefix("error: ").unwrap_or(line).to_owned()
}

/// The TOML type name of `v`, for errors.
fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "an array",
        Value::InlineTable(_) => "a table",
    }
}

/// A number of the file as a flag value (floats in Rust's round-trip form).
fn number_text(v: &Value) -> Option<String> {
    match v {
        Value::Integer(i) => Some(i.value().to_string()),
        Value::Float(f) => Some(format!("{:?}", f.value())),
        _ => None,
    }
}

/// The arguments of one key's value, or what is wrong with its type.
fn value_args(
    spec: &ScenarioKey,
    v: &Value,
    base: &Path,
    long: Option<&str>,
) -> Result<Vec<String>, String> {
    let flag = |value: String| match long {
        Some(l) => vec![format!("--{l}"), value],
        None => vec![value],
    };
    let expected = |what: &str| format!("expected {what}, found {}", type_name(v));
    match spec.kind {
        Bool => match v {
            Value::Boolean(b) if *b.value() => {
                Ok(long.map(|l| vec![format!("--{l}")]).unwrap_or_default())
            }
            Value::Boolean(_) => Ok(Vec::new()),
            _ => Err(expected("a boolean (true or false)")),
        },
        Switch => match v {
            Value::Boolean(b) => Ok(vec![match long {
                Some(l) => format!("--{l}={}", b.value()),
                None => b.value().to_string(),
            }]),
            _ => Err(expected("a boolean (true or false)")),
        },
        Number => number_text(v).map(flag).ok_or_else(|| expected("a number")),
        Numbers => {
            let list = match v {
                Value::Array(a) => a
                    .iter()
                    .map(number_text)
                    .collect::<Option<Vec<_>>>()
                    .filter(|l| !l.is_empty())
                    .ok_or_else(|| "expected a non-empty array of numbers".to_owned())?,
                _ => vec![number_text(v).ok_or_else(|| expected("an array of numbers"))?],
            };
            Ok(flag(list.join(",")))
        }
        Text => match v {
            Value::String(s) => Ok(flag(s.value().clone())),
            _ => Err(expected("a string")),
        },
        NumberOrText => match v {
            Value::String(s) => Ok(flag(s.value().clone())),
            _ => number_text(v)
                .map(flag)
                .ok_or_else(|| expected("a number or a string")),
        },
        Rule => match v {
            Value::String(s) => Ok(flag(s.value().clone())),
            Value::InlineTable(t) => {
                let axis = t.get("axis").and_then(Value::as_str);
                let from = t.get("from").and_then(number_text);
                let to = t.get("to").and_then(number_text);
                match (axis, from, to, t.len()) {
                    (Some(a), Some(f), Some(t), 3) => Ok(flag(format!("{a}:{f}:{t}"))),
                    _ => Err("expected { axis = \"x\"|\"y\"|\"z\", from = M, to = M } \
                              (m) or \"AXIS:FROM:TO\""
                        .to_owned()),
                }
            }
            _ => Err(expected(
                "a table { axis, from, to } or a string AXIS:FROM:TO",
            )),
        },
        Tables => Err(expected("an array of tables")),
        PathKind => match v {
            Value::String(s) => {
                let s = s.value();
                if spec.id == "mesh" && s.starts_with("builtin") {
                    Ok(flag(s.clone()))
                } else {
                    Ok(flag(base.join(s).to_string_lossy().into_owned()))
                }
            }
            _ => Err(expected("a string (a path relative to the scenario file)")),
        },
    }
}

/// The arguments of every key of a shell scenario, each checked on its own against the flags'
/// parser (so an error names its line and key).
fn file_args(
    system: &System,
    src: &Source<'_>,
    root: &toml_edit::Table,
    base: &Path,
    given: &[String],
) -> Result<Vec<FileArg>, ScenarioError> {
    let keys = system.keys;
    let cmd = (system.command)();
    let tables: Vec<&str> = {
        let mut t: Vec<&str> = keys.iter().map(|s| s.table).collect();
        t.dedup();
        t
    };
    let mut out = Vec::new();
    for (name, item) in root.iter() {
        let key_span = root.key(name).and_then(|k| k.span());
        if name == "system" {
            continue;
        }
        if let Some(spec) = keys.iter().find(|s| s.table == name && s.kind == Tables) {
            let Some(array) = item.as_array_of_tables() else {
                return Err(src.key_error(
                    key_span.or_else(|| item.span()),
                    name,
                    format!("expected an array of tables `[[{name}]]`"),
                ));
            };
            let long = long_of(&cmd, spec.id);
            for table in array.iter() {
                let value = table_value(spec.id, table, base)
                    .map_err(|(span, key, m)| src.key_error(span, &format!("{name}.{key}"), m))?;
                let args = vec![format!("--{}", long.as_deref().unwrap_or(spec.id)), value];
                let mut alone = vec!["balloon run".to_owned()];
                alone.extend(args.iter().cloned());
                if let Err(e) = cmd.clone().try_get_matches_from(&alone)
                    && !long.as_ref().is_some_and(|l| given.contains(l))
                {
                    let span = table.span().or(key_span.clone());
                    return Err(src.key_error(span, name, clap_message(&e)));
                }
                out.push(FileArg {
                    long: long.clone(),
                    args,
                });
            }
            continue;
        }
        let Some(table) = item.as_table_like().filter(|_| tables.contains(&name)) else {
            let message = if tables.contains(&name) {
                format!("expected a table `[{name}]`")
            } else if matches!(item, Item::Table(_) | Item::ArrayOfTables(_))
                || item.is_inline_table()
            {
                format!(
                    "unknown table (a {} scenario has [system], [{}])",
                    system.kind,
                    tables.join("], [")
                )
            } else {
                format!(
                    "a key outside any table (keys belong in [{}])",
                    tables.join("], [")
                )
            };
            return Err(src.key_error(key_span.or_else(|| item.span()), name, message));
        };
        for (key, value) in table.iter() {
            let span = table.key(key).and_then(|k| k.span());
            let full = format!("{name}.{key}");
            let Some(spec) = keys.iter().find(|s| s.table == name && s.key == key) else {
                let known: Vec<&str> = keys
                    .iter()
                    .filter(|s| s.table == name)
                    .map(|s| s.key)
                    .collect();
                return Err(src.key_error(
                    span,
                    &full,
                    format!(
                        "unknown key (the keys of [{name}] are {})",
                        known.join(", ")
                    ),
                ));
            };
            let Some(v) = value.as_value() else {
                return Err(src.key_error(
                    span,
                    &full,
                    "expected a value, found a table".to_owned(),
                ));
            };
            let long = long_of(&cmd, spec.id);
            let args = value_args(spec, v, base, long.as_deref())
                .map_err(|m| src.key_error(span.clone(), &full, m))?;
            // The key on its own through the flags' parser: its type and range (unless a flag
            // on the command line replaces it).
            let replaced = long.as_ref().is_some_and(|l| given.contains(l));
            let mut alone = vec!["balloon run".to_owned()];
            alone.extend(args.iter().cloned());
            if let Err(e) = cmd.clone().try_get_matches_from(&alone)
                && !replaced
            {
                return Err(src.key_error(span.clone(), &full, clap_message(&e)));
            }
            out.push(FileArg { long, args });
        }
    }
    Ok(out)
}

/// A selector key of an `[[anchors]]` or `[[loads]]` table as a selector spec
/// (`crate::selection::parse_selector`), `None` when `key` is not a selector key.
fn selector_value(key: &str, v: &Item, base: &Path) -> Option<Result<String, String>> {
    let list = |v: &Item| -> Result<Vec<String>, String> {
        v.as_array()
            .ok_or_else(|| "expected an array".to_owned())?
            .iter()
            .map(|x| number_text(x).ok_or_else(|| "expected numbers".to_owned()))
            .collect()
    };
    Some(match key {
        "indices" => list(v).map(|l| format!("indices:{}", l.join(","))),
        "box" => list(v).map(|l| format!("box:{}", l.join(","))),
        "vertices_file" => v
            .as_str()
            .map(|p| format!("file:{}", base.join(p).display()))
            .ok_or_else(|| "expected a path (relative to the scenario file)".to_owned()),
        "vertex_group" => {
            let t = v.as_inline_table();
            let file = t.and_then(|t| t.get("file")).and_then(Value::as_str);
            let property = t.and_then(|t| t.get("property")).and_then(Value::as_str);
            match (file, property, t.map_or(0, |t| t.len())) {
                (Some(f), Some(p), 2) => Ok(format!("ply:{}:{p}", base.join(f).display())),
                _ => Err(
                    "expected { file = \"PATH.ply\" (relative to the scenario file), property = \"NAME\" }"
                        .to_owned(),
                ),
            }
        }
        "below" | "above" => {
            let t = v.as_inline_table();
            let axis = t.and_then(|t| t.get("axis")).and_then(Value::as_str);
            let value = t.and_then(|t| t.get("value")).and_then(number_text);
            match (axis, value, t.map_or(0, |t| t.len())) {
                (Some(a), Some(x), 2) => Ok(format!("{key}:{a}:{x}")),
                _ => Err("expected { axis = \"x\"|\"y\"|\"z\", value = M }".to_owned()),
            }
        }
        _ => return None,
    })
}

/// The value of the flag `id` (`pin` or `load`) of one `[[anchors]]` / `[[loads]]` table, or
/// the span and key of what is wrong. A `spec` key is the flag's value as written on the
/// command line (its `file:` path relative to the scenario file).
fn table_value(
    id: &str,
    table: &toml_edit::Table,
    base: &Path,
) -> Result<String, (Option<std::ops::Range<usize>>, String, String)> {
    let mut selector: Option<String> = None;
    let mut parts: Vec<String> = Vec::new();
    let mut stiffness = None;
    let mut raw = None;
    let loads = id == "load";
    for (key, item) in table.iter() {
        let span = table.key(key).and_then(|k| k.span());
        let fail = |m: String| (span.clone(), key.to_owned(), m);
        if key == "spec" {
            let s = item
                .as_str()
                .ok_or_else(|| fail("expected a string".into()))?;
            raw = Some(crate::selection::rewrite_paths(id, s, Some(base)));
            continue;
        }
        if let Some(sel) = selector_value(key, item, base) {
            if selector.is_some() {
                return Err(fail(
                    "a second selector (one of indices, vertices_file, vertex_group, below, above, box)"
                        .into(),
                ));
            }
            selector = Some(sel.map_err(fail)?);
            continue;
        }
        let number = || {
            item.as_value()
                .and_then(number_text)
                .ok_or_else(|| fail("expected a number".into()))
        };
        match key {
            "stiffness" => stiffness = Some(number()?),
            "start" | "end" if loads => parts.push(format!("{key}={}", number()?)),
            "gravity" | "force" | "grab" if loads => {
                let v: Vec<String> = item
                    .as_array()
                    .map(|a| a.iter().filter_map(number_text).collect())
                    .filter(|v: &Vec<String>| v.len() == 3)
                    .ok_or_else(|| fail("expected an array of 3 numbers".into()))?;
                parts.insert(0, format!("{key}={}", v.join(",")));
            }
            "per" if loads => {
                let s = item
                    .as_str()
                    .ok_or_else(|| fail("expected a string".into()))?;
                parts.push(format!("per={s}"));
            }
            _ => {
                let known = if loads {
                    "gravity, force, grab, per, stiffness, start, end, indices, vertices_file, below, above, box, spec"
                } else {
                    "indices, vertices_file, below, above, box, stiffness, spec"
                };
                return Err(fail(format!("unknown key (the keys here are {known})")));
            }
        }
    }
    let whole = |m: &str| (table.span(), String::new(), m.to_owned());
    if let Some(r) = raw {
        if selector.is_some() || stiffness.is_some() || !parts.is_empty() {
            return Err(whole("`spec` stands alone"));
        }
        return Ok(r);
    }
    if loads {
        if let Some(k) = stiffness {
            parts.push(format!("stiffness={k}"));
        }
        if let Some(sel) = selector {
            parts.push(format!("on={sel}"));
        }
        Ok(parts.join(";"))
    } else {
        let sel = selector
            .ok_or_else(|| whole("no selector (indices, vertices_file, below, above or box)"))?;
        Ok(match stiffness {
            Some(k) => format!("{sel}@{k}"),
            None => sel,
        })
    }
}

/// The `--long` names given in `overrides` (`--dt 0.1` and `--dt=0.1` both give `dt`).
fn overridden(overrides: &[String]) -> Vec<String> {
    overrides
        .iter()
        .filter_map(|a| a.strip_prefix("--"))
        .map(|a| a.split_once('=').map_or(a, |(n, _)| n).to_owned())
        .collect()
}

/// The parsed `balloon inflate` arguments of a scenario file and its overrides, with the
/// argument matches (for the recorded scenario).
fn parse<C: Parser>(
    system: &System,
    path: &Path,
    files: Vec<FileArg>,
    overrides: &[String],
) -> Result<(C, ArgMatches), ScenarioError> {
    let given = overridden(overrides);
    // A mesh given on the command line replaces the file's.
    let has_positional = system.keys.iter().any(|k| k.id == "mesh")
        && overrides.iter().any(|a| !a.starts_with('-'))
        && (system.command)()
            .try_get_matches_from(
                std::iter::once("balloon run".to_owned()).chain(overrides.iter().cloned()),
            )
            .is_ok_and(|m| m.value_source("mesh") == Some(clap::parser::ValueSource::CommandLine));
    let mut argv: Vec<OsString> = vec!["balloon run".into()];
    for f in files {
        let skip = match &f.long {
            Some(l) => given.contains(l),
            None => has_positional,
        };
        if !skip {
            argv.extend(f.args.into_iter().map(OsString::from));
        }
    }
    argv.extend(overrides.iter().map(OsString::from));
    let fail = |e: clap::Error| ScenarioError::Arguments {
        path: path.to_path_buf(),
        message: clap_message(&e),
    };
    let matches = match (system.command)().try_get_matches_from(argv) {
        Ok(m) => m,
        Err(e) => {
            // The overrides on their own: if they fail, the command line is to blame, not the
            // file (whose keys were each checked on their own already).
            let alone = (system.command)().try_get_matches_from(
                std::iter::once("balloon run".to_owned()).chain(overrides.iter().cloned()),
            );
            return Err(match alone {
                Err(o) => ScenarioError::Override {
                    message: clap_message(&o),
                },
                Ok(_) => fail(e),
            });
        }
    };
    let cli = C::from_arg_matches(&matches).map_err(fail)?;
    Ok((cli, matches))
}

/// A scenario file read: its TOML text (a JSON file's translation), the JSON line of each
/// TOML line for a JSON file, the parsed document and the system.
type ReadScenario = (
    String,
    Option<Vec<usize>>,
    toml_edit::Document<String>,
    System,
);

/// Reads and checks a scenario file: its text, its TOML and its `[system] kind`. A file
/// ending in `.json` is a JSON scenario ([`crate::scenario_json`]).
fn read(path: &Path) -> Result<ReadScenario, ScenarioError> {
    let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let (text, lines) = if json {
        let c = crate::scenario_json::to_toml(&text).map_err(|e| ScenarioError::Json {
            path: path.to_path_buf(),
            line: e.line,
            message: e.message,
        })?;
        (c.toml, Some(c.lines))
    } else {
        (text, None)
    };
    let doc = toml_edit::Document::parse(text.clone()).map_err(|e| {
        let src = Source {
            path,
            text: &text,
            lines: lines.as_deref(),
        };
        ScenarioError::Syntax {
            path: path.to_path_buf(),
            line: src.line(e.span()),
            message: e.message().trim().to_owned(),
        }
    })?;
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    // A `[connect]` table selects the connected balloons unless `[system] kind` says otherwise.
    let mut system = if doc.as_table().contains_key("connect") {
        CONNECT
    } else {
        SHELL
    };
    if let Some(item) = doc.as_table().get("system") {
        let span = doc.as_table().key("system").and_then(|k| k.span());
        let table = item.as_table_like().ok_or_else(|| {
            src.key_error(span, "system", "expected a table `[system]`".to_owned())
        })?;
        for (key, value) in table.iter() {
            let span = table.key(key).and_then(|k| k.span());
            let full = format!("system.{key}");
            // `version`: the program version that recorded the scenario (information only).
            if key == "version" {
                if !value.is_str() {
                    return Err(src.key_error(span, &full, "expected a string".to_owned()));
                }
                continue;
            }
            if key != "kind" {
                return Err(src.key_error(
                    span,
                    &full,
                    "unknown key (the keys of [system] are kind and version)".to_owned(),
                ));
            }
            match value.as_str() {
                Some(s) if SYSTEMS.iter().any(|y| y.kind == s) => {
                    system = SYSTEMS
                        .iter()
                        .copied()
                        .find(|y| y.kind == s)
                        .unwrap_or(SHELL);
                }
                Some(s) => {
                    return Err(src.key_error(
                        span,
                        &full,
                        format!(
                            "`{s}` is not a system (the systems are {})",
                            SYSTEMS
                                .iter()
                                .map(|y| y.kind)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ));
                }
                None => return Err(src.key_error(span, &full, "expected a string".to_owned())),
            }
        }
    }
    Ok((text, lines, doc, system))
}

/// The `balloon inflate` arguments of a shell scenario file with command-line overrides; the
/// arguments carry their recorded scenario ([`record`]).
#[cfg(test)]
pub fn shell_args(path: &Path, overrides: &[String]) -> Result<InflateArgs, ScenarioError> {
    match scenario_args(path, overrides)? {
        SystemArgs::Shell(a) => Ok(*a),
        _ => Err(ScenarioError::Arguments {
            path: path.to_path_buf(),
            message: "not a shell scenario ([system] kind)".to_owned(),
        }),
    }
}

/// The arguments of the command a scenario file runs, with their recorded scenario.
#[derive(Debug)]
pub enum SystemArgs {
    /// `balloon inflate`.
    Shell(Box<InflateArgs>),
    /// `balloon volumetric`.
    Volumetric(Box<VolumetricArgs>),
    /// `balloon two-layer`.
    TwoLayer(Box<TwoLayerArgs>),
}

/// The arguments of a scenario file with command-line overrides, for the system its
/// `[system] kind` selects; the arguments carry their recorded scenario ([`record`]).
pub fn scenario_args(path: &Path, overrides: &[String]) -> Result<SystemArgs, ScenarioError> {
    let (text, lines, doc, system) = read(path)?;
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let files = file_args(&system, &src, doc.as_table(), &base, &overridden(overrides))?;
    Ok(match system.kind {
        "volumetric" => {
            let (c, m) = parse::<VolumetricCli>(&system, path, files, overrides)?;
            let mut a = c.args;
            a.scenario_record = Some(record(&system, &m));
            SystemArgs::Volumetric(Box::new(a))
        }
        "two-layer" => {
            let (c, m) = parse::<TwoLayerCli>(&system, path, files, overrides)?;
            let mut a = c.args;
            a.scenario_record = Some(record(&system, &m));
            SystemArgs::TwoLayer(Box::new(a))
        }
        "connect" => {
            return Err(ScenarioError::Arguments {
                path: path.to_path_buf(),
                message: "a connected-balloons scenario ([connect]): read it with \
                          `connect_scenario_args` (`balloon run` does)"
                    .to_owned(),
            });
        }
        _ => {
            let (c, m) = parse::<ShellCli>(&system, path, files, overrides)?;
            let mut a = c.args;
            a.scenario_record = Some(record(&system, &m));
            SystemArgs::Shell(Box::new(a))
        }
    })
}

/// The `balloon connect` arguments of a connected-balloons scenario file (`[system] kind =
/// "connect"`, or a `[connect]` table) with command-line overrides, carrying their recorded
/// scenario ([`record`]). `None` when the file is another system's (read it with
/// [`scenario_args`]).
pub fn connect_scenario_args(
    path: &Path,
    overrides: &[String],
) -> Result<Option<ConnectArgs>, ScenarioError> {
    let (text, lines, doc, system) = read(path)?;
    if system.kind != CONNECT.kind {
        return Ok(None);
    }
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let files = file_args(&system, &src, doc.as_table(), &base, &overridden(overrides))?;
    let (c, m) = parse::<ConnectCli>(&system, path, files, overrides)?;
    let mut a = c.args;
    a.shell.scenario_record = Some(record(&system, &m));
    Ok(Some(a))
}

/// A string as a TOML basic string.
fn toml_string(s: &str) -> String {
    Value::from(s).to_string().trim().to_owned()
}

/// A flag's raw value as a TOML number: an integer if it is one, else a float in round-trip
/// form (so the recorded run reads back the same `f64`).
fn toml_number(raw: &str) -> String {
    let raw = raw.trim();
    if let Ok(i) = raw.parse::<i64>() {
        return i.to_string();
    }
    match raw.parse::<f64>() {
        Ok(f) if f.is_finite() => format!("{f:?}"),
        _ => toml_string(raw),
    }
}

/// The recorded scenario of a run of `system` (`DIR/scenario.toml`): every key with its
/// effective value (given or default), the mesh path absolute, the program version. A flag
/// without a value and without a default (e.g. `--pump-rate`, whose default follows the body)
/// is written as a comment. `matches` are those of the system command's arguments.
pub fn record(system: &System, matches: &ArgMatches) -> String {
    let mut s = format!(
        "# The scenario of a `balloon` {} run, every value resolved (defaults explicit).\n\
         # Repeat it with: balloon run scenario.toml --out OTHER_DIR\n\
         # (the output folder, --overwrite and --json are not part of the scenario).\n\n\
         [system]\nkind = {}\nversion = {}\n",
        env!("CARGO_PKG_VERSION"),
        toml_string(system.kind),
        toml_string(env!("CARGO_PKG_VERSION")),
    );
    let mut table = "system";
    for spec in system.keys.iter().filter(|s| s.recorded) {
        if spec.kind == Tables {
            let values = matches.try_get_raw(spec.id).ok().flatten();
            for raw in values.into_iter().flatten() {
                let value = crate::selection::rewrite_paths(spec.id, &raw.to_string_lossy(), None);
                s.push_str(&format!(
                    "\n[[{}]]\nspec = {}\n",
                    spec.table,
                    toml_string(&value)
                ));
                table = spec.table;
            }
            continue;
        }
        if spec.table != table {
            table = spec.table;
            s.push_str(&format!("\n[{table}]\n"));
        }
        let line = match spec.kind {
            Bool | Switch => matches
                .try_get_one::<bool>(spec.id)
                .ok()
                .flatten()
                .map(|b| b.to_string()),
            _ => matches.try_get_raw(spec.id).ok().flatten().map(|raw| {
                let raw: Vec<String> = raw.map(|r| r.to_string_lossy().into_owned()).collect();
                match spec.kind {
                    Number | NumberOrText => toml_number(&raw.join(",")),
                    Numbers => format!(
                        "[{}]",
                        raw.iter()
                            .map(|r| toml_number(r))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                    PathKind if !raw.concat().starts_with("builtin") => {
                        let p = PathBuf::from(raw.concat());
                        toml_string(&std::path::absolute(&p).unwrap_or(p).to_string_lossy())
                    }
                    _ => toml_string(&raw.join(",")),
                }
            }),
        };
        match line {
            Some(v) => s.push_str(&format!("{} = {v}\n", spec.key)),
            None => s.push_str(&format!(
                "# {} = (not set: the flag's default applies)\n",
                spec.key
            )),
        }
    }
    s
}

/// Runs `balloon run`.
pub fn run(args: RunArgs) -> Result<()> {
    if let Some(a) = connect_scenario_args(&args.scenario, &args.overrides)? {
        return crate::cmd_connect::run(a);
    }
    match scenario_args(&args.scenario, &args.overrides)? {
        SystemArgs::Shell(a) => crate::cmd_inflate::run(*a),
        SystemArgs::Volumetric(a) => crate::cmd_volumetric::run(*a),
        SystemArgs::TwoLayer(a) => crate::cmd_two_layer::run(*a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_flag_of_each_system_has_exactly_one_key_of_the_right_kind() {
        for system in SYSTEMS {
            every_flag_has_one_key(system);
        }
    }

    fn every_flag_has_one_key(system: &System) {
        let cmd = (system.command)();
        for arg in cmd.get_arguments() {
            let id = arg.get_id().as_str();
            if id == "help" || id == "version" {
                continue;
            }
            let specs: Vec<_> = system.keys.iter().filter(|s| s.id == id).collect();
            assert_eq!(
                specs.len(),
                1,
                "argument `{id}` has {} scenario keys",
                specs.len()
            );
            let is_flag = matches!(arg.get_action(), clap::ArgAction::SetTrue);
            assert_eq!(
                specs[0].kind == Bool,
                is_flag,
                "argument `{id}`: kind {:?}",
                specs[0].kind
            );
        }
        for spec in system.keys {
            assert!(
                cmd.get_arguments().any(|a| a.get_id() == spec.id),
                "key {}.{} names no argument `{}`",
                spec.table,
                spec.key,
                spec.id
            );
        }
    }

    #[test]
    fn the_recorded_scenario_of_the_defaults_reads_back_to_the_same_arguments() {
        let m = ShellCli::command()
            .try_get_matches_from(["balloon run", "--dt", ".005", "--ogden-mu", "1,2"])
            .unwrap();
        let text = record(&SHELL, &m);
        assert!(text.contains("dt = 0.005\n"), "{text}");
        assert!(text.contains("steps = 300\n"), "{text}");
        assert!(text.contains("ogden_mu = [1, 2]\n"), "{text}");
        assert!(text.contains("# pump_rate = "), "{text}");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, &text).unwrap();
        let back = shell_args(&path, &[]).unwrap();
        assert_eq!(back.dt, 0.005);
        assert_eq!(back.steps, 300);
        assert_eq!(back.material.ogden_mu, Some(vec![1.0, 2.0]));
        assert_eq!(back.scenario_record.as_deref(), Some(text.as_str()));
    }

    #[test]
    fn errors_name_the_line_and_the_key() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        let cases = [
            ("[run]\nsteps = 5\ndtt = 0.1\n", 3, "run.dtt", "unknown key"),
            ("[run]\n\ndt = \"fast\"\n", 3, "run.dt", "expected a number"),
            ("[run]\ndt = 2.0\n", 2, "run.dt", "--dt"),
            (
                "[mesh]\nscale = 1\n[anchor]\nx = 1\n",
                3,
                "anchor",
                "unknown table",
            ),
            (
                "[mesh]\nscale = 1\n[anchors]\nx = 1\n",
                3,
                "anchors",
                "array of tables",
            ),
            (
                "[[anchors]]\nbelow = { axis = \"w\", value = 0 }\n",
                1,
                "anchors",
                "axis",
            ),
            (
                "[[anchors]]\nindices = [1]\nbox = [0, 0, 0, 1, 1, 1]\n",
                3,
                "anchors.box",
                "second selector",
            ),
            (
                "[[loads]]\ngravity = [0, 0]\n",
                2,
                "loads.gravity",
                "3 numbers",
            ),
            (
                "[shell]\nthickness_rule = { axis = \"z\", from = 1e-4 }\n",
                2,
                "shell.thickness_rule",
                "axis",
            ),
            (
                "[run]\nuntil_converged = 1\n",
                2,
                "run.until_converged",
                "boolean",
            ),
            (
                "[system]\nkind = \"bogus\"\n",
                2,
                "system.kind",
                "not a system",
            ),
        ];
        for (text, line, key, what) in cases {
            std::fs::write(&path, text).unwrap();
            let e = shell_args(&path, &[]).unwrap_err().to_string();
            let place = format!("s.toml:{line}: `{key}`");
            assert!(e.contains(&place) && e.contains(what), "{text:?}: {e}");
        }
        std::fs::write(&path, "[run\n").unwrap();
        let e = shell_args(&path, &[]).unwrap_err().to_string();
        assert!(e.contains("s.toml:1: not valid TOML"), "{e}");
    }

    #[test]
    fn anchors_loads_and_thickness_keys_become_flags_and_are_recorded() {
        use crate::selection::{LoadKind, Selector};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            "[shell]\nthickness_file = \"wall.txt\"\npin_stiffness = 50\n\
             [[anchors]]\nvertices_file = \"neck.txt\"\n\
             [[anchors]]\nbelow = { axis = \"z\", value = 0.01 }\nstiffness = 200\n\
             [[anchors]]\nspec = \"box:0,0,0,1,1,1\"\n\
             [[loads]]\ngravity = [0, 0, -9.81]\n\
             [[loads]]\nforce = [0, 0.5, 0]\nper = \"total\"\nindices = [3, 4]\nstart = 0.1\nend = 0.2\n\
             [[loads]]\ngrab = [0, 0, 1]\nstiffness = 10\nabove = { axis = \"y\", value = 0.3 }\n",
        )
        .unwrap();
        let a = shell_args(&path, &[]).unwrap();
        assert_eq!(a.setup.thickness_file, Some(dir.path().join("wall.txt")));
        assert_eq!(a.setup.pin_stiffness, Some(50.0));
        assert_eq!(a.setup.pin.len(), 3);
        assert_eq!(
            a.setup.pin[0].selector,
            Selector::File(dir.path().join("neck.txt"))
        );
        assert_eq!(a.setup.pin[1].stiffness, Some(200.0));
        assert_eq!(a.setup.load.len(), 3);
        assert_eq!(a.setup.load[0].kind, LoadKind::Gravity([0.0, 0.0, -9.81]));
        assert_eq!((a.setup.load[1].start, a.setup.load[1].end), (0.1, 0.2));
        assert!(matches!(
            a.setup.load[2].kind,
            LoadKind::Grab {
                stiffness: 10.0,
                ..
            }
        ));
        // The recorded scenario repeats them and reads back to the same arguments.
        let text = a.scenario_record.clone().unwrap();
        assert_eq!(text.matches("[[anchors]]").count(), 3, "{text}");
        assert_eq!(text.matches("[[loads]]").count(), 3, "{text}");
        let rec = dir.path().join("r.toml");
        std::fs::write(&rec, &text).unwrap();
        let b = shell_args(&rec, &[]).unwrap();
        assert_eq!(b.setup.pin, a.setup.pin);
        assert_eq!(b.setup.load, a.setup.load);
        assert_eq!(b.setup.thickness_file, a.setup.thickness_file);
        // A --pin on the command line replaces the file's anchors; a rule as a table.
        std::fs::write(
            &path,
            "[shell]\nthickness_rule = { axis = \"z\", from = 3e-4, to = 6e-4 }\n[[anchors]]\nindices = [1]\n",
        )
        .unwrap();
        let c = shell_args(&path, &["--pin".into(), "indices:7".into()]).unwrap();
        assert_eq!(c.setup.pin.len(), 1);
        assert_eq!(c.setup.pin[0].selector, Selector::Indices(vec![7]));
        let rule = c.setup.thickness_rule.unwrap();
        assert_eq!((rule.axis, rule.from, rule.to), (2, 3e-4, 6e-4));
    }

    #[test]
    fn an_invalid_override_names_the_flag_not_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, "[run]\ndt = 0.02\nsteps = 7\n").unwrap();
        for (flags, named) in [
            (vec!["--dt", "-1"], "'--dt <DT>'"),
            (vec!["--dt=nan"], "'--dt <DT>'"),
            (vec!["--steps", "x"], "'--steps <STEPS>'"),
            (vec!["--bogus"], "'--bogus'"),
        ] {
            let flags: Vec<String> = flags.into_iter().map(String::from).collect();
            let e = shell_args(&path, &flags).unwrap_err();
            assert!(
                matches!(e, ScenarioError::Override { .. }),
                "{flags:?}: {e:?}"
            );
            let text = e.to_string();
            assert!(
                text.contains(named)
                    && text.starts_with("command line")
                    && !text.contains("s.toml"),
                "{flags:?}: {text}"
            );
        }
        // A bad value in the file still names the file, its line and key.
        std::fs::write(&path, "[run]\ndt = -1\n").unwrap();
        let e = shell_args(&path, &[]).unwrap_err().to_string();
        assert!(e.contains("s.toml:2: `run.dt`"), "{e}");
    }

    #[test]
    fn connect_scenarios_read_their_table_and_record_it() {
        use balloon::shell::connected::Conductance;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            "[mesh]\npath = \"builtin:icosphere\"\n[connect]\ncopies = 2\nstretches = [1.35, 1.6]\n\
             conductance = 2.5\ntubes = \"0-1\"\n[run]\ndt = 0.02\n",
        )
        .unwrap();
        let a = connect_scenario_args(&path, &[])
            .unwrap()
            .expect("a [connect] table selects the connected balloons");
        assert_eq!(a.copies, Some(2));
        assert_eq!(a.stretches, Some(vec![1.35, 1.6]));
        assert_eq!(a.conductance, Conductance::Finite(2.5));
        assert_eq!(a.shell.dt, 0.02);
        let text = a.shell.scenario_record.clone().unwrap();
        assert!(text.contains("kind = \"connect\""), "{text}");
        assert!(text.contains("conductance = 2.5\n"), "{text}");
        let rec = dir.path().join("r.toml");
        std::fs::write(&rec, &text).unwrap();
        let b = connect_scenario_args(&rec, &["--conductance".into(), "instant".into()])
            .unwrap()
            .expect("the record is a connect scenario");
        assert_eq!(b.stretches, a.stretches);
        assert_eq!(b.conductance, Conductance::Instant);
        // Another system's file is not a connect scenario, and a connect file is not theirs.
        assert!(connect_scenario_args(&rec.with_file_name("none.toml"), &[]).is_err());
        std::fs::write(dir.path().join("shell.toml"), "[run]\ndt = 0.02\n").unwrap();
        assert!(
            connect_scenario_args(&dir.path().join("shell.toml"), &[])
                .unwrap()
                .is_none()
        );
        assert!(scenario_args(&rec, &[]).is_err());
        // Keys of the table are checked like the others.
        std::fs::write(&path, "[connect]\nconductance = true\n").unwrap();
        let e = scenario_args(&path, &[]).unwrap_err().to_string();
        assert!(
            e.contains("s.toml:2: `connect.conductance`") && e.contains("a number or a string"),
            "{e}"
        );
        std::fs::write(&path, "[connect]\ncopies = 0\n").unwrap();
        let e = scenario_args(&path, &[]).unwrap_err().to_string();
        assert!(
            e.contains("`connect.copies`") && e.contains("--copies"),
            "{e}"
        );
    }

    #[test]
    fn flags_override_the_file_and_paths_are_relative_to_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            "[mesh]\npath = \"m.obj\"\n[run]\ndt = 0.02\nsteps = 7\n",
        )
        .unwrap();
        let a = shell_args(&path, &["--dt".into(), "0.005".into()]).unwrap();
        assert_eq!(a.dt, 0.005);
        assert_eq!(a.steps, 7);
        assert_eq!(PathBuf::from(&a.mesh), dir.path().join("m.obj"));
        let a = shell_args(&path, &["--steps=9".into()]).unwrap();
        assert_eq!((a.dt, a.steps), (0.02, 9));
    }
}
