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
Inverse design (the rest shape that inflates to a given shape): :func:`design`.
Step-wise simulations: :class:`Shell`, :class:`Volumetric`, :class:`TwoLayer`.
Parameter sweeps over a dask.distributed cluster: :func:`sweep`, :func:`sweep_scenario`.
Surfaces for other tools: :func:`mesh_arrays` (a ``(vertices, faces)`` pair for trimesh or
pyvista) and :func:`to_meshio` (a ``meshio.Mesh``; meshio is optional), also methods of the
results and the step-wise simulations.
Errors: :class:`BalloonError` and its subclasses :class:`InvalidOption`, :class:`MeshError`,
:class:`SolverError`.
"""

import functools as _functools

from . import _balloon
from ._balloon import (
    BalloonError,
    InvalidOption,
    MeshError,
    SolverError,
    __version__,
)
from ._mesh import MeshMethods as _MeshMethods
from ._mesh import Result, mesh_arrays, to_meshio
from ._sweep import sweep, sweep_scenario


def _returns_result(job):
    """``job`` with its result dictionary as a :class:`Result` (a dict with ``to_meshio``)."""

    @_functools.wraps(job)
    def run(*args, **options):
        r = job(*args, **options)
        return Result(r) if isinstance(r, dict) else r

    return run


inflate = _returns_result(_balloon.inflate)
volumetric = _returns_result(_balloon.volumetric)
two_layer = _returns_result(_balloon.two_layer)
connect = _returns_result(_balloon.connect)
run_scenario = _returns_result(_balloon.run_scenario)
design = _balloon.design


class Shell(_balloon.Shell, _MeshMethods):
    __doc__ = _balloon.Shell.__doc__
    __module__ = "balloon"


class Volumetric(_balloon.Volumetric, _MeshMethods):
    __doc__ = _balloon.Volumetric.__doc__
    __module__ = "balloon"


class TwoLayer(_balloon.TwoLayer, _MeshMethods):
    __doc__ = _balloon.TwoLayer.__doc__
    __module__ = "balloon"


__all__ = [
    "BalloonError",
    "InvalidOption",
    "Result",
    "MeshError",
    "SolverError",
    "Shell",
    "TwoLayer",
    "Volumetric",
    "__version__",
    "connect",
    "design",
    "inflate",
    "mesh_arrays",
    "run_scenario",
    "sweep",
    "sweep_scenario",
    "to_meshio",
    "two_layer",
    "volumetric",
]
