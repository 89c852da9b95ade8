//! `balloon view`: the live viewer in the browser (issue 7; the server is `balloon-viewer`, the
//! protocol and flags are in `docs/viewer.md`). `balloon view SCENARIO.toml` (or `.json`) runs
//! a scenario file, read and checked exactly as `balloon run` reads it
//! ([`crate::cmd_run::scenario_of`]), so a bad file gets the same error naming the file, the
//! line and the key.

use anyhow::{Context, Result};
use balloon_scenario::Scenario;
use balloon_viewer::{SystemKind, Viewer, ViewerOptions};
use clap::Args;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

/// Arguments of `balloon view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// System to simulate: shell, volumetric, two-layer or connect (two balloons joined by a
    /// tube); or a scenario file (`.toml`, or `.json`) as `balloon run` takes it, run with its
    /// mesh, material, gas, anchors and loads.
    pub system: String,
    /// Mesh: an OBJ/OFF/PLY/STL file or `builtin:NAME` (default: a coarse teddy for shell and
    /// volumetric, two icospheres for connect; two-layer simulates its own sphere; a scenario
    /// file names its own).
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
    let (system, scenario) = system_or_scenario(&args.system)?;
    let exit_after = args.exit_after.map(Duration::from_secs_f64);
    let options = ViewerOptions {
        system,
        scenario,
        mesh: args.mesh.clone(),
        host: args.host.clone(),
        port: args.port,
        allow_remote: args.allow_remote.clone(),
    };
    let viewer = Viewer::start(&options)?;
    let url = viewer.url().to_string();
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "balloon view: serving {} at {url}", viewer.system())?;
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

/// The built-in system named `arg`, or the checked scenario of the scenario file `arg` (a
/// name that is no system and ends in `.toml` / `.json` or names a file), read as `balloon run`
/// reads it.
pub fn system_or_scenario(arg: &str) -> Result<(SystemKind, Option<Scenario>)> {
    let unknown = match arg.parse::<SystemKind>() {
        Ok(system) => return Ok((system, None)),
        Err(e) => e,
    };
    let path = Path::new(arg);
    let scenario_like = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml") || e.eq_ignore_ascii_case("json"));
    if !scenario_like && !path.exists() {
        return Err(anyhow::anyhow!(
            "{unknown}, and no scenario file (`.toml` or `.json`) of that name"
        ));
    }
    let call = crate::cmd_run::scenario_of(path, &[])?;
    Ok((SystemKind::Shell, Some(call.scenario)))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_scenario_file_gets_the_error_of_balloon_run() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.toml");
        std::fs::write(
            &path,
            "[mesh]\npath = \"builtin:icosphere\"\n[run]\ndtt = 0.1\n",
        )
        .unwrap();
        let arg = path.to_string_lossy().into_owned();
        let view = crate::error_chain(&system_or_scenario(&arg).unwrap_err());
        let run = crate::error_chain(&crate::cmd_run::scenario_of(&path, &[]).unwrap_err());
        assert_eq!(view, run);
        assert!(
            view.contains("bad.toml:4: `run.dtt`: unknown key"),
            "{view}"
        );
        // A value out of range names the key as `balloon run` does.
        std::fs::write(&path, "[run]\ndt = -1\n").unwrap();
        let view = crate::error_chain(&system_or_scenario(&arg).unwrap_err());
        let run = crate::error_chain(&crate::cmd_run::scenario_of(&path, &[]).unwrap_err());
        assert_eq!(view, run);
        assert!(view.contains("bad.toml:2") && view.contains("dt"), "{view}");
        // Neither a system nor a file.
        let e = system_or_scenario("cloth").unwrap_err().to_string();
        assert!(
            e.contains("unknown system `cloth`") && e.contains("no scenario file"),
            "{e}"
        );
        let e = crate::error_chain(&system_or_scenario("/no/such/run.toml").unwrap_err());
        assert!(e.contains("/no/such/run.toml"), "{e}");
    }

    #[test]
    fn systems_and_scenario_files_are_told_apart() {
        assert_eq!(
            system_or_scenario("connect").unwrap().0,
            SystemKind::Connect
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.json");
        std::fs::write(
            &path,
            r#"{"system": {"kind": "two-layer"}, "body": {"level": 1}}"#,
        )
        .unwrap();
        let (_, scenario) = system_or_scenario(&path.to_string_lossy()).unwrap();
        assert_eq!(
            scenario.map(|s| s.kind()),
            Some(balloon_scenario::SystemKind::TwoLayer)
        );
    }
}
