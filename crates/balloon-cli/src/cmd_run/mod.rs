//! `balloon run SCENARIO.toml [FLAGS...]`: a run described by a scenario file.
//!
//! The file is read into a typed scenario by `balloon_scenario::file::read` (its keys are the
//! flags of the system's command, grouped in tables; docs/scenarios.md): every error names the
//! file, the line and the key. Flags after the file name are that command's flags and override
//! the file's keys: they are parsed by the command's own parser, and the parameters they give
//! replace the file's. The run is then the command's job; with `--out DIR` it records its
//! resolved scenario in `DIR/scenario.toml`, so that `balloon run DIR/scenario.toml --out DIR2`
//! repeats the run.

use crate::cmd_connect::ConnectArgs;
use crate::cmd_inflate::ShellCli;
use crate::cmd_two_layer::TwoLayerArgs;
use crate::cmd_volumetric::VolumetricArgs;
use crate::scenario_cli::{Invocation, cli_error, typed};
use anyhow::Result;
use balloon_scenario::keys::Literals;
use balloon_scenario::{Scenario, SystemKind};
use clap::{CommandFactory, FromArgMatches, Parser};
use std::path::{Path, PathBuf};

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

/// The parser of `balloon connect`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
pub struct ConnectCli {
    /// The flags.
    #[command(flatten)]
    pub args: ConnectArgs,
}

/// The parser of `balloon volumetric`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
pub struct VolumetricCli {
    /// The flags.
    #[command(flatten)]
    pub args: VolumetricArgs,
}

/// The parser of `balloon two-layer`'s flags, on their own.
#[derive(Debug, Parser)]
#[command(name = "balloon run")]
pub struct TwoLayerCli {
    /// The flags.
    #[command(flatten)]
    pub args: TwoLayerArgs,
}

/// Each system with the parser of its command's flags.
pub fn commands() -> [(SystemKind, clap::Command); 4] {
    [
        (SystemKind::Shell, ShellCli::command()),
        (SystemKind::Connect, ConnectCli::command()),
        (SystemKind::Volumetric, VolumetricCli::command()),
        (SystemKind::TwoLayer, TwoLayerCli::command()),
    ]
}

/// The first line of a clap error without its `error: ` prefix.
fn clap_message(e: &clap::Error) -> String {
    let text = e.to_string();
    let line = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    line.strip_prefix("error: ").unwrap_or(line).to_owned()
}

/// A flag after the scenario file that does not parse: the command line is to blame, not the
/// file.
#[derive(Debug, thiserror::Error)]
#[error("command line (a flag after the scenario file): {0}")]
pub struct OverrideError(pub String);

/// The scenario of `overrides` alone (the system's flags after the file), with the parameters
/// they give and the text typed for each.
fn overrides_of(
    kind: SystemKind,
    overrides: &[String],
) -> Result<(Scenario, Literals, Vec<&'static str>), OverrideError> {
    let argv = std::iter::once("balloon run".to_owned()).chain(overrides.iter().cloned());
    let fail = |e: clap::Error| OverrideError(clap_message(&e));
    let (scenario, matches) = match kind {
        SystemKind::Shell => {
            let m = crate::negative_values(ShellCli::command())
                .try_get_matches_from(argv)
                .map_err(fail)?;
            let a = ShellCli::from_arg_matches(&m).map_err(fail)?;
            (Scenario::Shell(a.args.scenario()), m)
        }
        SystemKind::Connect => {
            let m = crate::negative_values(ConnectCli::command())
                .try_get_matches_from(argv)
                .map_err(fail)?;
            let a = ConnectCli::from_arg_matches(&m).map_err(fail)?;
            (Scenario::Connect(a.args.scenario()), m)
        }
        SystemKind::Volumetric => {
            let m = crate::negative_values(VolumetricCli::command())
                .try_get_matches_from(argv)
                .map_err(fail)?;
            let a = VolumetricCli::from_arg_matches(&m).map_err(fail)?;
            (Scenario::Volumetric(a.args.scenario()), m)
        }
        SystemKind::TwoLayer => {
            let m = crate::negative_values(TwoLayerCli::command())
                .try_get_matches_from(argv)
                .map_err(fail)?;
            let a = TwoLayerCli::from_arg_matches(&m).map_err(fail)?;
            (Scenario::TwoLayer(a.args.scenario()), m)
        }
    };
    let (literals, given) = typed(kind, &matches);
    Ok((scenario, literals, given))
}

/// The checked scenario of a scenario file with command-line `overrides` (the flags of the
/// file's system), with the values as typed (the file's, then the flags').
pub fn scenario_of(path: &Path, overrides: &[String]) -> Result<Invocation> {
    let kind = balloon_scenario::file::system_of(path)?;
    let (over, over_literals, given) = overrides_of(kind, overrides)?;
    let file = balloon_scenario::file::read(path, &given)?;
    let mut scenario = file.scenario;
    let mut literals = file.literals;
    for name in &given {
        scenario.copy_from(&over, name);
        match over_literals.get(name) {
            Some(t) => literals.set(name, t.to_vec()),
            None => literals.remove(name),
        }
    }
    scenario
        .validate()
        .map_err(|e| cli_error(e, &literals, &given))?;
    Ok(Invocation { scenario, literals })
}

/// Runs `balloon run`.
pub fn run(args: RunArgs) -> Result<()> {
    if let Some(design) = balloon_scenario::design::read(&args.scenario)? {
        return run_design(&args, &design);
    }
    let call = scenario_of(&args.scenario, &args.overrides)?;
    let record = call.record();
    match &call.scenario {
        Scenario::Shell(s) => {
            balloon_run::jobs::shell::run(s, None, Some(&record), false).map(drop)
        }
        Scenario::Connect(s) => balloon_run::jobs::connect::run(s, Some(&record), false).map(drop),
        Scenario::Volumetric(s) => {
            balloon_run::jobs::volumetric::run(s, None, Some(&record), false).map(drop)
        }
        Scenario::TwoLayer(s) => {
            balloon_run::jobs::two_layer::run(s, Some(&record), false).map(drop)
        }
    }
}

/// Runs a scenario's `[design]` table: the job of `balloon design` with the table's keys.
fn run_design(args: &RunArgs, d: &balloon_scenario::design::DesignScenario) -> Result<()> {
    if !args.overrides.is_empty() {
        anyhow::bail!(
            "{}: a [design] scenario takes no flags after the file (give the keys in the file, \
             or use `balloon design`)",
            args.scenario.display()
        );
    }
    let mut job = balloon_run::jobs::design::DesignJob::new(
        crate::cmd_design::load_target(&d.target, d.scale)?,
        d.target.clone(),
        d.pressure,
    );
    job.gas_amount = d.gas_amount;
    if let Some(a) = d.ambient {
        job.ambient = a;
    }
    job.thickness = d.thickness;
    job.material = d.material.clone();
    job.params = d.params;
    job.out.clone_from(&d.out);
    job.overwrite = d.overwrite;
    job.rest = d
        .rest
        .as_deref()
        .map(|r| crate::cmd_design::load_rest(r, d.scale))
        .transpose()?;
    job.quiet = false;
    crate::cmd_design::report(&job, &balloon_run::jobs::design::run(&job)?)
}

#[cfg(test)]
mod tests;
