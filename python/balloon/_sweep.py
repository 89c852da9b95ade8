"""Parameter sweeps: many whole jobs mapped over a dask.distributed client.

The runs are independent jobs; dask schedules them on whatever cluster the client is connected
to (a ``LocalCluster`` on one machine, dask-jobqueue's ``SLURMCluster``/``PBSCluster``, a
Kubernetes cluster, ...). Without a client they run one after the other in this process.
Either way the results are the same: each run is the same deterministic job.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence

from ._balloon import BalloonError, InvalidOption

_SYSTEMS = ("inflate", "volumetric", "two_layer")


class InvalidSystem(InvalidOption, ValueError):
    """An unknown ``system`` of :func:`sweep` (an :class:`InvalidOption`, and a ``ValueError``
    as it always was)."""


def _job(system: str):
    from . import _balloon

    if system not in _SYSTEMS:
        raise InvalidSystem(f"system must be one of {', '.join(_SYSTEMS)}, not {system!r}")
    return getattr(_balloon, system)


def _options(index: int, options: Any) -> Dict[str, Any]:
    """Run ``index``'s options as a dict; anything else is an :class:`InvalidOption` naming
    the run."""
    if not isinstance(options, Mapping):
        raise InvalidOption(
            f"run {index}: the options of a run must be a dict of keyword options, "
            f"got {type(options).__name__} ({options!r:.80})"
        )
    bad = [k for k in options if not isinstance(k, str)]
    if bad:
        raise InvalidOption(f"run {index}: option names must be strings, got {bad[0]!r}")
    return dict(options)


def _failed(index: int, e: Exception) -> Dict[str, Any]:
    """The result of run ``index`` that raised ``e``: the message names the run."""
    message = str(e)
    if not message.startswith(f"run {index}: "):
        message = f"run {index}: {message}"
    return {"error": message, "error_type": type(e).__name__, "run": index}


def _run_dir(out: Optional[str], index: int) -> Optional[str]:
    return None if out is None else os.path.join(os.fspath(out), f"run_{index:04d}")


def _run_one(
    system: str, mesh: Any, options: Any, out: Optional[str], index: int = 0
) -> Dict[str, Any]:
    """One run of a sweep: its summary, or ``{"error": message, "error_type": class name,
    "run": index}`` when it failed (the message starts with ``run INDEX:``)."""
    try:
        options = _options(index, options)
        if out is not None:
            options.setdefault("out", out)
            options.setdefault("overwrite", True)
        if system == "two_layer":
            return _job(system)(**options)["summary"]
        return _job(system)(mesh, **options)["summary"]
    except (BalloonError, TypeError, ValueError) as e:
        return _failed(index, e)


def _run_scenario_one(
    path: str, overrides: Any, out: Optional[str], index: int = 0
) -> Dict[str, Any]:
    """One run of a scenario sweep: its summary, or the error as :func:`_run_one` gives it."""
    from ._balloon import run_scenario

    try:
        overrides = _options(index, overrides)
        if out is not None:
            overrides.setdefault("out", out)
            overrides.setdefault("overwrite", True)
        return run_scenario(path, **overrides)["summary"]
    except (BalloonError, TypeError, ValueError) as e:
        return _failed(index, e)


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
    A failed run (an invalid option, an entry that is not a dict, a solver failure) gives
    ``{"error": "run INDEX: message", "error_type": class name, "run": INDEX}`` and the sweep
    goes on with the others.
    """
    _job(system)
    args = [(system, mesh, r, _run_dir(out, i), i) for i, r in enumerate(runs)]
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
    args = [(path, r, _run_dir(out, i), i) for i, r in enumerate(runs)]
    return _map(_run_scenario_one, args, client)
