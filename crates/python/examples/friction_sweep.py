"""Parameter sweep: a block on a slope, over the friction coefficient and the slope angle.

Each run is a femp scene (slope.json, edited per run), run in its own process by joblib; the
block's acceleration along the slope is fitted from the metrics and charted against Coulomb's
law, a = g (sin θ − μ cos θ) while μ < tan θ, and 0 (it sticks) beyond.

    python crates/python/examples/friction_sweep.py --out out/sweep            # 48 runs
    python crates/python/examples/friction_sweep.py --out out/sweep --quick    # 6 runs

Writes ``OUT/sweep.csv`` (one row per run) and ``OUT/friction_sweep.png``; each run's own
outputs (metrics.csv, summary.json) are in ``OUT/runs/``.

Scaling past one machine: the runs are independent, so any joblib backend spreads them —
``with joblib.parallel_config(backend="dask"):`` after starting a ``dask.distributed.Client``
on a cluster, or ``backend="ray"`` after ``ray.util.joblib.register_ray()`` — with femp
installed on every worker and the output directory on a shared file system; ``femp.sweep`` runs
femp's own ``run_case`` on Dask or Ray with nothing else on the workers (tested in
tests/test_scale.py).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time

# One thread per run, the runs in parallel: femp's results have the same bits on any number of
# threads, and small 2D runs do not gain from more.
os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from joblib import Parallel, delayed  # noqa: E402

import femp  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
G = 9.81


def analytic(mu: float, tan_theta: float) -> float:
    """Coulomb: the block's acceleration down the slope (0 once static friction holds it)."""
    th = math.atan(tan_theta)
    return max(0.0, G * (math.sin(th) - mu * math.cos(th)))


def one_run(mu: float, tan_theta: float, out: str) -> dict:
    """Run the slope scene with friction ``mu`` on a slope of gradient ``tan_theta``."""
    scene = femp.Scene.load(os.path.join(HERE, "slope.json"))
    deg = -math.degrees(math.atan(tan_theta))
    scene = scene.with_changes({
        "contact.friction": mu,
        "bodies[0].shape.box.transform.rotate_deg": deg,
        "bodies[1].transform.rotate_deg": deg,
    })
    mass = femp.World(scene).particles()["mass"].sum()
    clock = time.perf_counter()
    r = femp.run(scene, out, frames=False, overwrite=True)
    wall = time.perf_counter() - clock
    m = r.metrics
    th = math.atan(tan_theta)
    speed = (m["momentum_x"] * math.cos(th) - m["momentum_y"] * math.sin(th)) / mass
    half = len(speed) // 2  # after the block has landed and settled on the slope
    accel = np.polyfit(m["t"][half:], speed[half:], 1)[0]
    return {
        "mu": mu,
        "tan_theta": tan_theta,
        "acceleration": float(accel),
        "analytic": analytic(mu, tan_theta),
        "status": r.summary["status"],
        "newton_iterations": r.summary["newton_iterations"],
        "wall_s": wall,
    }


def chart(rows: list, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    for i, tt in enumerate(sorted({r["tan_theta"] for r in rows})):
        colour = f"C{i}"
        mus = np.linspace(0.0, max(r["mu"] for r in rows), 200)
        ax.plot(mus, [analytic(u, tt) for u in mus], color=colour, lw=1,
                label=f"Coulomb, tan θ = {tt:g}")
        pts = sorted((r["mu"], r["acceleration"]) for r in rows if r["tan_theta"] == tt)
        ax.plot(*zip(*pts), "o", color=colour, ms=4, label=f"femp, tan θ = {tt:g}")
    ax.set_xlabel("friction coefficient μ")
    ax.set_ylabel("block acceleration down the slope (m/s²)")
    ax.set_title("MPM block on an FEM slope (BFEMP, 2D)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="runs at a time (default: the number of cores)")
    ap.add_argument("--quick", action="store_true", help="6 runs instead of 48")
    args = ap.parse_args(argv)

    if args.quick:
        grid = [(mu, 0.2) for mu in (0.0, 0.05, 0.1, 0.15, 0.25, 0.3)]
    else:
        grid = [(mu, tt) for tt in (0.1, 0.2, 0.3) for mu in np.linspace(0.0, 0.375, 16)]
    os.makedirs(os.path.join(args.out, "runs"), exist_ok=True)
    clock = time.perf_counter()
    rows = Parallel(n_jobs=args.jobs)(
        delayed(one_run)(float(mu), tt,
                         os.path.join(args.out, "runs", f"mu{mu:.4f}_tan{tt:.2f}"))
        for mu, tt in grid
    )
    wall = time.perf_counter() - clock
    with open(os.path.join(args.out, "sweep.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    chart(rows, os.path.join(args.out, "friction_sweep.png"))
    worst = max(abs(r["acceleration"] - r["analytic"]) for r in rows)
    print(f"{len(rows)} runs in {wall:.1f} s on {args.jobs} jobs; largest deviation from "
          f"Coulomb {worst:.2e} m/s²; chart: {os.path.join(args.out, 'friction_sweep.png')}")
    return 0 if all(r["status"] == "completed" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
