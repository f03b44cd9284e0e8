"""Single World.step() calls against one femp.run of the same steps (what `femp run` does,
without frames): the cost of driving femp from a Python loop.

    python crates/python/benches/single_steps.py [--steps 100] [--reps 5] [--busy 2]

Each repetition times, interleaved: ``femp.run`` (frames off, metrics measured only at the
end), a World built and stepped by ``step(n)`` in one call, and a World built and stepped by
``n`` single ``step()`` calls. ``--busy K`` keeps K processes spinning meanwhile (a busy
machine). Prints the medians and the ratio single calls / run.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from typing import Optional, Sequence

import femp

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


def spin(stop: "mp.synchronize.Event") -> None:
    x = 0
    while not stop.is_set():
        for _ in range(100000):
            x += 1


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=os.path.join(ROOT, "fixtures/scenes/block_on_plate.json"))
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--busy", type=int, default=0)
    args = ap.parse_args(argv)
    n = args.steps
    scene = femp.Scene.load(args.scene)
    # A run covers the scene's duration at most: make it long enough for n steps.
    dt = scene.to_dict()["time"]["dt"]
    scene = scene.with_changes({"time.duration": (n + 1) * dt})
    stop = mp.Event()
    hogs = [mp.Process(target=spin, args=(stop,), daemon=True) for _ in range(args.busy)]
    for h in hogs:
        h.start()
    times: dict = {"run": [], "one call": [], "single calls": []}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(args.reps):
                t = time.perf_counter()
                femp.run(scene, os.path.join(tmp, "run"), max_steps=n, frames=False,
                         overwrite=True, metrics_every=n)
                times["run"].append(time.perf_counter() - t)
                t = time.perf_counter()
                femp.World(scene).step(n)
                times["one call"].append(time.perf_counter() - t)
                t = time.perf_counter()
                w = femp.World(scene)
                for _ in range(n):
                    w.step()
                times["single calls"].append(time.perf_counter() - t)
    finally:
        stop.set()
        for h in hogs:
            h.join()
    med = {k: statistics.median(v) for k, v in times.items()}
    for k, v in med.items():
        print(f"{k:>13}: {v:.3f} s  ({1e3 * v / n:.2f} ms a step)")
    print(f"single calls / run: {med['single calls'] / med['run']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
