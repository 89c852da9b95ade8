"""`to_meshio()` and `mesh_arrays()` of results and step-wise simulations: the same surface and
fields as the arrays, a meshio mesh that writes and reads back, and a clear ImportError
without meshio."""

import sys

import numpy as np
import pytest

import balloon


def test_shell_result_and_simulation_convert():
    r = balloon.inflate("builtin:sphere", steps=2, gas="constant", pressure=900.0)
    v, f = r.mesh_arrays()
    assert np.array_equal(v, r["positions"]) and np.array_equal(f, r["triangles"])
    assert v.dtype == np.float64 and f.dtype == np.int64 and f.shape[1] == 3
    v[0, 0] += 1.0  # a copy: the result is untouched
    assert v[0, 0] != r["positions"][0, 0]
    sim = balloon.Shell("builtin:sphere", gas="constant", pressure=900.0)
    sim.step()
    sv, sf = sim.mesh_arrays()
    assert np.array_equal(sv, sim.positions) and np.array_equal(sf, sim.triangles)
    assert balloon.mesh_arrays(sim)[0].shape == sv.shape


def test_to_meshio_carries_the_fields(tmp_path):
    meshio = pytest.importorskip("meshio")
    sim = balloon.Shell("builtin:sphere", gas="constant", pressure=900.0)
    sim.step()
    m = sim.to_meshio()
    assert isinstance(m, meshio.Mesh)
    assert np.array_equal(m.points, sim.positions)
    assert m.cells[0].type == "triangle"
    assert np.array_equal(m.cells[0].data, sim.triangles)
    assert np.array_equal(m.cell_data["thickness"][0], sim.thickness)
    assert np.array_equal(m.point_data["velocity"], sim.velocities)
    path = tmp_path / "state.vtu"
    m.write(path)
    back = meshio.read(path)
    assert np.allclose(back.points, sim.positions)
    assert np.allclose(back.cell_data["thickness"][0], sim.thickness)


def test_volumetric_two_layer_and_connect():
    meshio = pytest.importorskip("meshio")
    vol = balloon.volumetric(steps=2)
    m = vol.to_meshio()
    assert np.array_equal(m.points, vol["surface_positions"])
    assert np.array_equal(m.cells[0].data, vol["surface_triangles"])
    sim = balloon.Volumetric()
    assert np.array_equal(sim.mesh_arrays()[1], sim.surface_triangles)
    tl = balloon.two_layer(steps=2)
    v, f = tl.mesh_arrays()
    assert np.array_equal(v, tl["positions"]) and f.shape == (0, 3)
    assert tl.to_meshio().cells[0].type == "vertex"
    assert balloon.TwoLayer().to_meshio().points.shape[1] == 3
    c = balloon.connect("builtin:sphere", copies=2, stretches=[1.1, 1.2], steps=1)
    m = c.to_meshio()
    owner = m.point_data["balloon"]
    o = c["vertex_offsets"]
    assert (owner[o[0]:o[1]] == 0).all() and (owner[o[1]:o[2]] == 1).all()
    assert isinstance(m, meshio.Mesh)


def test_not_a_result_is_a_type_error():
    with pytest.raises(TypeError, match="not a balloon result"):
        balloon.mesh_arrays({"summary": {}})


def test_missing_meshio_is_a_clear_import_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "meshio", None)
    with pytest.raises(ImportError, match="pip install meshio"):
        balloon.to_meshio(balloon.Shell("builtin:sphere"))
