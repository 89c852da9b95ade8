//! The `balloon` command-line tool.
//!
//! Subcommands: `mesh info` (inspect a mesh), `inflate` (shell balloons, Wang et al. 2015), `connect`
//! (shell balloons joined by tubes),
//! `volumetric` (volume-conserving bodies, Diziol, Bender and Bayer 2011) and `two-layer` (two-layer objects, Song 2009),
//! `run` (a shell run described by a scenario file) and `view` (a live viewer in the browser).
//! Run `balloon <subcommand> --help` for the flags and their defaults.

use balloon_cli::{
    cmd_connect, cmd_design, cmd_inflate, cmd_mesh, cmd_run, cmd_two_layer, cmd_view,
    cmd_volumetric, interrupt,
};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// Simulate inflatable thin shells and volume-conserving soft bodies.
#[derive(Debug, Parser)]
#[command(name = "balloon", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Inspect meshes.
    #[command(subcommand)]
    Mesh(cmd_mesh::MeshCommand),
    /// Inflate a shell balloon with thickness (three-prism FEM, Wang et al. 2015). With no MESH, the
    /// built-in teddy.
    Inflate(cmd_inflate::InflateArgs),
    /// Connect several shell balloons, each with its own ideal gas, by tubes (the two-balloon
    /// experiment): copies of one mesh or the components of one file, pre-inflated to stretches
    /// or pressures; every `inflate` flag applies.
    Connect(cmd_connect::ConnectArgs),
    /// Simulate a volume-conserving impulse-based body generated from a triangle soup (Diziol, Bender and Bayer 2011).
    Volumetric(cmd_volumetric::VolumetricArgs),
    /// Simulate a two-layer elastic object (Song 2009).
    TwoLayer(cmd_two_layer::TwoLayerArgs),
    /// Run a scenario file (TOML; `[system] kind` selects `shell` (`inflate`), `connect`,
    /// `volumetric` or `two-layer`, whose flags are the keys, grouped in tables); flags after
    /// the file override it (docs/scenarios.md).
    Run(cmd_run::RunArgs),
    /// Design the rest shape that inflates to a target shape at a given pressure (inverse
    /// statics, docs/design.md), checked by a forward static solve.
    Design(cmd_design::DesignArgs),
    /// Watch and steer a simulation live in the browser (local server, loopback only).
    View(cmd_view::ViewArgs),
}

fn main() -> std::process::ExitCode {
    let matches = balloon_cli::negative_values(Cli::command()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // The subcommand's matches: the values as typed, for the recorded scenario and errors.
    let sub = |name: &str| {
        matches
            .subcommand_matches(name)
            .cloned()
            .unwrap_or_default()
    };
    if matches!(
        cli.command,
        Command::Inflate(_)
            | Command::Connect(_)
            | Command::Volumetric(_)
            | Command::TwoLayer(_)
            | Command::Run(_)
            | Command::Design(_)
    ) && let Err(e) = interrupt::install()
    {
        eprintln!(
            "warning: cannot handle SIGINT / SIGTERM ({e}); an interrupted run writes no summary"
        );
    }
    let result = match cli.command {
        Command::Mesh(c) => cmd_mesh::run(c),
        Command::Inflate(a) => cmd_inflate::run(&a, &sub("inflate")),
        Command::Connect(a) => cmd_connect::run(&a, &sub("connect")),
        Command::Volumetric(a) => cmd_volumetric::run(&a, &sub("volumetric")),
        Command::TwoLayer(a) => cmd_two_layer::run(&a, &sub("two-layer")),
        Command::Run(a) => cmd_run::run(a),
        Command::View(a) => cmd_view::run(a),
        Command::Design(a) => cmd_design::run(&a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // A reader that stopped reading (`balloon mesh info FILE | head -1`) is not an error.
        Err(e) if is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", balloon_cli::error_chain(&e));
            match e.downcast_ref::<interrupt::Interrupted>() {
                Some(i) => std::process::ExitCode::from(i.exit_code()),
                None => std::process::ExitCode::FAILURE,
            }
        }
    }
}

/// Whether `e` comes from writing to a closed pipe (stdout's reader went away).
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .map(std::io::Error::kind)
            .or_else(|| {
                c.downcast_ref::<serde_json::Error>()
                    .and_then(serde_json::Error::io_error_kind)
            })
            == Some(std::io::ErrorKind::BrokenPipe)
    })
}
