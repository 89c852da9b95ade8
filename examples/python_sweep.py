"""A notebook-style tour of the `balloon` Python package (CI runs it: `cargo xtask ci`).

1. Inflate a sphere with the pump step by step from Python and record its pressure-volume
   curve (gauge pressure over the enclosed volume), plotted with matplotlib.
2. Run a small wall-thickness sweep on a local dask cluster of two workers and plot the final
   volume over the thickness.

Install the package first (`pip install ./python` from the repository root, plus
`pip install matplotlib "dask[distributed]"`), then:

    python examples/python_sweep.py [--out DIR]

Writes DIR/pressure_volume.png, DIR/thickness_sweep.png and DIR/sweep.json.
"""

import argparse
import json
import os

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402
from dask.distributed import Client, LocalCluster  # noqa: E402

import balloon  # noqa: E402

MESH = "builtin:sphere"  # a 0.1 m icosphere; any .obj/.off/.ply/.stl path works too


def pressure_volume_curve(steps: int):
    """Pumps air into the sphere (2 L/s) and records (volume, gauge pressure) after each step."""
    shell = balloon.Shell(MESH, gas="pump", pump_rate=2e-3, dt=0.01)
    curve = [(shell.gas_volume, shell.gauge_pressure)]
    for _ in range(steps):
        stats = shell.step()
        curve.append((stats["gas_volume"], stats["gauge_pressure"]))
    return curve


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="python-example", help="output folder")
    parser.add_argument("--steps", type=int, default=25, help="pump steps of part 1")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    # 1. The pressure-volume curve of an inflation, from a step-wise simulation.
    curve = pressure_volume_curve(args.steps)
    v0 = curve[0][0]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot([v / v0 for v, _ in curve], [p for _, p in curve], marker=".")
    ax.set_xlabel("gas volume V / V0")
    ax.set_ylabel("gauge pressure (Pa)")
    ax.set_title(f"pumping {MESH}")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "pressure_volume.png"), dpi=100)
    print(f"pressure-volume: V/V0 {curve[-1][0] / v0:.3f} at {curve[-1][1]:.1f} Pa")

    # 2. A thickness sweep on a local cluster (the same call runs on a Slurm cluster through
    #    dask-jobqueue: see docs/python.md).
    thicknesses = [1.5e-4, 2e-4, 3e-4, 4e-4]
    runs = [
        {"thickness": h, "gas": "constant", "pressure": 1500.0, "steps": 8} for h in thicknesses
    ]
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        results = balloon.sweep(MESH, runs, client=client)
    failed = [r["error"] for r in results if r.get("error")]
    if failed:
        raise SystemExit(f"sweep runs failed: {failed}")
    ratios = [r["final_gas_volume"] / r["initial_gas_volume"] for r in results]
    for h, q in zip(thicknesses, ratios):
        print(f"thickness {h * 1e3:.2f} mm: V/V0 = {q:.4f}")
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot([h * 1e3 for h in thicknesses], ratios, marker="o")
    ax.set_xlabel("wall thickness (mm)")
    ax.set_ylabel("V / V0 after 8 steps at 1500 Pa")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "thickness_sweep.png"), dpi=100)
    with open(os.path.join(args.out, "sweep.json"), "w") as f:
        json.dump({"runs": runs, "results": results}, f, indent=1)
    # A thinner wall stretches more under the same pressure.
    assert all(a > b for a, b in zip(ratios, ratios[1:])), ratios
    print(f"written to {args.out}")


if __name__ == "__main__":
    main()
