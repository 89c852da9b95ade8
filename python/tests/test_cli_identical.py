"""The same job through the CLI and through Python gives bit-identical final positions.

What is compared: the CLI's `final.obj` (shell) or last frame (volumetric, two-layer) from
`--out`, whose coordinates are written as Rust's shortest round-trip decimal text, so parsing
them gives back the exact float64 values; against the Python result's arrays with
`np.array_equal` (no tolerance). The CLI's `--json` summary line is compared too, every key
except the wall-clock timings.
"""

import json
import subprocess

import numpy as np

import balloon
from conftest import read_obj_vertices, without_timing


def run_cli(cli, args):
    run = subprocess.run([cli, *args, "--json"], capture_output=True, text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_inflate_is_bit_identical_to_the_cli(cli, tmp_path):
    out = tmp_path / "cli"
    summary = run_cli(
        cli,
        ["inflate", "builtin:sphere", "--steps", "6", "--gas", "ideal", "--pressure", "1200",
         "--material", "neo-hookean", "--linear-solver", "pcg", "--out", str(out)],
    )
    r = balloon.inflate(
        "builtin:sphere", steps=6, gas="ideal", pressure=1200.0, material="neo-hookean",
        linear_solver="pcg", out=tmp_path / "py",
    )
    cli_x = read_obj_vertices(out / "final.obj")
    assert cli_x.shape == r["positions"].shape
    assert np.array_equal(cli_x, r["positions"])
    assert without_timing(summary) == without_timing(r["summary"])
    # The summary.json of the CLI run is the same record.
    written = json.loads((out / "summary.json").read_text())
    assert without_timing(written) == without_timing(r["summary"])


def test_python_out_folder_matches_the_cli_folder(cli, tmp_path):
    run_cli(cli, ["inflate", "builtin:sphere", "--steps", "3", "--gas", "constant",
                  "--out", str(tmp_path / "cli")])
    balloon.inflate("builtin:sphere", steps=3, gas="constant", out=tmp_path / "py")
    for name in ["final.obj", "frame_00000.obj", "stats.jsonl"]:
        a = (tmp_path / "cli" / name).read_text()
        b = (tmp_path / "py" / name).read_text()
        if name == "stats.jsonl":
            strip = lambda t: [without_timing(json.loads(l)) | {"step_ms": 0} for l in t.splitlines()]
            assert strip(a) == strip(b)
        else:
            assert a == b, name
    # The recorded scenarios are identical: the Python keywords became the same flags.
    assert (tmp_path / "cli" / "scenario.toml").read_text() == (
        tmp_path / "py" / "scenario.toml"
    ).read_text()


def test_volumetric_and_two_layer_are_bit_identical_to_the_cli(cli, tmp_path):
    out = tmp_path / "vol"
    summary = run_cli(cli, ["volumetric", "builtin:sphere", "--cells", "60", "--steps", "6",
                            "--frame-every", "3", "--out", str(out)])
    r = balloon.volumetric(
        "builtin:sphere", cells=60, steps=6, frame_every=3, out=tmp_path / "vol-py"
    )
    assert np.array_equal(read_obj_vertices(out / "frame_00006.obj"), r["surface_positions"])
    assert without_timing(summary) == without_timing(r["summary"])

    out = tmp_path / "two"
    summary = run_cli(cli, ["two-layer", "--steps", "40", "--frame-every", "0",
                            "--drag", "0,0,2@0:0.01", "--out", str(out)])
    r = balloon.two_layer(
        steps=40, frame_every=0, drag="0,0,2@0:0.01", out=tmp_path / "two-py"
    )
    assert np.array_equal(read_obj_vertices(out / "frame_00040.obj"), r["positions"])
    assert without_timing(summary) == without_timing(r["summary"])


def test_static_continuation_is_identical_to_the_cli_and_on_the_analytic_curve(cli, tmp_path):
    """`static=True` with a volume continuation: the same final shape, summary and points as
    `balloon inflate --static`, and the pressures on the thin-sphere curve of the neo-Hookean
    membrane, P(l) = 2 mu H / R (1/l - 1/l^7) (docs/membranes.md M18)."""
    mu, h0 = 4.0e5, 1.0e-3
    out = tmp_path / "cli"
    summary = run_cli(
        cli,
        ["inflate", "builtin:sphere", "--static", "--gas", "volume", "--volume-ratios",
         "1.5:3.0:0.5", "--material", "membrane-neo-hookean", "--mu", str(mu), "--thickness",
         str(h0), "--out", str(out)],
    )
    r = balloon.inflate(
        "builtin:sphere", static=True, gas="volume", volume_ratios="1.5:3.0:0.5",
        material="membrane-neo-hookean", mu=mu, thickness=h0, out=tmp_path / "py",
    )
    assert np.array_equal(read_obj_vertices(out / "final.obj"), r["positions"])
    assert without_timing(summary) == without_timing(r["summary"])
    lines = [json.loads(l) for l in (out / "stats.jsonl").read_text().splitlines()]
    assert [without_timing(p) for p in r["points"]] == [without_timing(p) for p in lines]
    assert [p["volume_ratio"] for p in r["points"]] == [1.5, 2.0, 2.5, 3.0]
    # Independent check: the built-in sphere's radius from its rest volume.
    radius = (3.0 * r["summary"]["initial_gas_volume"] / (4.0 * np.pi)) ** (1.0 / 3.0)
    for p in r["points"]:
        l = p["volume_ratio"] ** (1.0 / 3.0)
        analytic = 2.0 * mu * h0 / radius * (1.0 / l - l ** -7)
        assert abs(p["gauge_pressure"] / analytic - 1.0) < 5e-3, (p, analytic)
        # Incompressible: the thickness is H / l^2 (mean over the elements).
        assert abs(p["thickness_mean"] * l * l / h0 - 1.0) < 5e-3, p
    # The last point's thickness is the summary's and the returned array's.
    assert np.isclose(r["thickness"].mean(), r["summary"]["final_thickness_mean"], rtol=1e-12)


def test_connect_is_identical_to_the_cli_and_reaches_the_analytic_end_state(cli, tmp_path):
    """Two connected balloons (`balloon connect`, issue 14): the same end state as the CLI bit
    for bit, and the analytic two-balloon end state (`ThinSphere::joined_pair`) that the summary
    reports, within 1e-3 of the stretches."""
    # A level-2 icosphere (162 vertices) of radius 0.1 m, written as the CLI test does.
    t = (1.0 + 5 ** 0.5) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(v, dtype=float) / np.linalg.norm(v) for v in verts]
    for _ in range(2):
        cache, new_faces = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new_faces
    mesh = tmp_path / "ico2.obj"
    mesh.write_text("".join(f"v {0.1 * x} {0.1 * y} {0.1 * z}\n" for x, y, z in verts)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    flags = ["--copies", "2", "--stretches", "1.35,1.6", "--conductance", "instant",
             "--until-settled", "--volume-tol", "1e-8", "--steps", "3000", "--material",
             "membrane-neo-hookean", "--mu", "4e5", "--thickness", "1e-3", "--mass-damping", "5"]
    out = tmp_path / "cli"
    summary = run_cli(cli, ["connect", str(mesh), *flags, "--out", str(out)])
    r = balloon.connect(
        str(mesh), copies=2, stretches=[1.35, 1.6], conductance="instant", until_settled=True,
        volume_tol=1e-8, steps=3000, material="membrane-neo-hookean", mu=4e5, thickness=1e-3,
        mass_damping=5.0, out=tmp_path / "py",
    )
    assert without_timing(summary) == without_timing(r["summary"])
    assert np.array_equal(read_obj_vertices(out / "final.obj"), r["positions"])
    assert r["vertex_offsets"] == [0, 162, 324]
    assert r["triangles"].shape == (640, 3) and r["triangles"].max() == 323
    s = r["summary"]
    assert s["settled"] is True
    # The end state against the analytic one, and the stretch measured from the positions of
    # each balloon (the cube root of its enclosed volume over the rest volume).
    want = [s["analytic"]["small_stretch"], s["analytic"]["large_stretch"]]
    got = sorted(b["stretch"] for b in s["balloon_states"])
    for g, w in zip(got, want):
        assert abs(g / w - 1.0) < 1e-3, (got, want)
    x, tri = r["positions"], r["triangles"]
    for i in range(2):
        lo, hi = r["vertex_offsets"][i], r["vertex_offsets"][i + 1]
        t_i = tri[(tri[:, 0] >= lo) & (tri[:, 0] < hi)]
        a, b, c = x[t_i[:, 0]], x[t_i[:, 1]], x[t_i[:, 2]]
        volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
        rest = s["balloon_states"][i]["rest_gas_volume"]
        assert abs((volume / rest) ** (1.0 / 3.0) / s["balloon_states"][i]["stretch"] - 1.0) < 1e-9


def test_wall_bending_is_the_same_through_python_and_the_cli(cli, tmp_path):
    # `bending` is the `[shell]` key of the wall's bending stiffness (`--bending`).
    summary = run_cli(
        cli, ["inflate", "builtin:sphere", "--steps", "3", "--bending", "50",
              "--out", str(tmp_path / "cli")],
    )
    r = balloon.inflate("builtin:sphere", steps=3, bending=50.0, out=tmp_path / "py")
    assert summary["scenario"]["shell"]["bending"] == 50.0
    assert np.array_equal(read_obj_vertices(tmp_path / "cli" / "final.obj"), r["positions"])
    assert without_timing(summary) == without_timing(r["summary"])
