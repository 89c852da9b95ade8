"""The surfaces of results and step-wise simulations as the objects other Python tools take.

:func:`mesh_arrays` gives a ``(vertices, faces)`` pair (float64 (n, 3) metres, int64 (m, 3)),
what ``trimesh.Trimesh(vertices, faces)`` and ``pyvista.make_tri_mesh(vertices, faces)`` take;
:func:`to_meshio` gives a ``meshio.Mesh`` with the fields as point and cell data, ready for
``mesh.write("state.vtu")`` or ParaView. ``meshio`` is optional: only :func:`to_meshio` needs it.

Both accept the dictionaries :func:`balloon.inflate`, :func:`balloon.connect`,
:func:`balloon.volumetric` and :func:`balloon.two_layer` return, and the step-wise
:class:`balloon.Shell`, :class:`balloon.Volumetric` and :class:`balloon.TwoLayer`; the results
also carry them as methods (``r.to_meshio()``, ``r.mesh_arrays()``). A volumetric body's
surface is its embedded triangle surface; a two-layer body has no triangles in the results, so
its particles come back with an empty face list (meshio: ``vertex`` cells).
"""

from typing import Any, Dict, Tuple

import numpy as np


def _get(obj: Any, key: str) -> Any:
    """``obj[key]`` for a result dictionary, ``obj.key`` for a step-wise simulation; None when
    absent."""
    if isinstance(obj, dict):
        return obj.get(key)
    return getattr(obj, key, None)


def _parts(obj: Any) -> Tuple[np.ndarray, np.ndarray, Dict[str, np.ndarray], Dict[str, np.ndarray]]:
    """Vertices, faces, per-vertex and per-face fields of ``obj``."""
    point_data: Dict[str, np.ndarray] = {}
    cell_data: Dict[str, np.ndarray] = {}
    surface = _get(obj, "surface_positions")
    if surface is not None:
        vertices = surface
        faces = _get(obj, "surface_triangles")
    else:
        vertices = _get(obj, "positions")
        faces = _get(obj, "triangles")
        velocities = _get(obj, "velocities")
        if velocities is not None:
            point_data["velocity"] = np.asarray(velocities, dtype=np.float64)
        thickness = _get(obj, "thickness")
        if thickness is not None:
            cell_data["thickness"] = np.asarray(thickness, dtype=np.float64)
    if vertices is None:
        raise TypeError(
            f"{type(obj).__name__} is not a balloon result or simulation "
            "(it has no `positions` or `surface_positions`)"
        )
    vertices = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
    if faces is None:
        faces = np.zeros((0, 3), dtype=np.int64)
    faces = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    offsets = _get(obj, "vertex_offsets")
    if offsets is not None:
        # Connected balloons: which balloon each vertex and triangle belongs to.
        owner = np.zeros(len(vertices), dtype=np.int64)
        for i, (a, b) in enumerate(zip(offsets[:-1], offsets[1:])):
            owner[a:b] = i
        point_data["balloon"] = owner
        if len(faces):
            cell_data["balloon"] = owner[faces[:, 0]]
    return vertices, faces, point_data, cell_data


def mesh_arrays(obj: Any) -> Tuple[np.ndarray, np.ndarray]:
    """The surface of ``obj`` (a result or a step-wise simulation) as ``(vertices, faces)``:
    float64 (n, 3) positions in metres and int64 (m, 3) outward-oriented triangles, copies that
    the caller owns.

    >>> import balloon
    >>> v, f = balloon.mesh_arrays(balloon.Shell("builtin:sphere"))
    >>> v.shape, f.shape
    ((2562, 3), (5120, 3))
    """
    vertices, faces, _, _ = _parts(obj)
    return vertices.copy(), faces.copy()


def to_meshio(obj: Any) -> Any:
    """The surface of ``obj`` (a result or a step-wise simulation) as a ``meshio.Mesh``: the
    triangles as one ``triangle`` cell block (a two-layer body's particles as ``vertex`` cells),
    ``velocity`` (m/s) and, for connected balloons, ``balloon`` (its index) as point data,
    ``thickness`` (m) and ``balloon`` as cell data.

    Needs the optional ``meshio`` package (``pip install meshio``); raises ImportError saying so
    when it is missing.
    """
    try:
        import meshio
    except ImportError as e:  # pragma: no cover - exercised with meshio absent
        raise ImportError(
            "balloon.to_meshio needs the optional package meshio: pip install meshio "
            "(balloon.mesh_arrays gives the same surface as numpy arrays without it)"
        ) from e
    vertices, faces, point_data, cell_data = _parts(obj)
    if len(faces):
        cells = [("triangle", faces)]
        cell_data = {k: [v] for k, v in cell_data.items()}
    else:
        cells = [("vertex", np.arange(len(vertices), dtype=np.int64).reshape(-1, 1))]
        cell_data = {}
    return meshio.Mesh(vertices, cells, point_data=point_data, cell_data=cell_data)


class Result(dict):
    """A result dictionary (what the whole-job functions return) that also converts itself:
    :meth:`mesh_arrays` and :meth:`to_meshio`. It is a ``dict``: every key reads as before."""

    def mesh_arrays(self) -> Tuple[np.ndarray, np.ndarray]:
        """See :func:`balloon.mesh_arrays`."""
        return mesh_arrays(self)

    def to_meshio(self) -> Any:
        """See :func:`balloon.to_meshio`."""
        return to_meshio(self)


class MeshMethods:
    """The conversions as methods of the step-wise simulations."""

    def mesh_arrays(self) -> Tuple[np.ndarray, np.ndarray]:
        """See :func:`balloon.mesh_arrays`."""
        return mesh_arrays(self)

    def to_meshio(self) -> Any:
        """See :func:`balloon.to_meshio`."""
        return to_meshio(self)
