"""A body from an STL surface: a triangulated sphere written as STL (meshio), filled with
tetrahedra by Gmsh (``femp.mesh.tetrahedralize``, as ``python -m femp.mesh ball.stl ball.msh``),
and used as an MPM body's shape (``femp.spec.MeshFile``, the same spelling as a FEM body's mesh)
falling onto a fixed FEM plate in 3D.

Checks: the tetrahedra fill exactly the surface's volume (the surface's triangles are kept); the
particles sampled inside them weigh what the volume does to within the lattice's resolution; and
until it nears the plate the ball falls as backward Euler's discrete free fall,
``z0 − g Δt² n(n + 1)/2`` after n steps.

    python crates/python/examples/mesh_from_stl.py --out out/stl

Needs ``pip install gmsh meshio``. Returns 0 when the checks hold.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Optional, Sequence, Tuple

import meshio
import numpy as np

import femp
import femp.mesh
from femp import spec

G = 9.81


def icosphere(radius: float, subdivisions: int) -> Tuple[np.ndarray, np.ndarray]:
    """A triangulated sphere: an icosahedron's faces split ``subdivisions`` times, projected."""
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    pts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = f
    for _ in range(subdivisions):
        mid: dict = {}

        def middle(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = pts[a] + pts[b]
                pts.append(m / np.linalg.norm(m))
                mid[key] = len(pts) - 1
            return mid[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = new
    return radius * np.array(pts), np.array(faces)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/stl", help="directory for ball.stl, ball.msh")
    ap.add_argument("--steps", type=int, default=8)
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    r, z0 = 0.2, 0.5
    points, triangles = icosphere(r, 2)
    stl = os.path.join(args.out, "ball.stl")
    meshio.write_points_cells(stl, points + [0, 0, z0], [("triangle", triangles)])
    info = femp.mesh.tetrahedralize(stl, os.path.join(args.out, "ball.msh"))
    surface = femp.mesh.surface_volume(points, triangles)
    print(f"{info['tetrahedra']} tetrahedra, volume {info['volume']:.6f} m³ "
          f"(surface {surface:.6f} m³, sphere {4 / 3 * np.pi * r ** 3:.6f} m³)")

    h, rho = 0.05, 1000.0
    s = spec.SceneSpec(
        dimension=3, gravity=[0, 0, -G],
        time=spec.Time(dt=0.01, duration=1.0),
        mpm=spec.MpmGrid(grid_spacing=h),
        bodies=[
            spec.MpmBody("ball", spec.MeshFile("ball.msh"), spec.Material(E=1e5, nu=0.3, rho=rho)),
            spec.FemBody("plate", spec.Cuboid(min=[-0.5, -0.5, -0.1], max=[0.5, 0.5, 0.0],
                                              cells=[4, 4, 1]),
                         spec.Material(E=1e7, nu=0.3, rho=rho),
                         prescribed=[spec.Prescribed("all")]),
        ],
        contact=spec.Contact(dhat=0.005, kappa=1e5),
    )
    world = femp.World(s.build(base_dir=args.out))
    p = world.particles()
    mass = p["mass"].sum()
    print(f"{len(p['mass'])} particles, {mass:.3f} kg (volume × ρ = {info['volume'] * rho:.3f} kg)")
    z_start = float(p["mass"] @ p["x"][:, 2] / mass)
    worst = 0.0
    for n in range(1, args.steps + 1):
        world.step()
        p = world.particles()
        z = float(p["mass"] @ p["x"][:, 2] / mass)
        expect = z_start - G * world.dt ** 2 * n * (n + 1) / 2
        worst = max(worst, abs(z - expect))
        print(f"t = {world.time:.2f} s: centre of mass at z = {z:.6f} m (free fall {expect:.6f})")
    ok = (abs(info["volume"] - surface) < 1e-9 * surface
          and abs(mass / (info["volume"] * rho) - 1) < 0.05 and worst < 1e-6
          and world.metrics()["penetrations"] == 0)
    print(f"volume exact, mass within 5 %, free fall to {worst:.1e} m: {ok}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
