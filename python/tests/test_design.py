"""``balloon.design``: the rest shape that inflates to a given shape (docs/design.md)."""

import numpy as np
import pytest

import balloon

MU = 4.0e5
H = 1.0e-3


def icosphere(radius, level):
    """An icosphere (subdivided icosahedron, outward triangles) as (vertices, faces)."""
    t = (1.0 + 5.0**0.5) / 2.0
    verts = [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1),
    ]
    faces = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
        (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
        (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
        (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]
    verts = [np.array(v, dtype=float) / np.linalg.norm(v) for v in verts]
    for _ in range(level):
        mid = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mid[key] = len(verts) - 1
            return mid[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return radius * np.array(verts), np.array(faces, dtype=np.int64)


def thin_sphere_pressure(r0, stretch):
    """The thin incompressible neo-Hookean sphere: p = 2 mu H / R0 (1/l - 1/l^7)."""
    return 2.0 * MU * H / r0 * (1.0 / stretch - stretch**-7)


def flat_poled_icosphere():
    """The level-1 icosphere of radius 0.1 m with its poles cut flat (|z| <= 0.05 m): a target
    that no rest shape holds exactly under pressure (a flat membrane face)."""
    vertices, faces = icosphere(0.1, 1)
    vertices[:, 2] = np.clip(vertices[:, 2], -0.05, 0.05)
    return vertices, faces


def test_sphere_rest_radius_matches_the_thin_sphere_curve(tmp_path):
    vertices, faces = icosphere(0.1, 3)
    assert vertices.shape == (642, 3)
    stretch = 1.25
    r0 = 0.1 / stretch
    r = balloon.design(
        vertices,
        faces,
        pressure=thin_sphere_pressure(r0, stretch),
        thickness=H,
        material="membrane-neo-hookean",
        mu=MU,
        out=tmp_path / "d",
    )
    s = r["summary"]
    assert s["converged"] and s["check"]["converged"], s
    assert r["rest"].shape == (642, 3) and r["rest"].dtype == np.float64
    assert r["inflated"].shape == (642, 3)
    rest_radius = np.linalg.norm(r["rest"], axis=1).mean()
    assert abs(rest_radius - r0) / r0 < 5e-3, rest_radius
    # The check lands on the target and repeats the summary's figure.
    assert np.abs(r["inflated"] - vertices).max() < 1e-4 * s["bbox_diagonal"]
    assert s["check"]["distance"]["max_relative"] < 1e-4
    assert (tmp_path / "d" / "rest.obj").exists()
    assert "--volume-projection off" in s["check_command"]


def test_design_errors_name_the_parameter():
    vertices, faces = icosphere(0.1, 1)
    with pytest.raises(balloon.InvalidOption, match="pressure"):
        balloon.design(vertices, faces, pressure=-5.0)
    with pytest.raises(balloon.InvalidOption, match="thickness"):
        balloon.design(vertices, faces, pressure=100.0, thickness=-1.0)
    with pytest.raises(balloon.InvalidOption, match="tolerance"):
        balloon.design(vertices, faces, pressure=100.0, tolerance=2.0)
    with pytest.raises(balloon.InvalidOption, match="steps"):
        balloon.design(vertices, faces, pressure=100.0, steps=3)
    with pytest.raises(balloon.InvalidOption, match="fallback"):
        balloon.design(vertices, faces, pressure=100.0, fallback="sometimes")
    with pytest.raises(balloon.InvalidOption, match="fallback_iterations"):
        balloon.design(vertices, faces, pressure=100.0, fallback_iterations=0)
    # The shape optimisation's options, checked as a scenario's [design] table checks them.
    with pytest.raises(balloon.InvalidOption, match='`method` = .newton. is not allowed'):
        balloon.design(vertices, faces, pressure=100.0, method="newton")
    with pytest.raises(balloon.InvalidOption, match="`method` must be a string"):
        balloon.design(vertices, faces, pressure=100.0, method=2)
    with pytest.raises(balloon.InvalidOption, match="`shape_stages` = 2.5 is not allowed"):
        balloon.design(vertices, faces, pressure=100.0, shape_stages=2.5)
    with pytest.raises(balloon.InvalidOption, match="`shape_weight` must be a number"):
        balloon.design(vertices, faces, pressure=100.0, shape_weight=[1.0])
    with pytest.raises(balloon.InvalidOption, match="`newton_polish` must be true or false"):
        balloon.design(vertices, faces, pressure=100.0, newton_polish="yes")
    with pytest.raises(balloon.MeshError):
        balloon.design(vertices, faces[:, :2], pressure=100.0)
    # An open surface is not a target.
    with pytest.raises(balloon.MeshError, match="closed"):
        balloon.design(vertices, faces[1:], pressure=100.0)
    # Every error is a BalloonError.
    with pytest.raises(balloon.BalloonError):
        balloon.design(vertices, faces, pressure=100.0, material="rubber")


def test_flat_faced_target_gets_the_shape_optimisation():
    # An icosphere with its poles cut flat (|z| <= 0.05 m): no rest shape holds a flat
    # membrane face under pressure, so the inverse does not converge; the shape optimisation
    # reduces the distance of the forward equilibrium and the design still says NOT converged.
    vertices, faces = flat_poled_icosphere()
    options = dict(pressure=2000.0, thickness=H, material="membrane-neo-hookean", mu=MU)
    plain = balloon.design(vertices, faces, fallback="off", **options)["summary"]
    assert not plain["converged"]
    assert plain["inverse"]["fallback"] is None
    assert not plain["accepted"]
    # A distance the user accepts: the same design answers the target within it.
    near = plain["check"]["distance"]["max_relative"]
    accepted = balloon.design(
        vertices, faces, fallback="off", accept_distance=2 * near, **options
    )["summary"]
    assert accepted["accepted"] and not accepted["converged"], accepted
    with pytest.raises(balloon.InvalidOption, match="accept_distance"):
        balloon.design(vertices, faces, accept_distance=-1.0, **options)
    r = balloon.design(vertices, faces, fallback_iterations=20, **options)
    s = r["summary"]
    assert not s["converged"]
    f = s["inverse"]["fallback"]
    assert f["iterations"] > 0, f
    assert f["end"]["rms"] < f["start"]["rms"], f
    assert abs(f["start"]["rms"] - plain["check"]["distance"]["rms"]) < 1e-9
    assert s["check"]["distance"]["rms"] < plain["check"]["distance"]["rms"]
    assert np.isfinite(r["rest"]).all()


def test_the_shape_optimisations_options_reach_the_library():
    # The flat-poled icosphere again, with L-BFGS, the shape term in two stages and warm starts:
    # the record shows the loop and the stages asked for, and summary["params"] lists them.
    vertices, faces = flat_poled_icosphere()
    s = balloon.design(
        vertices,
        faces,
        pressure=2000.0,
        thickness=H,
        material="membrane-neo-hookean",
        mu=MU,
        fallback_iterations=3,
        method="lbfgs",
        shape_weight=np.float64(1.0),
        shape_stages=2,
        warm_start=True,
    )["summary"]
    p = s["params"]["fallback"]
    assert p["method"] == "lbfgs" and p["shape_weight"] == 1.0 and p["shape_stages"] == 2, p
    assert p["warm_start"] is True and p["newton_polish"] is False and p["max_iterations"] == 3
    f = s["inverse"]["fallback"]
    assert f["gauss_newton_steps"] == 0, f
    assert f["shape_stages"] == 2, f
    assert 0 < f["iterations"] <= 9, f


def test_a_gas_amount_is_the_load_of_its_pressure_at_the_target():
    # The amount of ideal gas that has the thin-sphere pressure over the atmosphere at the
    # target: the same gauge pressure and (up to rounding) the same rest shape as the pressure
    # design, and a forward check with the gas that lands on the target.
    vertices, faces = icosphere(0.1, 2)
    stretch = 1.25
    p = thin_sphere_pressure(0.1 / stretch, stretch)
    wall = dict(thickness=H, material="membrane-neo-hookean", mu=MU)
    by_pressure = balloon.design(vertices, faces, pressure=p, **wall)
    volume = by_pressure["summary"]["target_volume"]
    amount = (p + 101325.0) * volume
    by_gas = balloon.design(vertices, faces, gas_amount=amount, **wall)
    s = by_gas["summary"]
    assert s["converged"] and s["check"]["converged"], s
    assert abs(s["pressure"] - p) < 1e-9 * p, s["pressure"]
    assert s["gas_amount"] == amount and s["ambient"] == 101325.0
    assert np.abs(by_gas["rest"] - by_pressure["rest"]).max() < 1e-9
    assert abs(s["check"]["volume"] - volume) < 1e-6 * volume
    with pytest.raises(balloon.InvalidOption, match="either"):
        balloon.design(vertices, faces, pressure=p, gas_amount=amount)
    with pytest.raises(balloon.InvalidOption, match="give the load"):
        balloon.design(vertices, faces, **wall)
    with pytest.raises(balloon.InvalidOption, match="ambient"):
        balloon.design(vertices, faces, pressure=p, ambient=1e5)
    with pytest.raises(balloon.InvalidOption, match="gas_amount"):
        balloon.design(vertices, faces, gas_amount=-1.0)
    # Below the atmosphere at the target: named, not a failed solve.
    with pytest.raises(balloon.InvalidOption, match="gas_amount"):
        balloon.design(vertices, faces, gas_amount=0.5 * 101325.0 * volume, **wall)


def test_the_thickness_fit_runs_on_the_designed_rest_shape(tmp_path):
    # The flat-poled icosphere again, without the shape optimisation: the wall-thickness fit
    # (rest shape fixed, one thickness per face within the bounds) reduces the distance the
    # inverse left, returns the map, and writes it into rest.ply for `balloon inflate`.
    vertices, faces = flat_poled_icosphere()
    r = balloon.design(
        vertices,
        faces,
        pressure=2000.0,
        thickness=H,
        material="membrane-neo-hookean",
        mu=MU,
        fallback="off",
        fit_thickness=True,
        thickness_min=0.5 * H,
        thickness_max=2.0 * H,
        thickness_iterations=10,
        out=tmp_path / "d",
    )
    s = r["summary"]
    fit = s["thickness_fit"]
    assert fit["iterations"] > 0, fit
    assert fit["end"]["rms"] < fit["start"]["rms"], fit
    assert (fit["lower"], fit["upper"]) == (0.5 * H, 2.0 * H)
    assert r["thickness"].shape == (len(faces),)
    assert (r["thickness"] >= 0.5 * H).all() and (r["thickness"] <= 2.0 * H).all()
    assert abs(r["thickness"].min() - fit["min"]) < 1e-15
    assert np.ptp(r["thickness"]) > 0.0
    assert (tmp_path / "d" / "rest.ply").exists()
    assert "rest.ply" in s["check_command"]
    # The check uses the fitted wall: its distance is the fit's end.
    assert abs(s["check"]["distance"]["rms"] - fit["end"]["rms"]) < 1e-9
    with pytest.raises(balloon.InvalidOption, match="thickness_min"):
        balloon.design(vertices, faces, pressure=2000.0, thickness_min=-1.0)


def test_a_given_rest_shape_is_kept_and_its_wall_fitted():
    # The icosphere shrunk by 10 % as the rest shape to keep (a mould one has), the icosphere as
    # the target: no inverse iterations, the rest shape returned as given, the wall fitted.
    vertices, faces = icosphere(0.1, 1)
    rest = 0.9 * vertices
    r = balloon.design(
        vertices,
        faces,
        pressure=2000.0,
        thickness=H,
        material="membrane-neo-hookean",
        mu=MU,
        rest=rest,
        fit_thickness=True,
        thickness_iterations=20,
    )
    s = r["summary"]
    assert s["inverse"]["iterations"] == 0
    assert np.abs(r["rest"] - rest).max() < 1e-12
    fit = s["thickness_fit"]
    assert fit["end"]["rms"] < fit["start"]["rms"], fit
    with pytest.raises(balloon.MeshError):
        balloon.design(vertices, faces, pressure=2000.0, rest=rest[:-1])


def test_the_rest_shape_conditioning_is_returned_when_asked():
    # The icosphere kept as the rest shape of itself at 2 kPa (a membrane wall): with
    # conditioning=True the summary has the smallest singular values of dr/dX outside the
    # rigid motions (ascending, below the largest) and the forward gain of each; without, None.
    vertices, faces = icosphere(0.1, 1)
    options = dict(
        pressure=2000.0, thickness=H, material="membrane-neo-hookean", mu=MU, rest=0.9 * vertices
    )
    r = balloon.design(vertices, faces, conditioning=True, **options)
    c = r["summary"]["conditioning"]
    smallest = np.array(c["smallest"])
    assert smallest.shape == (6,)
    assert (smallest > 0.0).all() and (np.diff(smallest) >= 0.0).all(), c
    assert smallest[-1] < c["largest"]
    assert np.allclose(c["relative"], smallest / c["largest"], rtol=1e-12)
    assert len(c["forward_gain"]) == 6
    modes = r["conditioning_modes"]
    assert modes.shape == (6, len(vertices), 3)
    assert np.allclose((modes**2).sum(axis=(1, 2)), 1.0)
    plain = balloon.design(vertices, faces, **options)
    assert plain["summary"]["conditioning"] is None and plain["conditioning_modes"] is None
    with pytest.raises(balloon.InvalidOption, match="conditioning"):
        balloon.design(vertices, faces, conditioning=1.5, **options)


def test_the_bending_wall_reaches_the_design():
    # bending=F designs with the wall's bending stiffness (docs/design.md D20), recorded in the
    # summary's params: a bent rest shape kept for the icosphere has another equilibrium
    # residual with it than without; a bad factor names the option.
    vertices, faces = icosphere(0.1, 1)
    rest = 0.9 * vertices
    rest[0] *= 0.97
    options = dict(pressure=2000.0, thickness=H, material="membrane-neo-hookean", mu=MU, rest=rest)
    bent = balloon.design(vertices, faces, bending=1.0, **options)
    plain = balloon.design(vertices, faces, **options)
    assert bent["summary"]["params"]["wall_bending"] == 1.0
    assert plain["summary"]["params"]["wall_bending"] == 0.0
    residual = [r["summary"]["inverse"]["relative_residual"] for r in (bent, plain)]
    assert residual[0] != residual[1], residual
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(balloon.InvalidOption, match="bending"):
            balloon.design(vertices, faces, bending=bad, **options)


def test_design_refuses_the_folder_of_an_earlier_design_unless_overwrite(tmp_path):
    vertices, faces = icosphere(0.1, 1)
    out = tmp_path / "d"
    balloon.design(vertices, faces, pressure=100.0, out=out)
    (out / "mine.txt").write_text("mine")
    with pytest.raises(balloon.BalloonError, match="earlier design"):
        balloon.design(vertices, faces, pressure=100.0, out=out)
    with pytest.raises(balloon.InvalidOption, match="overwrite"):
        balloon.design(vertices, faces, pressure=100.0, out=out, overwrite="yes")
    r = balloon.design(vertices, faces, pressure=100.0, out=out, overwrite=True)
    assert r["summary"]["converged"]
    assert (out / "mine.txt").read_text() == "mine"
    assert (out / "rest.obj").exists()
