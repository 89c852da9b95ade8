//! `balloon volumetric` (being filled in).

/// Arguments.
#[derive(Debug, clap::Args)]
pub struct VolumetricArgs {}

/// Runs the subcommand.
pub fn run(_args: VolumetricArgs) -> anyhow::Result<()> {
    anyhow::bail!("`balloon volumetric` is not built yet")
}
