"""Parameter sweeps: many whole jobs mapped over a dask.distributed client.

The runs are independent jobs; dask schedules them on whatever cluster the client is connected
to (a ``LocalCluster`` on one machine, dask-jobqueue's ``SLURMCluster``/``PBSCluster``, a
Kubernetes cluster, ...). Without a client they run one after the other in this process.
Either way the results are the same: each run is the same deterministic job.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence

from ._balloon import BalloonError

_SYSTEMS = ("inflate", "volumetric", "two_layer")


def _job(system: str):
    from . import _balloon

    if system not in _SYSTEMS:
        raise ValueError(f"system must be one of {', '.join(_SYSTEMS)}, not {system!r}")
    return getattr(_balloon, system)


def _run_dir(out: Optional[str], index: int) -> Optional[str]:
    return None if out is None else os.path.join(os.fspath(out), f"run_{index:04d}")


def _run_one(system: str, mesh: Any, options: Mapping[str, Any], out: Optional[str]) -> Dict[str, Any]:
    """One run of a sweep: its summary, or ``{"error": message}`` when it failed."""
    options = dict(options)
    if out is not None:
        options.setdefault("out", out)
        options.setdefault("overwrite", True)
    try:
        if system == "two_layer":
            return _job(system)(**options)["summary"]
        return _job(system)(mesh, **options)["summary"]
    except BalloonError as e:
        return {"error": str(e), "error_type": type(e).__name__}


def _run_scenario_one(path: str, overrides: Mapping[str, Any], out: Optional[str]) -> Dict[str, Any]:
    """One run of a scenario sweep: its summary, or ``{"error": message}``."""
    overrides = dict(overrides)
    if out is not None:
        overrides.setdefault("out", out)
        overrides.setdefault("overwrite", True)
    from ._balloon import run_scenario

    try:
        return run_scenario(path, **overrides)["summary"]
    except BalloonError as e:
        return {"error": str(e), "error_type": type(e).__name__}


def _map(func, argument_lists: List[Sequence[Any]], client) -> List[Dict[str, Any]]:
    if client is None:
        return [func(*args) for args in argument_lists]
    columns = [list(c) for c in zip(*argument_lists)] if argument_lists else []
    if not columns:
        return []
    # pure=False: two equal runs are still two runs (and results come back in order).
    futures = client.map(func, *columns, pure=False)
    return client.gather(futures)


def sweep(
    mesh: Any,
    runs: Sequence[Mapping[str, Any]],
    client=None,
    out: Optional[str] = None,
    system: str = "inflate",
) -> List[Dict[str, Any]]:
    """Runs one job per option dict of ``runs`` and returns their summaries, in order.

    ``mesh`` is what :func:`balloon.inflate` takes (ignored for ``system="two_layer"``);
    each dict of ``runs`` holds keyword options of that function. ``client`` is a
    ``dask.distributed.Client`` (any cluster); ``None`` runs serially here. With ``out``,
    run ``i`` writes its output folder ``out/run_{i:04d}`` (unless its options give ``out``).
    A failed run gives ``{"error": message, "error_type": class name}`` and the sweep goes on.
    """
    _job(system)
    args = [(system, mesh, dict(r), _run_dir(out, i)) for i, r in enumerate(runs)]
    return _map(_run_one, args, client)


def sweep_scenario(
    path: Any,
    runs: Sequence[Mapping[str, Any]],
    client=None,
    out: Optional[str] = None,
) -> List[Dict[str, Any]]:
    """Like :func:`sweep` for a scenario file: each dict of ``runs`` holds overrides of the
    file's values (keyword options of its system), as :func:`balloon.run_scenario` takes them.
    """
    path = os.path.abspath(os.fspath(path))
    args = [(path, dict(r), _run_dir(out, i)) for i, r in enumerate(runs)]
    return _map(_run_scenario_one, args, client)
