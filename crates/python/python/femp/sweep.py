"""Sweeps over variants of a scene, on whatever runs them: a process pool, joblib, Dask or Ray.

A worker needs femp installed and nothing else: :func:`run_case` is a function of the femp
package (pickled by its name), a :class:`femp.Scene` pickles as its JSON text, base directory and
name, and a :class:`femp.RunResult` as its summary and numpy columns. So, with femp installed
on every worker and ``out`` on a file system they share::

    import femp, femp.sweep
    scene = femp.Scene.load("fixtures/scenes/block_on_plate.json")
    cases = femp.sweep.grid({"contact.friction": [0.0, 0.2, 0.5], "time.dt": [0.01, 0.005]})

    # Dask:  client = dask.distributed.Client(...)
    futures = client.map(femp.sweep.run_case, [scene] * len(cases), cases,
                         [f"out/sweep/{i}" for i in range(len(cases))])
    results = client.gather(futures)
    # Ray:   run = ray.remote(femp.sweep.run_case)
    results = ray.get([run.remote(scene, c, f"out/sweep/{i}") for i, c in enumerate(cases)])

Each run is independent and has the same bits on any number of threads (set
``RAYON_NUM_THREADS=1`` in the workers to run one case per core). Worker processes must be
started, not forked from a process that has run femp (its threads may hold locks a forked child
never sees released): ``ProcessPoolExecutor(mp_context=multiprocessing.get_context("spawn"))``;
Dask's and Ray's workers and joblib's default (loky) start theirs.
"""

from __future__ import annotations

import itertools
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

from . import RunResult, Scene, run

__all__ = ["run_case", "grid"]


def run_case(scene: Scene, changes: Optional[Mapping[str, Any]],
             out: Union[str, "os.PathLike[str]"], *, frames: bool = False,
             overwrite: bool = True, metrics_every: int = 1,
             max_steps: Optional[int] = None) -> RunResult:
    """Run ``scene`` with the dotted-path ``changes`` (:meth:`femp.Scene.with_changes`; ``None``
    for none) into ``out``: what a worker calls. Frames are off and an earlier case's outputs
    replaced unless asked otherwise; errors are femp's exceptions, raised in the caller by
    Dask's ``gather`` and Ray's ``get``."""
    s = scene.with_changes(dict(changes)) if changes else scene
    return run(s, out, frames=frames, overwrite=overwrite, metrics_every=metrics_every,
               max_steps=max_steps)


def grid(axes: Mapping[str, Sequence[Any]]) -> List[Dict[str, Any]]:
    """Every combination of the values of ``axes`` (dotted path → values), the last axis
    varying fastest: the ``changes`` of each case."""
    keys = list(axes)
    return [dict(zip(keys, values)) for values in itertools.product(*(axes[k] for k in keys))]
