"""femp.contact.ContactMesh against femp-contact's own benchmark and the IPC Toolkit.

    python crates/python/benches/contact_mesh.py [--reps 5]

(a) The scenes of ``cargo bench -p femp-contact --bench contact`` (barrier_2d / barrier_3d: 10⁵
    particles within d̂ = 10⁻³ of 10⁴ edges / 9 800 triangles): broad phase, active terms,
    energy, gradient and the PSD Hessian — from Python, as COO triplets (what the Rust benchmark
    computes) and as a scipy CSR matrix; ipctk 1.6 (``pip install ipctk``) on the same points
    and mesh, its Hessian a CSC matrix.
(b) Two icospheres (162 vertices, 320 triangles each) 0.5 d̂ apart: both one-sided potentials
    with gradients and sparse Hessians plus the CCD of a step closing the gap, against ipctk's
    collisions, potential, gradient, Hessian and CCD on the two spheres as one mesh.

Prints the best time of ``--reps`` for each.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Callable, Optional, Sequence

import numpy as np

import femp.contact as fc

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..", "..")
sys.path.insert(0, os.path.join(ROOT, "fixtures", "ipctk"))
sys.path.insert(0, os.path.join(ROOT, "crates", "python", "examples"))

from bench_ipctk import DHAT, barrier_pipeline, collision_mesh, scene2, scene3  # noqa: E402
from mesh_from_stl import icosphere  # noqa: E402


def best(f: Callable[[], object], reps: int) -> float:
    t = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        t.append(time.perf_counter() - t0)
    return min(t)


def ipctk_or_none() -> Optional[object]:
    try:
        import ipctk
        return ipctk
    except ImportError:
        return None


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    args = ap.parse_args(argv)
    ipctk = ipctk_or_none()
    for name, scene in [("2D", scene2()), ("3D", scene3())]:
        v, edges, faces, p = scene
        facets = edges if faces is None else faces
        m = fc.ContactMesh(v, facets, DHAT, 1e4)
        triplets = best(lambda: m._inner.potential(p, None, True), args.reps)
        csr = best(lambda: m.potential(p), args.reps)
        line = (f"(a) {name}: femp from Python {1e3 * triplets:.0f} ms (Hessian triplets), "
                f"{1e3 * csr:.0f} ms (scipy CSR)")
        if ipctk is not None:
            mesh, verts = collision_mesh(ipctk, scene)
            pot = ipctk.BarrierPotential(ipctk.NormalizedClampedLogBarrier(), DHAT, 1e4)
            t = best(lambda: barrier_pipeline(ipctk, mesh, verts, DHAT, pot), args.reps)
            line += f"; ipctk {1e3 * t:.0f} ms"
        print(line)

    a, tri = icosphere(1.0, 2)
    dhat = 0.01
    b = a + [2.0 + 0.5 * dhat, 0, 0]
    ma, mb = fc.ContactMesh(a, tri, dhat, 1e3), fc.ContactMesh(b, tri, dhat, 1e3)
    step = np.zeros_like(a)
    step[:, 0] = 0.01

    def run_femp() -> None:
        mb.potential(a)
        ma.potential(b)
        mb.max_step(a, a + step)
        ma.max_step(b, b - step)

    line = f"(b) two spheres ({2 * len(a)} vertices, {2 * len(tri)} triangles): femp " \
           f"{1e3 * best(run_femp, args.reps):.2f} ms"
    if ipctk is not None:
        verts = np.vstack([a, b])
        faces = np.vstack([tri, tri + len(a)]).astype(np.int32)
        mesh = ipctk.CollisionMesh(verts, ipctk.edges(faces), faces)
        pot = ipctk.BarrierPotential(dhat, 1e3)
        moved = verts + np.vstack([step, -step])

        def run_ipctk2() -> None:
            barrier_pipeline(ipctk, mesh, verts, dhat, pot)
            ipctk.compute_collision_free_stepsize(mesh, verts, moved)

        line += f"; ipctk {1e3 * best(run_ipctk2, args.reps):.2f} ms"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
