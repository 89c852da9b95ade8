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
pub mod cmd_design;
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

pub use scenario_cli::error_chain;

/// `cmd` (and its subcommands) with every flag that takes a value accepting a negative number
/// as that value, so `--steps -1` reaches the flag's own parser and is refused with the flag's
/// range, instead of clap reading `-1` as an unknown flag ("unexpected argument '-1'").
pub fn negative_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if a.get_action().takes_values() && !a.is_positional() {
            a.allow_negative_numbers(true)
        } else {
            a
        }
    })
    .mut_subcommands(negative_values)
}
