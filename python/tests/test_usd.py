"""`--format usd` read back with Pixar's own USD library (`usd-core`): one stage per run with a
mesh prim per body, its topology once and its points time-sampled at every written frame equal
to the OBJ run's frames, the fields as primvars, the stage's time range the simulated time, the
volumetric scene's sphere and floor as prims, a prim per balloon for `connect`, and a valid
stage when the run stops early."""

import json
import subprocess

import numpy as np
import pytest

from conftest import read_obj_vertices

Usd = pytest.importorskip("pxr.Usd")
from pxr import UsdGeom  # noqa: E402


def run(cli, args):
    p = subprocess.run([cli, *args, "--json"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def open_stage(path):
    stage = Usd.Stage.Open(str(path))
    assert stage is not None, path
    return stage


def frames_of(folder):
    return sorted(folder.glob("frame_*.obj"))


def test_inflate_stage_matches_the_obj_frames(cli, tmp_path):
    args = ["inflate", "builtin:sphere", "--steps", "6", "--frame-every", "2", "--gas", "ideal",
            "--pressure", "1200", "--dt", "0.002"]
    run(cli, [*args, "--out", str(tmp_path / "obj")])
    run(cli, [*args, "--out", str(tmp_path / "usd"), "--format", "usd"])
    assert not list((tmp_path / "usd").glob("frame_*"))
    stage = open_stage(tmp_path / "usd" / "run.usda")
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    objs = frames_of(tmp_path / "obj")
    assert len(objs) == 4  # steps 0, 2, 4, 6
    # The time range is the simulated time: 6 steps of 2 ms.
    seconds = (stage.GetEndTimeCode() - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    assert seconds == pytest.approx(6 * 0.002, rel=1e-9)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/balloon"))
    assert mesh
    points = mesh.GetPointsAttr()
    times = points.GetTimeSamples()
    assert times == [0.0, 1.0, 2.0, 3.0]
    time_attr = stage.GetPrimAtPath("/World").GetAttribute("balloon:time")
    for code, obj in zip(times, objs):
        x = np.array(points.Get(code), dtype=np.float64)
        ref = read_obj_vertices(obj)
        assert x.shape == ref.shape
        # points are single precision (point3f): equal to the OBJ's doubles to float32 rounding.
        assert np.allclose(x, ref, rtol=0, atol=1e-7 * np.abs(ref).max())
        step = int(obj.stem.split("_")[1])
        assert time_attr.Get(code) == pytest.approx(step * 0.002, rel=1e-12)
    # The topology is the OBJ's, once.
    counts = mesh.GetFaceVertexCountsAttr()
    assert counts.GetNumTimeSamples() == 0 and set(counts.Get()) == {3}
    faces = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    ref_faces = [
        [int(i) - 1 for i in line.split()[1:4]]
        for line in objs[0].read_text().splitlines() if line.startswith("f ")
    ]
    assert np.array_equal(faces, np.array(ref_faces))
    # Fields as primvars: per face thickness and stretch, per vertex pressure force, and the
    # gas pressure per body; the thickness shrinks as the balloon stretches.
    api = UsdGeom.PrimvarsAPI(mesh)
    thickness = api.GetPrimvar("thickness")
    assert thickness.GetInterpolation() == UsdGeom.Tokens.uniform
    assert len(thickness.Get(0.0)) == len(faces)
    assert np.mean(thickness.Get(3.0)) < np.mean(thickness.Get(0.0))
    assert api.GetPrimvar("stretch").GetInterpolation() == UsdGeom.Tokens.uniform
    assert api.GetPrimvar("pressure_force").GetInterpolation() == UsdGeom.Tokens.vertex
    pressure = api.GetPrimvar("pressure")
    assert pressure.GetInterpolation() == UsdGeom.Tokens.constant
    assert pressure.GetAttr().GetTimeSamples() == times
    assert len(mesh.GetVelocitiesAttr().Get(3.0)) == len(ref)


def test_connect_has_a_prim_per_balloon(cli, tmp_path):
    out = tmp_path / "usd"
    run(cli, ["connect", "builtin:sphere", "--copies", "2", "--stretches", "1.1,1.2",
              "--steps", "2", "--frame-every", "1", "--out", str(out), "--format", "usd"])
    stage = open_stage(out / "run.usda")
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert [p.GetName() for p in meshes] == ["balloon_0", "balloon_1"]
    for p in meshes:
        m = UsdGeom.Mesh(p)
        assert len(m.GetPointsAttr().Get(0.0)) == 2562
        assert m.GetPointsAttr().GetNumTimeSamples() == 3
        assert UsdGeom.PrimvarsAPI(m).GetPrimvar("pressure").Get(2.0) > 0.0


def test_volumetric_scene_has_sphere_and_floor(cli, tmp_path):
    out = tmp_path / "usd"
    run(cli, ["volumetric", "--scene", "drop-sphere", "--steps", "4", "--frame-every", "2",
              "--out", str(out), "--format", "usd"])
    stage = open_stage(out / "run.usda")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/World/body"))
    assert body.GetPointsAttr().GetNumTimeSamples() == 3
    sphere = stage.GetPrimAtPath("/World/sphere")
    floor = stage.GetPrimAtPath("/World/floor")
    assert sphere and floor
    xf = UsdGeom.Xformable(sphere)
    t0 = xf.ComputeLocalToWorldTransform(0.0).ExtractTranslation()
    t2 = xf.ComputeLocalToWorldTransform(2.0).ExtractTranslation()
    assert t2[2] < t0[2]  # the sphere falls
    assert UsdGeom.Mesh(floor).GetPointsAttr().GetNumTimeSamples() == 0


def test_volumetric_floor_scene_with_y_up(cli, tmp_path):
    # The viewer's built-in set-up as a scenario (`scene = "floor"`, `up = "y"`): the stage's
    # up axis follows `up`, the floor is a horizontal plane in that frame just under the body,
    # there is no sphere, and the body falls along -y.
    out = tmp_path / "usd"
    run(cli, ["volumetric", "--scene", "floor", "--up", "y", "--steps", "4", "--frame-every",
              "2", "--out", str(out), "--format", "usd"])
    stage = open_stage(out / "run.usda")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert not stage.GetPrimAtPath("/World/sphere")
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/World/body")).GetPointsAttr()
    assert body.GetNumTimeSamples() == 3
    floor = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/World/floor")).GetPointsAttr().Get(),
                     dtype=np.float64)
    first = np.array(body.Get(0.0), dtype=np.float64)
    last = np.array(body.Get(2.0), dtype=np.float64)
    assert np.ptp(floor[:, 1]) == 0.0  # horizontal with y up
    assert floor[0, 1] < first[:, 1].min()  # under the body
    fall = first.mean(axis=0) - last.mean(axis=0)
    assert fall[1] > 0.0 and abs(fall[1]) > 100 * max(abs(fall[0]), abs(fall[2])), fall


def test_two_layer_and_the_scenario_key(cli, tmp_path):
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        '[system]\nkind = "two-layer"\n[run]\nsteps = 3\n[output]\nformat = "usd"\nframe_every = 1\n'
        f'out = "{tmp_path / "usd"}"\n'
    )
    run(cli, ["run", str(scenario)])
    stage = open_stage(tmp_path / "usd" / "run.usda")
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/World/body"))
    assert body.GetPointsAttr().GetNumTimeSamples() == 4


def test_an_interrupted_run_leaves_a_valid_stage(cli, tmp_path):
    """A long run stopped by SIGINT keeps every frame written before it in a valid stage whose
    end time code is its last sample (the file is valid after every frame; the Rust tests read
    it between frames without the final rewrite)."""
    import signal
    import time

    out = tmp_path / "usd"
    p = subprocess.Popen(
        [cli, "inflate", "builtin:sphere", "--steps", "100000", "--gas", "constant",
         "--pressure", "500", "--frame-every", "1", "--out", str(out), "--format", "usd"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    stage_file = out / "run.usda"
    deadline = time.time() + 60
    stats = out / "stats.jsonl"
    while time.time() < deadline and (
        not stats.exists() or len(stats.read_text().splitlines()) < 3
    ):
        time.sleep(0.2)
    p.send_signal(signal.SIGINT)
    p.communicate(timeout=60)
    stage = open_stage(stage_file)
    n = UsdGeom.Mesh(stage.GetPrimAtPath("/World/balloon")).GetPointsAttr().GetNumTimeSamples()
    assert n >= 2
    assert stage.GetEndTimeCode() == n - 1
