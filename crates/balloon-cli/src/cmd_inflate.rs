//! `balloon inflate` (being filled in).

/// Arguments.
#[derive(Debug, clap::Args)]
pub struct InflateArgs {}

/// Runs the subcommand.
pub fn run(_args: InflateArgs) -> anyhow::Result<()> {
    anyhow::bail!("`balloon inflate` is not built yet")
}
