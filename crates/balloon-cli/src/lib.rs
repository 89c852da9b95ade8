//! The library behind the `balloon` command-line tool: every subcommand's flags (clap
//! structures), the simulations they build and the shared run loop with its output folder.
//!
//! It exists so that other front ends build and run exactly what the CLI builds and runs, with
//! the same flags, defaults, units and validation: the binary (`src/main.rs`) is a thin
//! dispatcher over it, and the Python package (`python/`, crate `balloon-py`) turns keyword
//! options into these flags and calls the same functions. It is not a stable Rust API for
//! simulations: use the `balloon` crate's builders for that.
//!
//! ```
//! use balloon_cli::cmd_inflate::InflateArgs;
//! use clap::Parser;
//!
//! #[derive(Parser)]
//! struct Cli {
//!     #[command(flatten)]
//!     args: InflateArgs,
//! }
//! // `balloon inflate builtin:sphere --steps 2 --gas constant`, parsed as the CLI parses it.
//! let cli = Cli::try_parse_from(["balloon", "builtin:sphere", "--steps", "2", "--gas", "constant"])
//!     .unwrap();
//! assert_eq!(cli.args.steps, 2);
//! assert_eq!(cli.args.pressure, balloon::shell::DEFAULT_GAUGE_PRESSURE);
//! ```

pub mod cmd_connect;
pub mod cmd_inflate;
pub mod cmd_mesh;
pub mod cmd_run;
pub mod cmd_static;
pub mod cmd_two_layer;
pub mod cmd_view;
pub mod cmd_volumetric;
pub mod interrupt;
pub mod material_args;
pub mod output;
pub mod params;
pub mod run;
pub mod scenario_json;
pub mod selection;

/// The error and its causes joined by `: `, skipping a cause whose text the message already
/// contains (library errors often include their source in their own message): the message the
/// CLI prints after `error: ` and the Python package raises.
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
    msg
}
