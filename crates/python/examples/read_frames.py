"""Reading a run's frames: the ParaView files femp writes (``*.pvd`` collections of ``.vtu``
frames) opened with meshio, checked against the run's own metrics.

An MPM block falls onto a fixed FEM plate (``fixtures/scenes/block_on_plate.json``). From the
particle frames (positions and the ``mass`` point data) the block's centre of mass is followed
in time; before the block touches the plate it must fall as backward Euler's discrete free fall,
``y0 + v0 t − g Δt² n(n + 1)/2`` after n steps (the exact ``g t²/2`` less ``g Δt t/2``), and at
every frame the frame's momentum must equal the one in metrics.csv.

    python crates/python/examples/read_frames.py --out out/frames

Needs ``pip install meshio``. Prints one line per frame; returns 0 when the checks hold.
"""

from __future__ import annotations

import argparse
import os
import sys
import xml.etree.ElementTree as ET
from typing import Dict, List, Optional, Sequence, Tuple

import meshio
import numpy as np

import femp

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
G = 9.81


def frames(pvd: str) -> List[Tuple[float, str]]:
    """The ``(time, file)`` of each frame of a ``.pvd`` collection, in order."""
    root = ET.parse(pvd).getroot()
    base = os.path.dirname(pvd)
    return [(float(d.get("timestep", "nan")), os.path.join(base, d.get("file", "")))
            for d in root.iter("DataSet")]


def centre_of_mass(vtu: str) -> Tuple[np.ndarray, float, np.ndarray]:
    """Centre of mass, total mass and momentum of the particles of one frame."""
    m = meshio.read(vtu)
    mass = np.asarray(m.point_data["mass"], dtype=float).reshape(-1)
    v = np.asarray(m.point_data["velocity"], dtype=float)
    x = np.asarray(m.points, dtype=float)
    total = float(mass.sum())
    return (mass[:, None] * x).sum(0) / total, total, (mass[:, None] * v).sum(0)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output directory of the run")
    args = ap.parse_args(argv)
    scene = femp.Scene.load(os.path.join(ROOT, "fixtures", "scenes", "block_on_plate.json"))
    run = femp.run(scene, args.out, max_steps=20, overwrite=True)
    metrics: Dict[str, np.ndarray] = run.metrics
    first: Optional[Tuple[float, float, float]] = None
    ok = True
    checked = 0  # frames compared with the free fall
    for t, vtu in frames(os.path.join(args.out, "particles.pvd")):
        c, mass, p = centre_of_mass(vtu)
        row = int(np.argmin(np.abs(metrics["t"] - t)))
        p_metrics = np.array([metrics["momentum_x"][row], metrics["momentum_y"][row]])
        # The frame holds the particles only; metrics' momentum adds the plate's, which is fixed.
        same = bool(np.allclose(p[:2], p_metrics, rtol=1e-6, atol=1e-9 * mass))
        if first is None:
            first = (t, float(c[1]), float(p[1] / mass))
        t0, y0, v0 = first
        dt = float(metrics["dt"][row])
        n = round((t - t0) / dt)
        free_fall = y0 + v0 * (t - t0) - 0.5 * G * dt * dt * n * (n + 1)
        touching = metrics["contact_terms"][row] > 0 or metrics["barrier_energy"][row] > 0
        print(f"t = {t:.3f} s: centre of mass y = {c[1]:.6f} m (free fall {free_fall:.6f}), "
              f"momentum as in metrics.csv: {same}{', touching' if touching else ''}")
        ok &= same
        if not touching and row > 0 and not np.any(metrics["contact_terms"][:row + 1] > 0):
            ok &= abs(c[1] - free_fall) <= 1e-9
            checked += 1
    return 0 if ok and checked > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
