"""Shared fixtures: the CLI binary the Python results are compared with."""

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli() -> str:
    """The `balloon` binary: $BALLOON_CLI (set by `cargo xtask ci`), else the workspace's
    release or debug build."""
    given = os.environ.get("BALLOON_CLI")
    candidates = [given] if given else [
        str(ROOT / "target" / "release" / "balloon"),
        str(ROOT / "target" / "debug" / "balloon"),
    ]
    for c in candidates:
        if c and os.access(c, os.X_OK):
            return c
    pytest.fail(
        f"no `balloon` binary among {candidates}: build it (`cargo build --release -p "
        "balloon-cli`) or set BALLOON_CLI"
    )


def read_obj_vertices(path):
    """The vertices of an OBJ file written by the CLI (Rust's shortest round-trip float text, so
    parsing gives back the exact float64 values)."""
    import numpy as np

    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                rows.append([float(x) for x in line.split()[1:4]])
    return np.array(rows, dtype=np.float64)


# Keys of a summary that measure wall-clock time and differ between two identical runs.
TIMING_KEYS = {
    "mean_step_ms", "lattice_ms", "steps_per_second", "solve_ms", "phase_times_ms", "times",
}


def without_timing(summary):
    return {k: v for k, v in summary.items() if k not in TIMING_KEYS}
