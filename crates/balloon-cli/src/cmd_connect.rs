//! `balloon connect [MESH|builtin]`: several shell balloons, each with its own isothermal ideal
//! gas, joined by tubes (the two-balloon experiment): its flags, turned into a
//! `balloon_scenario::connect::ConnectScenario` and run by `balloon_run::jobs::connect`.
//!
//! The balloons are either `--copies N` of one mesh, placed side by side along x, or the
//! connected components of the mesh. Each is pre-inflated statically to a linear stretch
//! (`--stretches`) or starts at rest holding the ideal gas at a gauge pressure
//! (`--pressures`), then the tubes (`--tubes`, default a chain) let gas flow with a
//! conductance (`--conductance`, m^3/s, or `instant`). Every other flag is `balloon
//! inflate`'s, parsed by the same [`InflateArgs`].

use crate::cmd_inflate::InflateArgs;
use crate::scenario_cli::{Invocation, job_error};
use anyhow::Result;
use balloon::shell::connected::Conductance;
use balloon_run::Finished;
use balloon_scenario::Scenario;
use balloon_scenario::connect::{ConnectScenario, ConnectTable, TubeList, parse_conductance};
use balloon_scenario::range::{parse_real, parse_whole};

pub use balloon_scenario::connect::{ConnectSim, split_components};

/// Arguments of `balloon connect`: those of `balloon inflate` and the connection's.
#[derive(Debug, clap::Args)]
pub struct ConnectArgs {
    /// The flags of `balloon inflate` (mesh, material, wall, time stepping, solvers, output).
    /// The gas is the isothermal ideal gas (`--gas ideal`, the only one allowed); `--static`,
    /// `--pressure`, `--pump-rate`, `--pin` and `--load` are refused.
    #[command(flatten)]
    pub shell: InflateArgs,
    /// Connect N copies of the mesh (1 to 1000), placed side by side along x; without it, the
    /// balloons are the mesh's connected components.
    #[arg(long, value_parser = parse_whole)]
    pub copies: Option<usize>,
    /// Pre-inflate each balloon statically to this linear stretch (V / V0)^(1/3), each in
    /// [1, 10] (below 1 the membrane would crumple), comma-separated, one per balloon; it then
    /// holds that gas.
    #[arg(long, value_delimiter = ',', num_args = 1, conflicts_with = "pressures",
          value_parser = parse_real)]
    pub stretches: Option<Vec<f64>>,
    /// Start each balloon at rest holding the ideal gas at this gauge pressure (Pa, each in
    /// [-1e7, 1e7]), comma-separated, one per balloon.
    #[arg(long, value_delimiter = ',', num_args = 1, allow_hyphen_values = true,
          value_parser = parse_real)]
    pub pressures: Option<Vec<f64>>,
    /// Tubes as `A-B` pairs of 0-based balloon indices, comma-separated (e.g. `0-1,1-2`);
    /// default: a chain 0-1, 1-2, ...
    #[arg(long)]
    pub tubes: Option<TubeList>,
    /// Conductance of every tube, m^3/s in (0, 1e6] (flow in nRT units = conductance x
    /// pressure difference), or `instant` (the joined balloons share one pressure after every
    /// step).
    #[arg(long, default_value = "instant", allow_hyphen_values = true, value_parser = parse_conductance)]
    pub conductance: Conductance,
    /// Stop when, for 20 steps in a row, every balloon's per-step relative gas volume change is
    /// below --volume-tol and its largest vertex speed below --speed-tol (--steps is then the
    /// most steps). `--until-converged` means the same here.
    #[arg(long)]
    pub until_settled: bool,
}

impl ConnectArgs {
    /// The scenario of these flags (every key, given or default).
    pub fn scenario(&self) -> ConnectScenario {
        ConnectScenario {
            shell: self.shell.scenario(),
            connect: ConnectTable {
                copies: self.copies,
                stretches: self.stretches.clone(),
                pressures: self.pressures.clone(),
                tubes: self.tubes.clone(),
                conductance: self.conductance,
                until_settled: self.until_settled,
            },
        }
    }
}

/// Runs `balloon connect` (`matches`: the subcommand's, for the values as typed).
pub fn run(args: &ConnectArgs, matches: &clap::ArgMatches) -> Result<()> {
    let call = Invocation::of(Scenario::Connect(args.scenario()), matches)?;
    let Scenario::Connect(s) = &call.scenario else {
        unreachable!("a connect scenario")
    };
    balloon_run::jobs::connect::run(s, Some(&call.record()), false).map(drop)
}

/// Runs the job of `balloon connect` for `args` (checks, build, the output folder, the steps,
/// the summary) and returns the summary with the final balloons; `quiet` prints nothing. No
/// scenario is recorded.
pub fn execute(args: &ConnectArgs, quiet: bool) -> Result<Finished<ConnectSim>> {
    let s = args.scenario();
    s.validate().map_err(job_error)?;
    balloon_run::jobs::connect::run(&s, None, quiet)
}
