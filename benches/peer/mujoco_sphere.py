#!/usr/bin/env python3
"""The peer comparison of issue 12 run in MuJoCo: the pressurised sphere brought to rest.

Loads a closed triangle mesh (OBJ, `v`/`f` lines; `cargo xtask bench --converged sphere` writes
the icosphere the Rust solvers use), builds a MuJoCo 2D flex on it (`flexcomp type="mesh"`,
`dof="full"`, `elastic2d="stretch"`: MuJoCo's StVK membrane) with the peer settings
(E t = 1155 N/m at t = 1 mm, nu = 1/3, 1 kg spread over the vertices, no gravity, mass damping
20 1/s as the dofs' damping), and adds the ideal gas at 377 Pa gauge (ambient 0,
p = p0 V0 / V) as a passive-force callback (MuJoCo's flex has no enclosed-gas pressure; the
force on a vertex is p dV/dx summed over its triangles). Steps with the `discrete` integrator
(MuJoCo 4 integrates 2D flex elasticity implicitly only there) for STEPS steps and reports the
first step after which every vertex stays within 1e-4 of the bounding-box diagonal of the last
step's shape: the steps to rest and their wall time.

Prints one JSON object (times in seconds): `compile_s` (MJCF to model), `steps_to_rest`,
`rest_s` (wall time of those steps), `callback_s` (the Python pressure callback's share of
it), `volume_ratio` (V/V0 at the end), `radius_min`/`radius_max`, `last_change` (largest
vertex move of the last step over the diagonal: how still the end is), and
`analytic_volume_ratio`: the equibiaxial plane-stress StVK sphere at constant thickness,
`p0 / l^2 = E t / (1 - nu) (l^2 - 1)` for the stretch l (the model MuJoCo's membrane is; the
Rust three-prism shell is stiffer in-plane and thins, so its rest volume differs).

Usage: python3 mujoco_sphere.py MESH.obj [--dt 0.03] [--steps 40]
Needs `pip install mujoco` (measured with 4.0.0) and numpy.
"""

import argparse
import json
import sys
import time

import numpy as np


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for lineno, line in enumerate(f, 1):
            parts = line.split()
            if not parts:
                continue
            try:
                if parts[0] == "v":
                    verts.append([float(c) for c in parts[1:4]])
                elif parts[0] == "f":
                    if len(parts) != 4:
                        raise ValueError("only triangles are supported")
                    faces.append([int(c.split("/")[0]) - 1 for c in parts[1:4]])
            except ValueError as e:
                sys.exit(f"{path}:{lineno}: {e}")
    if not verts or not faces:
        sys.exit(f"{path}: no vertices or no triangles")
    return np.array(verts), np.array(faces)


def volume(x, faces):
    a, b, c = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh")
    ap.add_argument("--dt", type=float, default=0.03)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--young-thickness", type=float, default=1155.0)
    ap.add_argument("--thickness", type=float, default=1e-3)
    ap.add_argument("--poisson", type=float, default=1.0 / 3.0)
    ap.add_argument("--mass", type=float, default=1.0)
    ap.add_argument("--pressure", type=float, default=377.0)
    ap.add_argument("--damping", type=float, default=20.0)
    args = ap.parse_args()
    if args.steps < 2 or not args.dt > 0:
        sys.exit("--steps must be at least 2 and --dt positive")
    try:
        import mujoco
    except ImportError:
        sys.exit("MuJoCo is not installed: pip install mujoco")
    verts, faces = read_obj(args.mesh)
    n = len(verts)
    points = " ".join(f"{c:.17g}" for c in verts.ravel())
    elements = " ".join(str(i) for i in faces.ravel())
    xml = f"""<mujoco>
  <option timestep="{args.dt}" gravity="0 0 0" integrator="discrete"/>
  <worldbody>
    <flexcomp name="balloon" type="direct" dim="2" dof="full" mass="{args.mass}"
              radius="{args.thickness}" point="{points}" element="{elements}">
      <contact contype="0" conaffinity="0"/>
      <edge equality="false"/>
      <elasticity young="{args.young_thickness / args.thickness}" poisson="{args.poisson}"
                  thickness="{args.thickness}" elastic2d="stretch"/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    t = time.perf_counter()
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    compile_s = time.perf_counter() - t
    mujoco.mj_forward(m, d)
    # The flex vertices are MuJoCo's own copy of the mesh, in its order.
    x0 = d.flexvert_xpos.copy()
    faces_m = m.flex_elem[: 3 * m.flex_elemnum[0]].reshape(-1, 3)
    v0 = volume(x0, faces_m)
    if not v0 > 0:
        sys.exit(f"{args.mesh}: the mesh encloses no positive volume ({v0:e}); orient it outward")
    bodies = m.flex_vertbodyid[:n]
    if not (m.body_dofnum[bodies] == 3).all():
        sys.exit("every flex vertex should have 3 slide dofs (dof=full)")
    dofs = (m.body_dofadr[bodies][:, None] + np.arange(3)[None, :]).ravel()
    m.dof_damping[dofs] = args.damping * np.repeat(m.body_mass[bodies], 3)
    callback_s = [0.0]

    def pressure(m, d):
        start = time.perf_counter()
        x = d.flexvert_xpos
        a, b, c = x[faces_m[:, 0]], x[faces_m[:, 1]], x[faces_m[:, 2]]
        p = args.pressure * v0 / volume(x, faces_m)
        # dV/dx of a vertex: the sum of (area vector / 3) over its triangles (closed mesh).
        share = np.cross(b - a, c - a) * (p / 6.0)
        f = np.zeros((n, 3))
        for k in range(3):
            np.add.at(f, faces_m[:, k], share)
        d.qfrc_passive[dofs] += f.ravel()
        callback_s[0] += time.perf_counter() - start

    mujoco.set_mjcb_passive(pressure)
    try:
        walls, shapes = [], []
        start = time.perf_counter()
        for _ in range(args.steps):
            mujoco.mj_step(m, d)
            walls.append(time.perf_counter() - start)
            shapes.append(d.flexvert_xpos.copy())
    finally:
        mujoco.set_mjcb_passive(None)
    final = shapes[-1]
    diag = float(np.linalg.norm(final.max(0) - final.min(0)))
    dev = [float(np.linalg.norm(s - final, axis=1).max()) / diag for s in shapes]
    tail = np.maximum.accumulate(dev[::-1])[::-1]
    rest = int(np.argmax(tail < 1e-4))
    last_change = float(np.linalg.norm(shapes[-1] - shapes[-2], axis=1).max()) / diag
    # Plane-stress StVK sphere at constant thickness: with s = l^2,
    # k s^2 - k s - p0 = 0, k = E t / (1 - nu).
    k = args.young_thickness / (1.0 - args.poisson)
    s = (1.0 + np.sqrt(1.0 + 4.0 * args.pressure / k)) / 2.0
    r = np.linalg.norm(final - final.mean(axis=0), axis=1)
    print(
        json.dumps(
            {
                "mujoco": mujoco.__version__,
                "vertices": n,
                "dt": args.dt,
                "compile_s": compile_s,
                "steps_to_rest": rest + 1,
                "rest_s": walls[rest],
                "callback_s": callback_s[0] * (rest + 1) / args.steps,
                "volume_ratio": volume(final, faces_m) / v0,
                "radius_min": float(r.min()),
                "radius_max": float(r.max()),
                "last_change": last_change,
                "analytic_volume_ratio": float(s**1.5),
            }
        )
    )


if __name__ == "__main__":
    main()
