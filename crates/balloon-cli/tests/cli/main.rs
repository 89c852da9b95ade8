//! End-to-end tests of the `balloon` binary: one test binary for all subcommands.

mod anchors;
mod connect;
mod design;
mod gas_laws;
mod help;
mod hostile;
mod inflate;
mod interrupt_solve;
mod loads;
mod membrane;
mod mesh;
mod params;
mod pinned_all;
mod readback;
mod records;
mod render;
mod scenario;
mod stability;
mod transform;
mod two_layer;
mod view;
mod volumetric;

use std::process::{Command, Output};

/// Runs the `balloon` binary with `args` and returns its output.
pub fn run_balloon(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_balloon"))
        .args(args)
        .output()
        .expect("failed to start the balloon binary")
}

/// The last non-empty line of stdout parsed as JSON (what `--json` prints).
pub fn last_json_line(out: &Output) -> serde_json::Value {
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .expect("no stdout line");
    serde_json::from_str(line)
        .unwrap_or_else(|e| panic!("last stdout line is not JSON ({e}): {line}"))
}

/// The shared real meshes folder beside the repository, if present; when it is absent and the
/// `CI` environment variable is set, the test fails instead (in CI the tests on the real meshes
/// must run, not skip).
pub fn shared_meshes_dir() -> Option<std::path::PathBuf> {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/meshes");
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "CI is set but {} is missing: the tests on the real meshes would be skipped",
        dir.display()
    );
    None
}

/// `balloon volumetric`'s flags parsed on their own, to run its job in this process (keeping
/// the simulation) with exactly the command's settings.
#[derive(clap::Parser)]
struct VolumetricCli {
    #[command(flatten)]
    args: balloon_cli::cmd_volumetric::VolumetricArgs,
}

/// The arguments of `balloon volumetric ARGV...` (`argv` without the subcommand's name).
pub fn volumetric_args(argv: &[&str]) -> balloon_cli::cmd_volumetric::VolumetricArgs {
    use clap::Parser as _;
    let mut all = vec!["volumetric"];
    all.extend_from_slice(argv);
    VolumetricCli::try_parse_from(all)
        .unwrap_or_else(|e| panic!("{e}"))
        .args
}

/// The `v` lines of an OBJ file as flat `x y z` coordinates.
pub fn obj_points(path: &std::path::Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .flat_map(|l| {
            l.split_whitespace()
                .map(|v| v.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect()
}
