//! `balloon mesh ...` (being filled in).

/// Mesh subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum MeshCommand {
    /// Print mesh statistics.
    Info,
}

/// Runs a mesh subcommand.
pub fn run(_cmd: MeshCommand) -> anyhow::Result<()> {
    anyhow::bail!("`balloon mesh info` is not built yet")
}
