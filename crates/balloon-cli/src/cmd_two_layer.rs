//! `balloon two_layer` (being filled in).

/// Arguments.
#[derive(Debug, clap::Args)]
pub struct TwoLayerArgs {}

/// Runs the subcommand.
pub fn run(_args: TwoLayerArgs) -> anyhow::Result<()> {
    anyhow::bail!("`balloon two_layer` is not built yet")
}
