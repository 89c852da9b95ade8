//! From the command line to a checked scenario: the values as the user typed them (for the
//! recorded scenario and for errors), the flags given, and the library's errors in the
//! command line's words.

use anyhow::Result;
use balloon_scenario::keys::{Kind, Literals};
use balloon_scenario::names::{Spelling, flag_of, value_message};
use balloon_scenario::{Scenario, ScenarioError, SystemKind};
use clap::ArgMatches;
use clap::parser::ValueSource;

/// The clap argument id of parameter `name` (the field of the flags' struct).
pub fn arg_id(name: &str) -> &str {
    match name {
        "static" => "static_solve",
        "box" => "box_size",
        other => other,
    }
}

/// The parameters of system `kind` given on the command line in `matches`, with the text
/// typed for each value (numbers and texts; one per element of a list).
pub fn typed(kind: SystemKind, matches: &ArgMatches) -> (Literals, Vec<&'static str>) {
    let mut literals = Literals::default();
    let mut given = Vec::new();
    for key in Scenario::keys(kind) {
        let id = arg_id(key.name);
        if !matches.ids().any(|i| i.as_str() == id)
            || matches.value_source(id) != Some(ValueSource::CommandLine)
        {
            continue;
        }
        given.push(key.name);
        if matches!(
            key.kind,
            Kind::Number | Kind::Numbers | Kind::NumberOrText | Kind::Text | Kind::Rule
        ) && let Ok(Some(raw)) = matches.try_get_raw(id)
        {
            literals.set(
                key.name,
                raw.map(|r| r.to_string_lossy().into_owned()).collect(),
            );
        }
    }
    (literals, given)
}

/// A library error as the command line reports it: a value error shows the text typed and
/// the flag the way the parser names it (`invalid value '1e308' for '--dt <DT>': ...`),
/// prefixed when the flag came after a scenario file (`overrides`); other errors are left to
/// `main`, which spells every backticked parameter as its flag.
pub fn cli_error(e: ScenarioError, literals: &Literals, overrides: &[&str]) -> anyhow::Error {
    match e {
        ScenarioError::Value(v) => {
            let message = value_message(&v, Spelling::Flag, literals.typed(&v));
            if overrides.contains(&v.name.as_str()) {
                anyhow::anyhow!("command line (a flag after the scenario file): {message}")
            } else {
                anyhow::anyhow!(message)
            }
        }
        e => anyhow::Error::new(e),
    }
}

/// A library error of a scenario built without the typed values (the library's form of each
/// value).
pub fn job_error(e: ScenarioError) -> anyhow::Error {
    cli_error(e, &Literals::default(), &[])
}

/// A checked scenario from the command line, with the values as typed.
#[derive(Debug)]
pub struct Invocation {
    /// The scenario.
    pub scenario: Scenario,
    /// The text typed for each value given.
    pub literals: Literals,
}

impl Invocation {
    /// The scenario of a subcommand's flags (`matches`: the subcommand's), checked.
    pub fn of(scenario: Scenario, matches: &ArgMatches) -> Result<Self> {
        let (literals, _) = typed(scenario.kind(), matches);
        scenario
            .validate()
            .map_err(|e| cli_error(e, &literals, &[]))?;
        Ok(Self { scenario, literals })
    }

    /// The recorded scenario (`OUT/scenario.toml`, and the summary's `scenario`).
    pub fn record(&self) -> String {
        balloon_scenario::file::record(&self.scenario, &self.literals)
    }
}

/// The error and its causes joined by `: `, skipping a cause whose text the message already
/// contains (library errors often include their source in their own message), with every
/// backticked parameter name spelled as its flag (`` `dt` `` becomes `--dt`): the message the
/// CLI prints after `error: `.
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    balloon_scenario::names::respell(&msg, Spelling::Flag)
}

/// The flag (`--dt`) of parameter `name`, for messages.
pub fn flag(name: &str) -> String {
    format!("--{}", flag_of(name).unwrap_or(name))
}
