"""Type stubs of the extension module ``balloon._balloon`` (built from ``python/src/lib.rs``).

Keyword options are the CLI flags of the matching command in snake_case (``balloon inflate
--help``, ``balloon volumetric --help``, ``balloon two-layer --help``): same names, defaults
and units; ``True`` gives an on/off flag, ``False`` or ``None`` leaves an option out.
"""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

MeshLike = Union[str, os.PathLike, Tuple[npt.ArrayLike, npt.ArrayLike]]
"""A mesh file path, ``"builtin"``, ``"builtin:NAME"`` or a ``(vertices, triangles)`` pair."""

Option = Union[bool, int, float, str, os.PathLike, Sequence[float], None]

class BalloonError(Exception):
    """Base class of every error balloon raises; the message is the CLI's."""

class InvalidOption(BalloonError):
    """An unknown keyword option, a bad value, or a scenario file that does not parse."""

class MeshError(BalloonError):
    """A mesh that cannot be read or used."""

class SolverError(BalloonError):
    """A simulation step that failed."""

class _ShellResultBase(TypedDict):
    summary: Dict[str, Any]
    positions: npt.NDArray[np.float64]
    thickness: npt.NDArray[np.float64]
    triangles: npt.NDArray[np.int64]

class ShellResult(_ShellResultBase, total=False):
    points: List[Dict[str, Any]]
    """``static=True`` only: one dict per converged point (the ``stats.jsonl`` lines)."""

class VolumetricResult(TypedDict):
    summary: Dict[str, Any]
    positions: npt.NDArray[np.float64]
    surface_positions: npt.NDArray[np.float64]
    surface_triangles: npt.NDArray[np.int64]

class TwoLayerResult(TypedDict):
    summary: Dict[str, Any]
    positions: npt.NDArray[np.float64]

def inflate(mesh: Optional[MeshLike] = None, **options: Option) -> ShellResult:
    """Runs ``balloon inflate`` (a shell balloon, Wang et al. 2015) and returns its summary and final
    state; the GIL is released and Ctrl-C stops the run (inside a Newton solve in the
    main thread, else after the current step)."""

def volumetric(mesh: Optional[MeshLike] = None, **options: Option) -> VolumetricResult:
    """Runs ``balloon volumetric`` (a volume-conserving body, Diziol, Bender and Bayer 2011)."""

def two_layer(**options: Option) -> TwoLayerResult:
    """Runs ``balloon two-layer`` (a two-layer mass-spring body, Song 2009)."""

class ConnectResult(TypedDict):
    summary: Dict[str, Any]
    positions: npt.NDArray[np.float64]
    vertex_offsets: List[int]
    triangles: npt.NDArray[np.int64]

def connect(mesh: Optional[Union[str, os.PathLike]] = None, **options: Option) -> ConnectResult:
    """Runs ``balloon connect``: balloons of ideal gas joined by tubes (``copies=2,
    stretches=[1.35, 1.6]``); balloon ``i`` is rows ``vertex_offsets[i]:vertex_offsets[i+1]``."""

class DesignResult(TypedDict):
    rest: npt.NDArray[np.float64]
    inflated: npt.NDArray[np.float64]
    summary: Dict[str, Any]

def design(
    target_vertices: npt.ArrayLike,
    faces: npt.ArrayLike,
    pressure: Optional[float] = None,
    **options: Option,
) -> DesignResult:
    """Designs the rest shape whose static equilibrium under ``pressure`` (Pa), or under
    ``gas_amount=`` (J, nRT) of ideal gas, is the target (``balloon design``); check
    ``summary["converged"]``."""

def run_scenario(path: Union[str, os.PathLike], **overrides: Option) -> Dict[str, Any]:
    """Runs a scenario file (``balloon run``); ``overrides`` replace the file's values."""

class Shell:
    """A shell balloon built as ``balloon inflate`` builds it, stepped from Python."""

    def __init__(self, mesh: Optional[MeshLike] = None, **options: Option) -> None: ...
    def step(self) -> Dict[str, Any]:
        """Advances one step; returns its statistics (a ``stats.jsonl`` line's keys)."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Vertex positions, m, (n, 3)."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """Vertex velocities, m/s, (n, 3)."""
    @property
    def triangles(self) -> npt.NDArray[np.int64]:
        """Triangles, (m, 3)."""
    @property
    def thickness(self) -> npt.NDArray[np.float64]:
        """Shell thickness per triangle, m, (m,)."""
    @property
    def time(self) -> float:
        """Simulated time, s."""
    @property
    def steps(self) -> int:
        """Steps taken."""
    @property
    def dt(self) -> float:
        """Time step, s."""
    @property
    def gauge_pressure(self) -> float:
        """Gauge pressure of the gas, Pa, at the current volume and time (also before the
        first step and after a failed step that was rolled back)."""
    @property
    def gas_volume(self) -> float:
        """Enclosed gas volume, m^3, of the current positions."""
    def set_dt(self, dt: float) -> None: ...
    def set_pressure(self, pressure: float) -> None:
        """Gauge pressure, Pa (not for the pump gas)."""
    def set_pump_rate(self, rate: float) -> None:
        """Pump rate, m^3/s of ambient air (the pump gas only)."""
    def set_external_forces(self, forces: Optional[npt.ArrayLike] = None) -> None:
        """(n, 3) forces, N, per vertex; None removes them."""
    def set_anchor_springs(
        self, springs: List[Tuple[int, Tuple[float, float, float], float]]
    ) -> None:
        """(vertex, anchor point m, stiffness N/m) zero-length springs; [] removes them."""

class Volumetric:
    """A volume-conserving body built as ``balloon volumetric`` builds it, stepped from Python."""

    def __init__(self, mesh: Optional[MeshLike] = None, **options: Option) -> None: ...
    def step(self) -> Dict[str, Any]: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Lattice particle positions, m, (n, 3)."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]: ...
    @property
    def surface_positions(self) -> npt.NDArray[np.float64]:
        """The embedded surface, m, (k, 3)."""
    @property
    def surface_triangles(self) -> npt.NDArray[np.int64]: ...
    @property
    def time(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def dt(self) -> float: ...
    def set_dt(self, dt: float) -> None: ...
    def set_external_forces(self, forces: Optional[npt.ArrayLike] = None) -> None:
        """(n, 3) forces, N, per lattice particle; None removes them."""

class TwoLayer:
    """A two-layer body built as ``balloon two-layer`` builds it, stepped from Python."""

    def __init__(self, **options: Option) -> None: ...
    def step(self) -> Dict[str, Any]: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]: ...
    @property
    def velocities(self) -> npt.NDArray[np.float64]: ...
    @property
    def time(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def dt(self) -> float: ...
    def set_dt(self, dt: float) -> None: ...
    def set_drag(
        self,
        point: Optional[Tuple[float, float, float]] = None,
        stiffness: float = 10.0,
        damping: float = 0.1,
    ) -> Optional[int]:
        """Drags the nearest particle towards ``point``; None releases it."""
