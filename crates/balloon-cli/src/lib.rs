//! The library behind the `balloon` command-line tool: every subcommand's flags (clap
//! structures), which become the typed scenario of `balloon-scenario`, and the spelling of the
//! library's errors as flags.
//!
//! It is a thin client: the scenario (its keys, defaults, ranges, checks and the building of
//! each simulation) is `balloon-scenario`'s, the run loop and the output folder are
//! `balloon-run`'s, shared with the Python package. It is not a Rust API for simulations: use
//! `balloon` and `balloon-scenario` for that.
//!
//! ```
//! use balloon_cli::cmd_inflate::ShellCli;
//! use clap::Parser;
//! // `balloon inflate builtin:sphere --steps 2 --gas constant`, parsed as the CLI parses it.
//! let cli = ShellCli::try_parse_from(["balloon", "builtin:sphere", "--steps", "2", "--gas", "constant"])
//!     .unwrap();
//! assert_eq!(cli.args.steps, 2);
//! assert_eq!(cli.args.pressure, balloon::shell::DEFAULT_GAUGE_PRESSURE);
//! let scenario = cli.args.scenario();
//! assert_eq!(scenario.run.steps, 2);
//! assert_eq!(scenario.gas.model, balloon_scenario::gas::GasControl::Constant);
//! ```

pub mod choices;
pub mod cmd_connect;
pub mod cmd_inflate;
pub mod cmd_mesh;
pub mod cmd_run;
pub mod cmd_two_layer;
pub mod cmd_view;
pub mod cmd_volumetric;
pub mod interrupt;
pub mod material_args;
pub mod params;
pub mod pictures;
pub mod scenario_cli;
pub mod selection;

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
    balloon_scenario::names::respell(&msg, balloon_scenario::names::Spelling::Flag)
}
