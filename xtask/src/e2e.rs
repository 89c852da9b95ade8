//! `cargo xtask e2e`: the viewer's end-to-end test in headless Chromium.
//!
//! Checks and installs the prerequisites, then runs `crates/balloon-viewer/frontend/e2e.mjs`
//! against the real `balloon view` binary:
//!
//! 1. node (20 or newer) and npm are on the PATH (otherwise an error saying how to install them);
//! 2. `npm ci` in the frontend folder, skipped when `node_modules` was installed from the current
//!    `package-lock.json` (a stamp file records the lockfile it was installed from);
//! 3. the vendored copies under `web/vendor` are byte-identical to the pinned packages;
//! 4. Chromium at `/usr/bin/chromium`, installed with `apt-get` when missing and running as root
//!    (CI), otherwise an error naming what is missing;
//! 5. `cargo test --workspace --no-run`, which builds `target/debug/balloon` with the same
//!    features as `cargo test --workspace` (a plain `cargo build -p balloon-cli` resolves the
//!    features without the workspace's dev-dependencies and rebuilt every crate, 127 s in CI),
//!    so after `cargo xtask ci`'s test stage it is a no-op;
//! 6. `node e2e.mjs --balloon target/debug/balloon` (screenshots in `target/e2e/`).

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Where the test expects Chromium (Debian's `chromium` package).
const CHROMIUM: &str = "/usr/bin/chromium";
/// Oldest Node.js major version the pinned playwright-core supports.
const MIN_NODE_MAJOR: u32 = 20;
/// Stamp written into `node_modules` after a successful `npm ci`: a copy of the lockfile.
const STAMP: &str = ".balloon-installed-lock.json";

/// Options of `cargo xtask e2e`.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Comma-separated systems to test, and scenario files (relative to the workspace) to view
    /// (default: shell, volumetric, two-layer, connect, `examples/pinned-neck/pinned-neck.toml`,
    /// `examples/drop-sphere/drop-sphere.toml` and `examples/static-sphere/static-sphere.toml`).
    pub systems: Option<String>,
}

/// Runs the whole task; fails with a message naming the missing prerequisite or failed step.
pub fn run(opts: &Options) -> Result<()> {
    let t0 = Instant::now();
    let root = crate::workspace_root();
    let frontend = root.join("crates/balloon-viewer/frontend");
    check_node()?;
    npm_ci(&frontend)?;
    run_checked(
        Command::new("node")
            .args(["vendor.mjs", "--check"])
            .current_dir(&frontend),
        "node vendor.mjs --check",
    )?;
    ensure_chromium()?;
    let t = Instant::now();
    crate::cargo(&["test", "--workspace", "--no-run"], &[])?;
    eprintln!("xtask e2e: build: {:.1} s", t.elapsed().as_secs_f64());
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    let binary = target.join("debug").join("balloon");
    if !binary.is_file() {
        bail!(
            "`cargo test --workspace --no-run` succeeded but {} is missing",
            binary.display()
        );
    }
    let mut cmd = Command::new("node");
    cmd.arg("e2e.mjs")
        .arg("--balloon")
        .arg(&binary)
        .arg("--out")
        .arg(target.join("e2e"))
        .arg("--chromium")
        .arg(CHROMIUM)
        .current_dir(&frontend);
    if let Some(s) = &opts.systems {
        cmd.args(["--systems", s]);
    }
    run_checked(&mut cmd, "node e2e.mjs")?;
    eprintln!("xtask e2e: whole task {:.1} s", t0.elapsed().as_secs_f64());
    Ok(())
}

/// Runs a command with inherited output and says how long it took; an error names it and its
/// exit status.
fn run_checked(cmd: &mut Command, what: &str) -> Result<()> {
    eprintln!("xtask e2e: {what}");
    let t = Instant::now();
    let status = cmd
        .status()
        .with_context(|| format!("failed to start `{what}`"))?;
    if !status.success() {
        bail!("`{what}` failed ({status})");
    }
    eprintln!("xtask e2e: {what}: {:.1} s", t.elapsed().as_secs_f64());
    Ok(())
}

/// The first line a program prints for `--version`, or `None` when it cannot be run.
fn version_of(program: &str) -> Option<String> {
    let out = Command::new(program).arg("--version").output().ok()?;
    out.status.success().then(|| {
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .next()
            .unwrap_or("")
            .trim()
            .to_string()
    })
}

/// The major number of a Node.js version string such as `v20.19.2`.
fn node_major(version: &str) -> Option<u32> {
    version
        .trim()
        .trim_start_matches('v')
        .split('.')
        .next()?
        .parse()
        .ok()
}

fn check_node() -> Result<()> {
    const HOW: &str = "install Node.js 20 or newer with npm (Debian/Ubuntu: \
                       `apt-get install -y nodejs npm`, or from nodejs.org)";
    let Some(node) = version_of("node") else {
        bail!("the viewer's end-to-end test needs `node`, which is not on the PATH: {HOW}");
    };
    match node_major(&node) {
        Some(m) if m >= MIN_NODE_MAJOR => {}
        _ => bail!("node {node} is too old for the viewer's end-to-end test: {HOW}"),
    }
    let Some(npm) = version_of("npm") else {
        bail!("the viewer's end-to-end test needs `npm`, which is not on the PATH: {HOW}");
    };
    eprintln!("xtask e2e: node {node}, npm {npm}");
    Ok(())
}

/// `npm ci` unless `node_modules` holds exactly what the current lockfile pins.
fn npm_ci(frontend: &Path) -> Result<()> {
    let lock_path = frontend.join("package-lock.json");
    let lock = std::fs::read(&lock_path)
        .with_context(|| format!("cannot read {}", lock_path.display()))?;
    let stamp = frontend.join("node_modules").join(STAMP);
    if std::fs::read(&stamp).is_ok_and(|s| s == lock) {
        eprintln!("xtask e2e: node_modules is up to date with package-lock.json");
        return Ok(());
    }
    run_checked(
        Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund"])
            .current_dir(frontend),
        "npm ci (crates/balloon-viewer/frontend)",
    )?;
    std::fs::write(&stamp, &lock).with_context(|| format!("cannot write {}", stamp.display()))
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

fn ensure_chromium() -> Result<()> {
    if Path::new(CHROMIUM).is_file() {
        return Ok(());
    }
    let has_apt = version_of("apt-get").is_some();
    if !(is_root() && has_apt) {
        bail!(
            "the viewer's end-to-end test needs Chromium at {CHROMIUM}, which is missing; \
             install Debian's `chromium` package (`sudo apt-get install chromium`){}",
            if has_apt {
                ""
            } else {
                " (apt-get is not available here, so it cannot be installed automatically)"
            }
        );
    }
    eprintln!(
        "xtask e2e: {CHROMIUM} is missing; installing Debian's chromium package \
         (apt-get update && apt-get install -y chromium)"
    );
    run_checked(
        Command::new("apt-get")
            .args(["update", "-q"])
            .env("DEBIAN_FRONTEND", "noninteractive"),
        "apt-get update",
    )?;
    run_checked(
        Command::new("apt-get")
            .args(["install", "-y", "-q", "chromium"])
            .env("DEBIAN_FRONTEND", "noninteractive"),
        "apt-get install -y chromium",
    )?;
    if !Path::new(CHROMIUM).is_file() {
        bail!("apt-get installed chromium but {CHROMIUM} is still missing");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_major_parses_version_strings() {
        assert_eq!(node_major("v20.19.2"), Some(20));
        assert_eq!(node_major("v18.0.0\n"), Some(18));
        assert_eq!(node_major("22.1.0"), Some(22));
        assert_eq!(node_major("node"), None);
        assert_eq!(node_major(""), None);
    }
}
