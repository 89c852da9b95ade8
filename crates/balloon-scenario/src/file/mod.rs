//! Scenario files: TOML (or JSON with the same tables, [`json`]) read into a typed
//! [`Scenario`] with every error at its file, line and key ([`read`]), and the recorded
//! scenario a run writes to `OUT/scenario.toml` ([`record`]), which reads back to the same run.
//!
//! `[system] kind` selects the system: `shell` (the default), `connect` (also selected by a
//! `[connect]` table), `volumetric` or `two-layer`. The other tables hold the system's keys
//! ([`crate::keys`]); paths are relative to the file.
//!
//! ```
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("s.toml");
//! std::fs::write(&path, "[run]\nsteps = 5\ndtt = 0.1\n").unwrap();
//! let e = balloon_scenario::file::read(&path, &[]).unwrap_err();
//! assert!(e.to_string().ends_with("s.toml:3: `run.dtt`: unknown key (the keys of [run] are \
//!     dt, steps, static, stability, until_converged, speed_tol, volume_tol, mass_damping, \
//!     stiffness_damping, newton_iters, newton_tol, linear_solver, tangent, \
//!     pcg_preconditioner, cg_tol, inexact_forcing, cg_max_iters, follower_term, \
//!     thickness_prediction)"));
//! std::fs::write(&path, "[mesh]\npath = \"builtin:icosphere\"\n[run]\nsteps = 5\n").unwrap();
//! let file = balloon_scenario::file::read(&path, &[]).unwrap();
//! let text = balloon_scenario::file::record(&file.scenario, &file.literals);
//! assert!(text.contains("\n[run]\ndt = 0.01\nsteps = 5\n"));
//! ```

pub mod json;
mod record;
mod tables;

pub use record::{record, record_json, resolve_shell_record};

use crate::error::ScenarioError;
use crate::keys::{Kind, Literals};
use crate::scenario::{KeyInfo, Scenario, SystemKind};
use crate::value::{SetError, Value};
use std::path::{Path, PathBuf};
use tables::number_text;
use toml_edit::Item;

/// A scenario file read: the scenario, the text of each value as written (for the recorded
/// scenario and errors) and the file's path.
#[derive(Clone, Debug)]
pub struct ScenarioFile {
    /// The typed scenario.
    pub scenario: Scenario,
    /// The text of each value the file gives.
    pub literals: Literals,
    /// The file.
    pub path: PathBuf,
}

/// A scenario file's text with its path, for errors with lines.
pub(crate) struct Source<'a> {
    pub(crate) path: &'a Path,
    pub(crate) text: &'a str,
    /// For a JSON scenario, the JSON line of each line of `text` (its TOML translation).
    pub(crate) lines: Option<&'a [usize]>,
}

pub(crate) type Span = Option<std::ops::Range<usize>>;

impl Source<'_> {
    /// The 1-based line of a span's start (0 if unknown).
    fn line(&self, span: Span) -> usize {
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

    pub(crate) fn key_error(&self, span: Span, key: &str, message: String) -> ScenarioError {
        ScenarioError::Key {
            path: self.path.to_path_buf(),
            line: self.line(span),
            key: key.to_owned(),
            message,
        }
    }
}

/// A TOML value as an untyped [`Value`].
pub(crate) fn value_of(v: &toml_edit::Value) -> Value {
    use toml_edit::Value as T;
    match v {
        T::String(s) => Value::Text(s.value().clone()),
        T::Integer(i) => Value::Int(*i.value()),
        T::Float(f) => Value::Float(*f.value()),
        T::Boolean(b) => Value::Bool(*b.value()),
        T::Datetime(d) => Value::Text(d.value().to_string()),
        T::Array(a) => Value::List(a.iter().map(value_of).collect()),
        T::InlineTable(t) => {
            Value::Table(t.iter().map(|(k, v)| (k.to_owned(), value_of(v))).collect())
        }
    }
}

/// The TOML type name of `v`, for errors.
pub(crate) fn type_name(v: &toml_edit::Value) -> &'static str {
    use toml_edit::Value as T;
    match v {
        T::String(_) => "a string",
        T::Integer(_) => "an integer",
        T::Float(_) => "a float",
        T::Boolean(_) => "a boolean",
        T::Datetime(_) => "a date",
        T::Array(_) => "an array",
        T::InlineTable(_) => "a table",
    }
}

/// The value a key of the file gives, as the setter takes it (a path joined to the file's
/// folder), with its text as written; or what is wrong with its type.
fn file_value(
    key: &KeyInfo,
    v: &toml_edit::Value,
    base: &Path,
) -> Result<(Value, Option<Vec<String>>), String> {
    let expected = |what: &str| format!("expected {what}, found {}", type_name(v));
    match key.kind {
        Kind::Path => match v.as_str() {
            Some(s) if key.name == "mesh" && s.starts_with("builtin") => {
                Ok((Value::Text(s.to_owned()), None))
            }
            Some(s) => Ok((
                Value::Text(base.join(s).to_string_lossy().into_owned()),
                None,
            )),
            None => Err(expected("a string (a path relative to the scenario file)")),
        },
        Kind::Number | Kind::NumberOrText => {
            let text = number_text(v).or_else(|| v.as_str().map(str::to_owned));
            Ok((value_of(v), text.map(|t| vec![t])))
        }
        Kind::Numbers => {
            let list = match v {
                toml_edit::Value::Array(a) => a.iter().map(number_text).collect(),
                _ => number_text(v).map(|t| vec![t]),
            };
            Ok((value_of(v), list))
        }
        Kind::Text => Ok((value_of(v), v.as_str().map(|s| vec![s.to_owned()]))),
        Kind::Rule => {
            let value = value_of(v);
            let text = crate::shell::rule_text(&value).ok();
            Ok((value, text.map(|t| vec![t])))
        }
        Kind::Bool | Kind::Switch | Kind::Tables => Ok((value_of(v), None)),
    }
}

/// What a setter's error says in a file: the type error, or `invalid value 'X': why`.
fn set_message(e: SetError, literal: Option<&str>) -> String {
    match e {
        SetError::Type(m) => m,
        SetError::Value(e) => {
            let value = literal.unwrap_or(&e.value).to_owned();
            let why = e.reason.or(e.hint);
            match why {
                Some(r) => format!("invalid value '{value}': {r}"),
                None => format!("invalid value '{value}'"),
            }
        }
    }
}

/// Reads a scenario file (TOML, or JSON when it ends in `.json`): every key is typed and
/// range-checked with its line, except the range of the parameters named in `replaced` (given
/// elsewhere, e.g. command-line flags that override the file: the final
/// [`Scenario::validate`] checks their values). The keys across tables (the material, the
/// gas laws, ...) are left to [`Scenario::validate`].
pub fn read(path: &Path, replaced: &[&str]) -> Result<ScenarioFile, ScenarioError> {
    let (text, lines, doc) = parse(path)?;
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    let kind = system(&src, doc.as_table())?;
    let base = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let mut scenario = Scenario::new(kind);
    let mut literals = Literals::default();
    read_tables(
        &src,
        doc.as_table(),
        &base,
        replaced,
        &mut scenario,
        &mut literals,
    )?;
    Ok(ScenarioFile {
        scenario,
        literals,
        path: path.to_path_buf(),
    })
}

/// The system a scenario file describes (`[system] kind`, or `connect` for a `[connect]`
/// table), without reading its other keys.
pub fn system_of(path: &Path) -> Result<SystemKind, ScenarioError> {
    let (text, lines, doc) = parse(path)?;
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    system(&src, doc.as_table())
}

/// A file's TOML text (a JSON file's translation), the JSON line of each TOML line, and the
/// parsed document.
pub(crate) type Parsed = (String, Option<Vec<usize>>, toml_edit::Document<String>);

/// Reads and parses a scenario file.
pub(crate) fn parse(path: &Path) -> Result<Parsed, ScenarioError> {
    // A FIFO, a device or a directory is refused before it is opened, a file over the limit
    // before it is read.
    let text = balloon::mesh::io::read_input_text(path, balloon::mesh::io::MAX_TEXT_INPUT_BYTES)
        .map_err(|e| ScenarioError::Read {
            path: path.to_path_buf(),
            source: e.into_io(),
        })?;
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let (text, lines) = if is_json {
        let c = json::to_toml(&text).map_err(|e| ScenarioError::Json {
            path: path.to_path_buf(),
            line: e.line,
            message: e.message,
        })?;
        (c.toml, Some(c.lines))
    } else {
        (text, None)
    };
    let src = Source {
        path,
        text: &text,
        lines: lines.as_deref(),
    };
    let doc = toml_edit::Document::parse(text.clone()).map_err(|e| ScenarioError::Syntax {
        path: path.to_path_buf(),
        line: src.line(e.span()),
        message: e.message().trim().to_owned(),
    })?;
    // An empty file (or only comments) would run every default: refused, it is surely a
    // mistake (a truncated or wrong file).
    if doc.as_table().is_empty() {
        return Err(ScenarioError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok((text, lines, doc))
}

/// The system of the file: `[system] kind`, or `connect` when there is a `[connect]` table.
fn system(src: &Source<'_>, root: &toml_edit::Table) -> Result<SystemKind, ScenarioError> {
    let mut system = if root.contains_key("connect") {
        SystemKind::Connect
    } else {
        SystemKind::Shell
    };
    let Some(item) = root.get("system") else {
        return Ok(system);
    };
    let span = root.key("system").and_then(|k| k.span());
    let table = item
        .as_table_like()
        .ok_or_else(|| src.key_error(span, "system", "expected a table `[system]`".to_owned()))?;
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
            Some(s) => {
                system = s.parse().map_err(|_| {
                    src.key_error(
                        span.clone(),
                        &full,
                        format!(
                            "`{s}` is not a system (the systems are {})",
                            SystemKind::NAMES.join(", ")
                        ),
                    )
                })?;
            }
            None => return Err(src.key_error(span, &full, "expected a string".to_owned())),
        }
    }
    Ok(system)
}

/// Sets every key of the file's tables on `scenario`, each checked on its own (so an error
/// names its line and key).
fn read_tables(
    src: &Source<'_>,
    root: &toml_edit::Table,
    base: &Path,
    replaced: &[&str],
    scenario: &mut Scenario,
    literals: &mut Literals,
) -> Result<(), ScenarioError> {
    let keys = Scenario::keys(scenario.kind());
    let tables: Vec<&str> = {
        let mut t: Vec<&str> = keys.iter().map(|k| k.table).collect();
        t.dedup();
        t
    };
    for (name, item) in root.iter() {
        let key_span = root.key(name).and_then(|k| k.span());
        if name == "system" {
            continue;
        }
        if let Some(key) = keys
            .iter()
            .find(|k| k.table == name && k.kind == Kind::Tables)
        {
            let Some(array) = item.as_array_of_tables() else {
                return Err(src.key_error(
                    key_span.or_else(|| item.span()),
                    name,
                    format!("expected an array of tables `[[{name}]]`"),
                ));
            };
            let mut specs = Vec::new();
            for table in array.iter() {
                let spec = tables::table_value(key.name, table, base)
                    .map_err(|(span, k, m)| src.key_error(span, &format!("{name}.{k}"), m))?;
                // The spec on its own (unless the parameter is given elsewhere).
                if let Err(e) = scenario.set(key.name, &Value::Text(spec.clone()))
                    && !replaced.contains(&key.name)
                {
                    let span = table.span().or(key_span.clone());
                    return Err(src.key_error(span, name, set_message(e, None)));
                }
                specs.push(Value::Text(spec));
            }
            if !replaced.contains(&key.name) {
                scenario
                    .set(key.name, &Value::List(specs))
                    .map_err(|e| src.key_error(key_span.clone(), name, set_message(e, None)))?;
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
                    scenario.kind(),
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
            let Some(info) = keys.iter().find(|k| k.table == name && k.key == key) else {
                let known: Vec<&str> = keys
                    .iter()
                    .filter(|k| k.table == name)
                    .map(|k| k.key)
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
            let (value, texts) =
                file_value(info, v, base).map_err(|m| src.key_error(span.clone(), &full, m))?;
            let literal = texts.as_ref().map(|t| t.join(","));
            let given_elsewhere = replaced.contains(&info.name);
            match scenario.set(info.name, &value) {
                Ok(()) => {}
                Err(e @ SetError::Type(_)) => {
                    return Err(src.key_error(span, &full, set_message(e, None)));
                }
                Err(e) if !given_elsewhere => {
                    return Err(src.key_error(span, &full, set_message(e, literal.as_deref())));
                }
                Err(_) => {}
            }
            if !given_elsewhere && let Err(e) = scenario.check(info.name) {
                let typed = literals_for(&texts, e.index).unwrap_or(&e.value);
                let why = e.reason.clone().or(e.hint.clone()).unwrap_or_default();
                return Err(src.key_error(span, &full, format!("invalid value '{typed}': {why}")));
            }
            match texts {
                Some(t) => literals.set(info.name, t),
                None => literals.remove(info.name),
            }
        }
    }
    Ok(())
}

/// The text of element `index` (or the only one) of a key's texts; `None` for an error about
/// a whole list of several values (its own value then shows them all).
fn literals_for(texts: &Option<Vec<String>>, index: Option<usize>) -> Option<&str> {
    let texts = texts.as_ref()?;
    if index.is_none() && texts.len() > 1 {
        return None;
    }
    texts.get(index.unwrap_or(0)).map(String::as_str)
}

#[cfg(test)]
mod tests;
