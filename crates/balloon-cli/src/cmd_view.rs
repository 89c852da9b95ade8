//! `balloon view`: the live browser viewer (being written for issue 7).

use clap::Args;

/// Arguments of `balloon view`.
#[derive(Debug, Args)]
pub struct ViewArgs {}

/// Runs the viewer.
pub fn run(_args: ViewArgs) -> anyhow::Result<()> {
    anyhow::bail!("`balloon view` is not implemented yet")
}
