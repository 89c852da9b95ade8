"""balloon: inflatable thin shells, volume-conserving and two-layer soft bodies.

Python bindings of the ``balloon`` Rust workspace. Every function takes the command-line
tool's flags as keyword options in snake_case, with the same defaults and units, and runs
exactly what the CLI runs (each option is a parameter of the library's typed scenario, which
the CLI's flags and scenario files set too):

>>> import balloon
>>> r = balloon.inflate("builtin:sphere", steps=15, gas="constant", pressure=900.0)
>>> r["positions"].shape
(2562, 3)

Whole jobs: :func:`inflate`, :func:`volumetric`, :func:`two_layer`, :func:`connect`,
:func:`run_scenario`.
Step-wise simulations: :class:`Shell`, :class:`Volumetric`, :class:`TwoLayer`.
Parameter sweeps over a dask.distributed cluster: :func:`sweep`, :func:`sweep_scenario`.
Errors: :class:`BalloonError` and its subclasses :class:`InvalidOption`, :class:`MeshError`,
:class:`SolverError`.
"""

from ._balloon import (
    BalloonError,
    InvalidOption,
    MeshError,
    Shell,
    SolverError,
    TwoLayer,
    Volumetric,
    __version__,
    connect,
    inflate,
    run_scenario,
    two_layer,
    volumetric,
)
from ._sweep import sweep, sweep_scenario

__all__ = [
    "BalloonError",
    "InvalidOption",
    "MeshError",
    "SolverError",
    "Shell",
    "TwoLayer",
    "Volumetric",
    "__version__",
    "connect",
    "inflate",
    "run_scenario",
    "sweep",
    "sweep_scenario",
    "two_layer",
    "volumetric",
]
