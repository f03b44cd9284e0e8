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

DHAT = 1e-3
N = 100_000
HERE = os.path.dirname(os.path.abspath(__file__))


def golden(k: np.ndarray, a: float) -> np.ndarray:
    return np.modf(k * a)[0]


def scene2() -> tuple:
    ne = 10_000
    x = 200.0 * np.arange(ne + 1) / ne
    v = np.stack([x, 0.5 * np.sin(0.3 * x)], axis=1)
    e = np.stack([np.arange(ne), np.arange(1, ne + 1)], axis=1)
    k = np.arange(N, dtype=float)
    px = 200.0 * (k + 0.5) / N
    off = (0.05 + 0.9 * golden(k, 0.754877666246693)) * DHAT
    return v, e, np.stack([px, 0.5 * np.sin(0.3 * px) + off], axis=1)


def scene3() -> tuple:
    n = 70
    g = np.arange(n + 1) / n
    X, Y = np.meshgrid(g, g)
    v = np.stack([X.ravel(), Y.ravel(), 0.02 * np.sin(6 * X.ravel()) * np.cos(5 * Y.ravel())], 1)
    idx = lambda i, j: j * (n + 1) + i  # noqa: E731
    f = [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)] for j in range(n) for i in range(n)]
    f += [[idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)] for j in range(n) for i in range(n)]
    m = 316
    k = np.arange(m * m, dtype=float)
    px, py = (np.mod(k, m) + 0.5) / m, (np.floor(k / m) + 0.5) / m
    off = (0.05 + 0.9 * golden(k, 0.618033988749895)) * DHAT
    return v, np.array(f), np.stack([px, py, 0.02 * np.sin(6 * px) * np.cos(5 * py) + off], 1)


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
    for name, (v, facets, p) in [("2D", scene2()), ("3D", scene3())]:
        m = fc.ContactMesh(v, facets, DHAT, 1e4)
        triplets = best(lambda: m._inner.potential(p, None, True), args.reps)
        csr = best(lambda: m.potential(p), args.reps)
        line = (f"(a) {name}: femp from Python {1e3 * triplets:.0f} ms (Hessian triplets), "
                f"{1e3 * csr:.0f} ms (scipy CSR)")
        if ipctk is not None:
            verts = np.asfortranarray(np.vstack([v, p]))
            if v.shape[1] == 2:
                edges, faces = facets.astype(np.int32), np.zeros((0, 3), np.int32)
            else:
                faces = facets.astype(np.int32)
                edges = ipctk.edges(faces)
            mesh = ipctk.CollisionMesh(verts, edges, faces)
            pot = ipctk.BarrierPotential(ipctk.NormalizedClampedLogBarrier(), DHAT, 1e4)

            def run_ipctk() -> None:
                col = ipctk.NormalCollisions()
                col.build(mesh, verts, DHAT)
                pot(col, mesh, verts)
                pot.gradient(col, mesh, verts)
                pot.hessian(col, mesh, verts, ipctk.PSDProjectionMethod.CLAMP)

            line += f"; ipctk {1e3 * best(run_ipctk, args.reps):.0f} ms"
        print(line)

    sys.path.insert(0, os.path.join(HERE, "..", "examples"))
    from mesh_from_stl import icosphere

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
            col = ipctk.NormalCollisions()
            col.build(mesh, verts, dhat)
            pot(col, mesh, verts)
            pot.gradient(col, mesh, verts)
            pot.hessian(col, mesh, verts, ipctk.PSDProjectionMethod.CLAMP)
            ipctk.compute_collision_free_stepsize(mesh, verts, moved)

        line += f"; ipctk {1e3 * best(run_ipctk2, args.reps):.2f} ms"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
