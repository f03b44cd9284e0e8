"""femp from Python: elastic MPM and FEM bodies in frictional contact.

Scenes are the JSON files of the ``femp`` program (docs/scenes.md); here they load from a file,
a JSON string or a dict, and edit as dicts::

    import femp
    scene = femp.Scene.load("fixtures/scenes/block_on_plate.json")
    d = scene.to_dict()
    d["contact"]["friction"] = 0.3
    scene = femp.Scene.from_dict(d, base_dir=scene.base_dir)
    result = femp.run(scene, "out/plate_mu03")          # frames, metrics.csv, summary.json
    result.metrics["total_energy"]                       # numpy array, one value per step

    world = femp.World(scene)                            # or step it yourself
    world.step(10)
    world.particles()["x"]                               # (n, D) numpy array

Single contacts, the barrier, CCD and APIC transfers: ``femp.contact`` and ``femp.transfer``.
Errors: ``femp.SceneError`` (bad scene; a ``ValueError`` too), ``femp.SimulationError`` (a run
that failed part-way), ``femp.OutputError`` (a busy or used output directory), ``OSError``;
Ctrl-C raises ``KeyboardInterrupt`` and keeps what a run wrote.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Union

import numpy as np

from . import _femp
from ._femp import FempError, OutputError, SimulationError, __version__
from . import contact, transfer

__all__ = [
    "Scene",
    "World",
    "RunResult",
    "run",
    "read_metrics",
    "contact",
    "transfer",
    "FempError",
    "SceneError",
    "SimulationError",
    "OutputError",
    "__version__",
]


class SceneError(_femp.SceneError, ValueError):
    """A malformed, non-physical or too large scene; the message names the field."""


def _scene_error(e: _femp.SceneError) -> SceneError:
    err = SceneError(*e.args)
    err.__cause__ = e
    return err


class Scene:
    """A validated scene. Build with :meth:`load`, :meth:`from_json` or :meth:`from_dict`."""

    __slots__ = ("_inner",)

    def __init__(self, inner: _femp.Scene):
        self._inner = inner

    @staticmethod
    def load(path: Union[str, os.PathLike]) -> "Scene":
        """Read, parse and validate a scene file; relative mesh paths resolve against its
        directory."""
        try:
            return Scene(_femp.Scene.load(os.fspath(path)))
        except _femp.SceneError as e:
            raise _scene_error(e) from None

    @staticmethod
    def from_json(
        text: str, base_dir: Union[str, os.PathLike] = ".", name: str = "scene"
    ) -> "Scene":
        """Parse and validate scene JSON text."""
        try:
            return Scene(_femp.Scene.from_json(text, os.fspath(base_dir), name))
        except _femp.SceneError as e:
            raise _scene_error(e) from None

    @staticmethod
    def from_dict(
        d: Dict[str, Any], base_dir: Union[str, os.PathLike] = ".", name: str = "scene"
    ) -> "Scene":
        """Validate a scene given as a dict (the JSON's structure)."""
        return Scene.from_json(json.dumps(d), base_dir, name)

    def to_json(self) -> str:
        """The JSON text of the scene."""
        return self._inner.to_json()

    def to_dict(self) -> Dict[str, Any]:
        """The scene as a dict, to edit and pass to :meth:`from_dict`."""
        return json.loads(self._inner.to_json())

    @property
    def name(self) -> str:
        return self._inner.name

    @property
    def dimension(self) -> int:
        return self._inner.dimension

    @property
    def base_dir(self) -> str:
        return os.fspath(self._inner.base_dir)

    def estimate(self) -> str:
        """What ``femp check`` prints: particles, grid nodes, DOFs, memory, steps."""
        return self._inner.estimate()

    def with_changes(self, changes: Dict[str, Any]) -> "Scene":
        """A copy with dotted-path changes applied, e.g.
        ``{"contact.friction": 0.3, "bodies[1].material.E": 2e7, "time.dt": 1e-3}``."""
        d = self.to_dict()
        for path, value in changes.items():
            _set_path(d, path, value)
        return Scene.from_dict(d, self.base_dir, self.name)

    def __repr__(self) -> str:
        return f"femp.Scene(name={self.name!r}, dimension={self.dimension})"


def _set_path(d: Any, path: str, value: Any) -> None:
    """Set ``value`` at a dotted path such as ``bodies[1].material.E``. A field may be new (the
    scene check then refuses a name it does not know); a list index must exist and not be
    negative, and every step but the last must lead into an object or list."""

    def bad(why: str) -> SceneError:
        return SceneError(f"with_changes: `{path}`: {why}")

    keys: list = []
    for part in path.split("."):
        if not part:
            raise bad("empty field name (two dots, or a dot at an end)")
        while "[" in part:
            head, rest = part.split("[", 1)
            if head:
                keys.append(head)
            if "]" not in rest:
                raise bad("`[` without `]`")
            index, part = rest.split("]", 1)
            try:
                k = int(index)
            except ValueError:
                raise bad(f"list index `{index}` is not a whole number") from None
            if k < 0:
                raise bad(f"negative list index {k}: count from 0")
            keys.append(k)
        if part:
            keys.append(part)
    node = d
    walked = ""
    for depth, k in enumerate(keys):
        last = depth == len(keys) - 1
        if isinstance(k, int):
            if not isinstance(node, list):
                raise bad(f"`{walked}` is not a list, cannot take [{k}]")
            if k >= len(node):
                raise bad(f"`{walked}` has {len(node)} entries, no [{k}]")
            walked += f"[{k}]"
        else:
            if not isinstance(node, dict):
                raise bad(f"`{walked}` is not an object, cannot take `.{k}`")
            walked += ("." if walked else "") + k
            if not last and k not in node:
                # A new section (e.g. `contact` in a scene without one); the scene check
                # refuses names it does not know.
                node[k] = [] if isinstance(keys[depth + 1], int) else {}
        if last:
            node[k] = value
        else:
            node = node[k]


class World:
    """A simulation state stepped from Python: build it from a :class:`Scene`, :meth:`step` it,
    read its state as numpy arrays (copies) and its metrics."""

    __slots__ = ("_inner",)

    def __init__(self, scene: Scene):
        if not isinstance(scene, Scene):
            raise TypeError(f"femp.World needs a femp.Scene, got {type(scene).__name__}")
        try:
            self._inner = _femp.World(scene._inner)
        except _femp.SceneError as e:
            raise _scene_error(e) from None

    def step(self, n: int = 1) -> Dict[str, Any]:
        """Advance ``n`` steps; the last step's solver report (``newton_iterations``,
        ``friction_iterations``, ``contact_terms``, ``min_distance``, …). A step that fails
        raises :class:`SimulationError`; Ctrl-C raises ``KeyboardInterrupt``."""
        return self._inner.step(n)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._inner.time

    @property
    def steps(self) -> int:
        """Steps taken."""
        return self._inner.steps

    @property
    def dt(self) -> float:
        """The time step (s)."""
        return self._inner.dt

    @property
    def dimension(self) -> int:
        """2 or 3."""
        return self._inner.dimension

    @property
    def fem_bodies(self) -> List[str]:
        """Names of the FEM bodies, in scene order."""
        return self._inner.fem_bodies

    @property
    def mpm_bodies(self) -> List[str]:
        """Names of the MPM bodies, in scene order."""
        return self._inner.mpm_bodies

    def particles(self) -> Dict[str, Any]:
        """The MPM particles: ``x``, ``v`` (n × D), ``mass``, ``volume``, ``rest_volume`` (n),
        ``F``, ``B``, ``stress`` (n × D × D), ``contact_force`` (n × D), ``body`` (index into
        ``body_names``)."""
        return self._inner.particles()

    def fem(self, name: str) -> Dict[str, Any]:
        """FEM body ``name``: ``x``, ``v``, ``rest``, ``initial`` (vertices × D), ``mass``,
        ``elements``, ``facets`` (vertex indices), ``stress`` (per element),
        ``contact_force`` (per vertex). ``ValueError`` for an unknown name."""
        return self._inner.fem(name)

    def metrics(self) -> Dict[str, Union[int, float]]:
        """metrics.csv's columns now (energies, momenta, penetrations, the last step's solver
        columns and per-body contact forces); counts as ``int``, the rest as ``float``
        (``wall_s`` is 0 here)."""
        return self._inner.metrics()

    def warnings(self) -> List[str]:
        """What the scene asks for and femp does not fully model."""
        return self._inner.warnings()

    def __repr__(self) -> str:
        return repr(self._inner)


@dataclass
class RunResult:
    """What a run wrote: ``out`` (the directory), ``summary`` (summary.json as a dict) and
    ``metrics`` (metrics.csv's columns as numpy arrays, one value per step, row 0 the initial
    state)."""

    out: str
    summary: Dict[str, Any]
    metrics: Dict[str, np.ndarray] = field(repr=False)


def run(
    scene: Scene,
    out: Union[str, os.PathLike],
    *,
    max_steps: Optional[int] = None,
    frames: bool = True,
    overwrite: bool = False,
    progress: bool = False,
    metrics_every: int = 1,
) -> RunResult:
    """Run ``scene`` into the directory ``out`` as ``femp run`` does (frames unless
    ``frames=False``, metrics.csv, summary.json). ``metrics_every=N`` measures the state and
    writes a metrics row every N steps and after the last (``femp run --metrics-every N``).
    A run that fails part-way raises :class:`SimulationError` and keeps what it wrote;
    summary.json says why."""
    try:
        if not isinstance(scene, Scene):
            raise TypeError(f"femp.run needs a femp.Scene, got {type(scene).__name__}")
        if not os.fspath(out):
            # As `femp run --out ''`: an empty name is not a directory to write into (it would
            # mean the current one).
            raise ValueError("femp.run: out is empty: name the output directory")
        summary, columns, rows = _femp.run(
            scene._inner, os.fspath(out), max_steps, frames, overwrite, progress, metrics_every
        )
    except _femp.SceneError as e:
        raise _scene_error(e) from None
    table = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    metrics = {c: table[:, i] for i, c in enumerate(columns)}
    return RunResult(os.fspath(out), json.loads(summary), metrics)


def read_metrics(path: Union[str, os.PathLike]) -> Dict[str, np.ndarray]:
    """metrics.csv (a file, or a run's output directory) as columns of numpy arrays."""
    path = os.fspath(path)
    if os.path.isdir(path):
        path = os.path.join(path, "metrics.csv")
    table = np.genfromtxt(path, delimiter=",", names=True, ndmin=1)
    return {name: np.asarray(table[name], dtype=float) for name in table.dtype.names or ()}
