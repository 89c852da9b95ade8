//! Project automation for the `balloon` workspace.
//!
//! * `cargo xtask ci`: format check, clippy with warnings denied, docs with warnings denied, the
//!   whole test suite, the viewer's end-to-end test, `validate --quick` (no files written), the
//!   Python package's tests (`cargo xtask python`) and every criterion bench once in test mode;
//!   with `CI` set, a missing `../shared/meshes` fails it. Nothing is built in release: the
//!   validation cases run in this process and the Python extension is built in the `dev`
//!   profile. `.ci/run` builds every target first (`cargo build --workspace --all-targets`,
//!   xtask included) and runs this with the xtask binary of that build.
//! * `cargo xtask validate [--quick] [--meshes DIR]`: every validation case (analytic sphere,
//!   thickness scaling, gas law, pressure equilibrium, volume projection, membrane limit points
//!   against the analytic thin sphere, volumetric bodies, two-layer integrators, real meshes);
//!   prints a table, writes `docs/validation.md` and
//!   `docs/figures/*.png`, exits non-zero when a case fails. Runs itself in release.
//! * `cargo xtask bench [--quick] [--meshes DIR] [--update-docs]`: the paper's Table 1 for a
//!   folder of meshes and every linear solver, plus cost-vs-size of the volumetric and two-layer
//!   systems; writes `target/bench/bench.{md,json}` (and `docs/benchmarks.md` on request). Runs
//!   itself in release.
//! * `cargo xtask python`: builds the Python package's wheel (maturin, `dev` profile, in `target/`)
//!   into a virtual environment `target/py-venv` (created once, with the pinned
//!   `python/requirements-test.txt`), then runs pytest on `python/tests` and
//!   `examples/python_sweep.py`. Needs only `python3` with `venv` and pip's index.
//! * `cargo xtask e2e [--systems LIST]`: the live viewer's end-to-end test in headless Chromium
//!   (installs its prerequisites: `npm ci`, Debian's chromium when root); see `docs/viewer.md`.

mod bench;
mod e2e;
mod measure;
mod plot;
mod render;
mod report;
mod validate;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "balloon project automation")]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// fmt --check, clippy -D warnings, doc -D warnings, tests, the viewer's end-to-end test,
    /// `validate --quick` (nothing written), the Python package (`python`), benches in test
    /// mode. With `CI` set, a missing `../shared/meshes` fails the run.
    Ci {
        /// Skip clippy and docs (faster local runs).
        #[arg(long)]
        quick: bool,
    },
    /// Runs every validation case in release, writes docs/validation.md and docs/figures/.
    Validate {
        /// A subset with fewer pressures and shorter runs (about 1-2 minutes).
        #[arg(long)]
        quick: bool,
        /// Folder of meshes (.obj/.off/.ply/.stl) to load, validate and inflate. Default: the
        /// built-in models plus `../shared/meshes` when present.
        #[arg(long)]
        meshes: Option<PathBuf>,
        /// Do not write docs/validation.md and the figures (only print the table).
        #[arg(long)]
        no_write: bool,
        /// Run one group only (shell, membrane, connected, tube, volumetric, drop-sphere, two-layer,
        /// floppy, thin-parts, design, meshes); leaves docs/ unchanged, draws the group's figures into
        /// target/validate-figures/.
        #[arg(long)]
        only: Option<String>,
    },
    /// Benchmarks in release: Table 1 per linear solver, cost growth with size.
    Bench {
        /// Fewer runs and smaller sizes (a smoke run).
        #[arg(long)]
        quick: bool,
        /// Folder of meshes for Table 1. Default: built-in models of comparable sizes.
        #[arg(long)]
        meshes: Option<PathBuf>,
        /// Timed runs per (model, solver); the median is reported.
        #[arg(long, default_value_t = 3)]
        runs: usize,
        /// Also write docs/benchmarks.md.
        #[arg(long)]
        update_docs: bool,
        /// Run only the converged default solver's studies named here (comma-separated:
        /// sphere, teddy, scaling; `all` for the three) and write target/bench/converged.md.
        /// `sphere` also runs the same sphere in MuJoCo (`benches/peer/mujoco_sphere.py`)
        /// when `python3` imports `mujoco` (`pip install mujoco`), and says so when not.
        #[arg(long)]
        converged: Option<String>,
    },
    /// The Python package: wheel into target/py-venv, pytest, examples/python_sweep.py.
    Python,
    /// The live viewer's end-to-end test: `balloon view` driven in headless Chromium.
    E2e {
        /// Comma-separated systems and scenario files to test (default:
        /// shell,volumetric,two-layer,connect and the pinned-neck, static-sphere and drop-sphere examples).
        #[arg(long)]
        systems: Option<String>,
    },
}

fn cargo(args: &[&str], envs: &[(&str, &str)]) -> Result<()> {
    eprintln!("xtask: cargo {}", args.join(" "));
    let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    cmd.args(args);
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let started = std::time::Instant::now();
    let status = cmd
        .status()
        .with_context(|| format!("failed to start cargo {}", args.join(" ")))?;
    eprintln!(
        "xtask: cargo {} took {:.0} s",
        args.join(" "),
        started.elapsed().as_secs_f64()
    );
    if !status.success() {
        bail!("`cargo {}` failed ({status})", args.join(" "));
    }
    Ok(())
}

fn ci(quick: bool) -> Result<()> {
    // The Python stage's virtual environment and pinned test dependencies are downloads and
    // unpacking, not compilation: they are prepared in the background while the Rust stages
    // build and run, and waited for before the wheel is built. A failure there fails the
    // Python stage.
    let venv = std::thread::spawn(prepare_venv);
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
    // In CI the shared real meshes must be there: tests that read them would otherwise pass
    // by skipping (they fail too when `CI` is set; this names the cause once, up front).
    if std::env::var_os("CI").is_some() {
        let meshes = workspace_root().join("../shared/meshes");
        if !meshes.is_dir() {
            bail!(
                "CI is set but {} is missing: the tests and validation cases on the real meshes \
                 would be skipped",
                meshes.display()
            );
        }
    }
    cargo(&["test", "--workspace"], &[])?;
    let started = std::time::Instant::now();
    e2e::run(&e2e::Options::default())?;
    eprintln!(
        "xtask: viewer e2e took {:.0} s",
        started.elapsed().as_secs_f64()
    );
    // The validation cases (analytic sphere, gas law, volume conservation, ...) in their quick
    // subset, without rewriting docs/validation.md: a failing case fails CI. They run in this
    // process, i.e. in the build `xtask ci` was built in (`.ci/run` runs the test build's
    // `target/debug/xtask`: opt-level 2, dependencies at 3, debug assertions and overflow
    // checks on), instead of a release build of xtask and every crate below it only for them
    // (4 minutes of CI's 2 cores). The numbers are the same (no build changes floating-point
    // semantics); `cargo xtask validate` alone still runs in release for its timings.
    let started = std::time::Instant::now();
    eprintln!(
        "xtask: validate --quick --no-write (in the {} build)",
        if cfg!(debug_assertions) {
            "debug-assertions"
        } else {
            "release"
        }
    );
    validate::run(&validate::Options {
        quick: true,
        meshes: None,
        write: false,
        only: None,
    })?;
    eprintln!(
        "xtask: validate --quick --no-write took {:.0} s",
        started.elapsed().as_secs_f64()
    );
    let started = std::time::Instant::now();
    venv.join()
        .map_err(|_| anyhow::anyhow!("preparing the Python virtual environment panicked"))??;
    python_package()?;
    eprintln!(
        "xtask: python took {:.0} s",
        started.elapsed().as_secs_f64()
    );
    // Every criterion bench once in test mode so none rots. The `test` profile and the whole
    // workspace (the same feature unification as `cargo test --workspace`) reuse the test
    // build: `-p balloon-benches --profile dev` rebuilt 50 crates (3.4 min on the 2-core
    // machine). `--bench '*'` selects the bench targets only (not the libraries' unit tests in
    // bench mode).
    cargo(
        &[
            "bench",
            "--workspace",
            "--profile",
            "test",
            "--bench",
            "*",
            "--",
            "--test",
        ],
        &[],
    )?;
    Ok(())
}

/// Runs `program args` in the workspace root with `envs`, failing on a non-zero status.
fn run_program(program: &Path, args: &[&str], envs: &[(&str, &Path)]) -> Result<()> {
    eprintln!("xtask: {} {}", program.display(), args.join(" "));
    let mut cmd = Command::new(program);
    cmd.args(args).current_dir(workspace_root());
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let status = cmd
        .status()
        .with_context(|| format!("failed to start {}", program.display()))?;
    if !status.success() {
        bail!(
            "`{} {}` failed ({status})",
            program.display(),
            args.join(" ")
        );
    }
    Ok(())
}

/// The Python package's CI step: [`prepare_venv`], then [`python_package`].
fn python() -> Result<()> {
    let t0 = std::time::Instant::now();
    prepare_venv()?;
    python_package()?;
    eprintln!(
        "xtask: python package step took {:.0} s",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The virtual environment `target/py-venv` of the Python step (created when missing;
/// `$BALLOON_PYTHON` or `python3` makes it) with the pinned test dependencies installed.
fn prepare_venv() -> Result<()> {
    let t0 = std::time::Instant::now();
    let venv = workspace_root().join("target").join("py-venv");
    let py = venv.join("bin").join("python");
    if !py.exists() {
        let base = std::env::var_os("BALLOON_PYTHON").unwrap_or_else(|| "python3".into());
        run_program(
            Path::new(&base),
            &["-m", "venv", &venv.to_string_lossy()],
            &[],
        )?;
    }
    // Already satisfied pins cost a second; a changed pin is installed.
    run_program(
        &py,
        &[
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "-r",
            "python/requirements-test.txt",
        ],
        &[],
    )?;
    eprintln!(
        "xtask: python virtual environment ready in {:.0} s",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The wheel built by maturin into `target/py-wheels` and installed into the virtual
/// environment of [`prepare_venv`], then pytest on `python/tests` (against the CLI binary of
/// the test build) and `examples/python_sweep.py`.
///
/// The extension is built in the `dev` profile (opt-level 2, dependencies at 3, the profile of
/// the test build): it shares `target/debug` with `cargo test --workspace`, so only the crates
/// whose features differ in the extension's own feature resolution (51 of its 164 units) are
/// compiled again, where `--release` compiles all 164 (CI no longer builds anything else in
/// release to share them with). Wheels for users are built by `pip install ./python` /
/// `maturin build`, in release (`python/pyproject.toml`).
fn python_package() -> Result<()> {
    let root = workspace_root();
    let target = root.join("target");
    let bin = target.join("py-venv").join("bin");
    let py = bin.join("python");
    let wheels = target.join("py-wheels");
    if wheels.exists() {
        std::fs::remove_dir_all(&wheels)
            .with_context(|| format!("cannot clear {}", wheels.display()))?;
    }
    run_program(
        &bin.join("maturin"),
        &[
            "build",
            "--profile",
            "dev",
            "--quiet",
            "-m",
            "python/Cargo.toml",
            "--out",
            &wheels.to_string_lossy(),
        ],
        &[],
    )?;
    let wheel = std::fs::read_dir(&wheels)
        .with_context(|| format!("cannot read {}", wheels.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .with_context(|| format!("maturin wrote no wheel into {}", wheels.display()))?;
    run_program(
        &py,
        &[
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "--force-reinstall",
            "--no-deps",
            &wheel.to_string_lossy(),
        ],
        &[],
    )?;
    // The CLI the Python results are compared with bit for bit. `cargo test --workspace
    // --no-run` builds it with the test build's features (a plain `cargo build -p balloon-cli`
    // resolves features differently and rebuilds dependencies: 1.5 min in CI), so after
    // `cargo xtask ci`'s test stage it is a no-op (as in `e2e`).
    cargo(&["test", "--workspace", "--no-run", "--quiet"], &[])?;
    let cli = target.join("debug").join("balloon");
    run_program(
        &py,
        &[
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "python/tests",
        ],
        &[("BALLOON_CLI", &cli)],
    )?;
    run_program(
        &py,
        &[
            "examples/python_sweep.py",
            "--out",
            &target.join("python-example").to_string_lossy(),
        ],
        &[],
    )?;
    Ok(())
}

/// The workspace root (the parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Re-runs this command line with an optimised xtask (`cargo run --release -p xtask -- ...`):
/// validation and benchmarks measure optimised numerics. Returns the child's exit status.
fn rerun_in_release() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut full = vec![
        "run".to_string(),
        "--quiet".into(),
        "--release".into(),
        "--package".into(),
        "xtask".into(),
        "--".into(),
    ];
    full.extend(args);
    eprintln!("xtask: re-running in release: cargo {}", full.join(" "));
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(&full)
        .current_dir(workspace_root())
        .status()
        .context("failed to start cargo run --release -p xtask")?;
    if !status.success() {
        std::process::exit(status.code().unwrap_or(1));
    }
    Ok(())
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Task::Ci { quick } => ci(quick),
        Task::Python => python(),
        Task::E2e { systems } => e2e::run(&e2e::Options { systems }),
        Task::Validate { .. } | Task::Bench { .. } if cfg!(debug_assertions) => rerun_in_release(),
        Task::Validate {
            quick,
            meshes,
            no_write,
            only,
        } => validate::run(&validate::Options {
            quick,
            meshes,
            write: !no_write,
            only,
        }),
        Task::Bench {
            quick,
            meshes,
            runs,
            update_docs,
            converged,
        } => {
            let opts = bench::Options {
                quick,
                meshes,
                runs: runs.max(1),
                update_docs,
            };
            match converged {
                Some(parts) => {
                    let has =
                        |p: &str| parts.split(',').any(|s| s.trim() == p || s.trim() == "all");
                    bench::run_converged(
                        &opts,
                        bench::ConvergedParts {
                            sphere: has("sphere"),
                            teddy: has("teddy"),
                            scaling: has("scaling"),
                        },
                    )
                    .map(|_| ())
                }
                None => bench::run(&opts),
            }
        }
    }
}
