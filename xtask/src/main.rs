//! Project automation for the `balloon` workspace.
//!
//! * `cargo xtask ci`: format check, clippy with warnings denied, docs with warnings denied, the
//!   whole test suite, and every criterion bench once in test mode. `.ci/run` calls exactly this.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use std::process::Command;

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "balloon project automation")]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// fmt --check, clippy -D warnings, doc -D warnings, tests, benches in test mode.
    Ci {
        /// Skip clippy and docs (faster local runs).
        #[arg(long)]
        quick: bool,
    },
}

fn cargo(args: &[&str], envs: &[(&str, &str)]) -> Result<()> {
    eprintln!("xtask: cargo {}", args.join(" "));
    let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    cmd.args(args);
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let status = cmd
        .status()
        .with_context(|| format!("failed to start cargo {}", args.join(" ")))?;
    if !status.success() {
        bail!("`cargo {}` failed ({status})", args.join(" "));
    }
    Ok(())
}

fn ci(quick: bool) -> Result<()> {
    cargo(&["fmt", "--all", "--", "--check"], &[])?;
    if !quick {
        cargo(
            &[
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ],
            &[],
        )?;
        cargo(
            &["doc", "--workspace", "--no-deps"],
            &[("RUSTDOCFLAGS", "-D warnings")],
        )?;
    }
    cargo(&["test", "--workspace"], &[])?;
    cargo(&["bench", "-p", "balloon-benches", "--", "--test"], &[])?;
    Ok(())
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Task::Ci { quick } => ci(quick),
    }
}
