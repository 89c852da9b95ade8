//! `balloon view`: the live viewer in the browser (issue 7; the server is `balloon-viewer`, the
//! protocol and flags are in `docs/viewer.md`).

use anyhow::{Context, Result};
use balloon_viewer::{SystemKind, Viewer, ViewerOptions};
use clap::Args;
use std::io::Write;
use std::time::Duration;

/// Arguments of `balloon view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// System to simulate: shell, volumetric or two-layer.
    pub system: String,
    /// Mesh: an OBJ/OFF/PLY/STL file or `builtin:NAME` (default: a coarse teddy for shell and
    /// volumetric; two-layer simulates its own sphere).
    pub mesh: Option<String>,
    /// TCP port (0: the OS picks a free one).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Bind address; anything not loopback also needs --allow-remote.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Extra host names (or addresses) clients may use in Host and Origin, comma-separated or
    /// repeated; needed for a non-loopback --host (anyone who can reach it controls the
    /// simulation). The loopback names and the bound address are always accepted.
    #[arg(long, value_name = "HOST[,HOST...]", value_delimiter = ',')]
    pub allow_remote: Vec<String>,
    /// Do not start a browser, just print the URL.
    #[arg(long)]
    pub no_open: bool,
    /// Browser command to open the URL with (default: $BROWSER, then xdg-open / open).
    #[arg(long)]
    pub browser: Option<String>,
    /// Stop serving after this many seconds (tests, demos), in [0, 1e7] (about 4 months).
    #[arg(long, value_parser = crate::params::real(crate::params::Closed(0.0), crate::params::Closed(1e7)))]
    pub exit_after: Option<f64>,
}

/// Runs the viewer.
pub fn run(args: ViewArgs) -> Result<()> {
    let system: SystemKind = args.system.parse()?;
    let exit_after = args.exit_after.map(Duration::from_secs_f64);
    let options = ViewerOptions {
        system,
        mesh: args.mesh.clone(),
        host: args.host.clone(),
        port: args.port,
        allow_remote: args.allow_remote.clone(),
    };
    let viewer = Viewer::start(&options)?;
    let url = viewer.url().to_string();
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "balloon view: serving {} at {url}", system.name())?;
        out.flush()?;
    }
    if !args.no_open
        && let Err(e) = open_browser(args.browser.as_deref(), &url)
    {
        eprintln!("balloon view: could not open a browser: {e:#}");
        eprintln!("balloon view: open {url} by hand (the server keeps running)");
    }
    viewer.serve(exit_after).context("serving")?;
    Ok(())
}

/// Starts the browser on `url`: `--browser CMD`, else `$BROWSER`, else the platform opener.
/// Only starting it is checked (the browser runs on its own).
fn open_browser(browser: Option<&str>, url: &str) -> Result<()> {
    let env = std::env::var("BROWSER")
        .ok()
        .filter(|b| !b.trim().is_empty());
    let command = match browser.map(str::to_string).or(env) {
        Some(c) => c,
        None if cfg!(target_os = "macos") => "open".into(),
        None if cfg!(target_os = "windows") => "explorer".into(),
        None => "xdg-open".into(),
    };
    let mut parts = command.split_whitespace();
    let program = parts
        .next()
        .context("the browser command is empty (--browser or $BROWSER)")?;
    let mut child = std::process::Command::new(program)
        .args(parts)
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .spawn()
        .with_context(|| format!("cannot start `{command}`"))?;
    // An opener that fails at once (no display, unknown browser) is reported; one that keeps
    // running is the browser itself.
    std::thread::sleep(Duration::from_millis(300));
    if let Some(status) = child.try_wait()?
        && !status.success()
    {
        anyhow::bail!("`{command}` exited with {status}");
    }
    Ok(())
}
