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
    world.set_particles(v=np.zeros_like(world.particles()["v"]))   # and steer it
    world.apply_forces(particles=f)                      # (n, D) N, during the next step
    world.prescribe("pusher", vertices, positions)       # FEM vertices at the step's end
    with world.record("out/steered"):                    # the files `femp run` writes
        world.step(5)

Single contacts, the barrier, CCD and APIC transfers: ``femp.contact`` and ``femp.transfer``.
Long runs survive a stop: ``femp.run(scene, out, checkpoint=True)`` keeps ``checkpoint.femp``
in ``out`` at every frame time, and ``femp.run(scene, out, resume=True)`` continues from it — the
same steps, bit for bit, as a run never stopped (``World.checkpoint`` / ``World.restore`` for a
World stepped from Python).

Errors: ``femp.SceneError`` (bad scene; a ``ValueError`` too), ``femp.SimulationError`` (a run
that failed part-way), ``femp.OutputError`` (a busy or used output directory),
``femp.CheckpointError`` (no checkpoint, a damaged one, another scene's), ``OSError``;
Ctrl-C raises ``KeyboardInterrupt`` and keeps what a run wrote.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _femp
from ._femp import CheckpointError, FempError, OutputError, SimulationError, __version__
from . import contact, transfer
from . import spec
from . import spec as spec_module

__all__ = [
    "Scene",
    "World",
    "RunResult",
    "run",
    "read_metrics",
    "contact",
    "transfer",
    "spec",
    "sweep",
    "FempError",
    "SceneError",
    "SimulationError",
    "OutputError",
    "StateError",
    "CheckpointError",
    "Recording",
    "__version__",
]


class SceneError(_femp.SceneError, ValueError):
    """A malformed, non-physical or too large scene; the message names the field."""


class StateError(_femp.StateError, ValueError):
    """A state, force, target or parameter a :class:`World` refuses (a wrong shape, a
    non-finite value, a body put into another, an inverted element, a vertex the scene moves);
    the message names what and why, and the World is unchanged."""


def _scene_error(e: _femp.SceneError) -> SceneError:
    err = SceneError(*e.args)
    err.__cause__ = e
    return err


def _state_error(e: _femp.StateError) -> StateError:
    err = StateError(*e.args)
    err.__cause__ = e
    return err


def _rows(a: Any, what: str) -> np.ndarray:
    """``a`` as a C-contiguous 2-D float array, or a :class:`StateError` naming ``what``."""
    try:
        r = np.ascontiguousarray(a, dtype=float)
    except (TypeError, ValueError) as e:
        raise StateError(f"{what}: not an array of numbers: {e}") from None
    if r.ndim != 2:
        raise StateError(f"{what}: {r.ndim}-D array of shape {r.shape}, expected (rows, D)")
    return r


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
        """Validate a scene given as a dict (the JSON's structure; numpy arrays and scalars
        wherever numbers go). Errors name the field (``bodies[1].material.nu``), not a place in
        JSON text nobody wrote."""
        try:
            text = json.dumps(d, default=_json_default)
        except ValueError as e:  # NaN and infinities are valid Python floats, not JSON
            raise SceneError(f"(root): {e}") from None
        try:
            return Scene(_femp.Scene.from_json(text, os.fspath(base_dir), name))
        except _femp.SceneError as e:
            err = SceneError(*(_POSITION.sub("", str(a)) for a in e.args))
            err.__cause__ = e
            raise err from None

    @staticmethod
    def from_spec(spec: "spec_module.SceneSpec",
                  base_dir: Union[str, os.PathLike] = ".") -> "Scene":
        """Validate a scene built from typed values (:mod:`femp.spec`)."""
        return Scene.from_dict(spec.to_dict(), base_dir, spec.name or "scene")

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

    def __reduce__(self) -> Any:
        # Pickled as its JSON text, base directory and name (a worker process or another
        # machine with femp installed validates it again).
        return (Scene.from_json, (self.to_json(), self.base_dir, self.name))


_POSITION = re.compile(r" at line \d+ column \d+")


def _json_default(v: Any) -> Any:
    """numpy arrays and scalars as JSON values; anything else a ``TypeError`` naming it."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    raise TypeError(f"a scene holds numbers, text, lists and dicts: not {type(v).__name__} "
                    f"({v!r})")


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
    read its state as numpy arrays (copies) and its metrics; steer it between steps (set
    positions and velocities, apply forces, prescribe FEM vertices, change friction) and record
    it as ``femp run`` does."""

    __slots__ = ("_inner", "_recording_out")

    def __init__(self, scene: Scene):
        if not isinstance(scene, Scene):
            raise TypeError(f"femp.World needs a femp.Scene, got {type(scene).__name__}")
        try:
            self._inner = _femp.World(scene._inner)
        except _femp.SceneError as e:
            raise _scene_error(e) from None
        self._recording_out = ""

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

    # -- steering: state, forces and targets set between steps -------------------------------

    def set_particles(self, x: Optional[npt.ArrayLike] = None,
                      v: Optional[npt.ArrayLike] = None) -> None:
        """Set every particle's position ``x`` and/or velocity ``v`` (n × D, in
        ``particles()`` order). Deformation gradients and ``B`` are kept. :class:`StateError`
        (nothing changed) for a wrong shape, a NaN, or a particle put into or onto a FEM
        body."""
        try:
            self._inner.set_particles(None if x is None else _rows(x, "particles.x"),
                                      None if v is None else _rows(v, "particles.v"))
        except _femp.StateError as e:
            raise _state_error(e) from None

    def set_fem(self, name: str, x: Optional[npt.ArrayLike] = None,
                v: Optional[npt.ArrayLike] = None) -> None:
        """Set FEM body ``name``'s vertex positions ``x`` and/or velocities ``v`` (vertices ×
        D). :class:`StateError` (nothing changed) for a wrong shape, a NaN, an inverted element,
        the body put into or onto another, or a change to a vertex the scene prescribes."""
        try:
            self._inner.set_fem(name, None if x is None else _rows(x, f"fem[{name}].x"),
                                None if v is None else _rows(v, f"fem[{name}].v"))
        except _femp.StateError as e:
            raise _state_error(e) from None

    def apply_forces(self, particles: Optional[npt.ArrayLike] = None,
                     fem: Optional[Dict[str, npt.ArrayLike]] = None) -> None:
        """External forces during the next step only (set them again before every step of a
        control loop): ``particles`` (n × D) on the MPM particles, ``fem`` a dict of FEM body
        name → (vertices × D) forces. In N (N/m in 2D); held constant over the step. In BFEMP
        a force enters the incremental potential as gravity does; in augury, the accelerations
        at the step's end."""
        try:
            if particles is not None:
                self._inner.apply_particle_forces(_rows(particles, "particles.force"))
            for name, f in (fem or {}).items():
                self._inner.apply_fem_forces(name, _rows(f, f"fem[{name}].force"))
        except _femp.StateError as e:
            raise _state_error(e) from None

    def apply_impulses(self, particles: Optional[npt.ArrayLike] = None,
                       fem: Optional[Dict[str, npt.ArrayLike]] = None) -> None:
        """Impulses now (N s): each particle's or vertex's velocity changes by impulse / mass.
        A vertex the scene prescribes takes none (a non-zero one is a :class:`StateError`)."""
        if particles is not None:
            p = self.particles()
            j = _rows(particles, "particles.impulse")
            if j.shape != p["v"].shape:
                raise StateError(f"particles.impulse: shape {j.shape}, expected {p['v'].shape}")
            self.set_particles(v=p["v"] + j / p["mass"][:, None])
        for name, jf in (fem or {}).items():
            b = self.fem(name)
            j = _rows(jf, f"fem[{name}].impulse")
            if j.shape != b["v"].shape:
                raise StateError(f"fem[{name}].impulse: shape {j.shape}, expected {b['v'].shape}")
            self.set_fem(name, v=b["v"] + j / b["mass"][:, None])

    def prescribe(self, name: str, vertices: npt.ArrayLike, positions: npt.ArrayLike) -> None:
        """Move ``vertices`` (indices) of FEM body ``name`` to ``positions`` (len(vertices) ×
        D) by the end of the next step, each on a straight line from where it is: Dirichlet
        unknowns of that step, as the scene's ``prescribed`` sets are (BFEMP's barrier still
        keeps every particle out). Set them before every step you drive them in."""
        idx = np.asarray(vertices)
        if idx.ndim != 1 or (idx.size and not np.issubdtype(idx.dtype, np.integer)):
            raise StateError(f"fem[{name}].prescribe: vertices must be a 1-D array of indices")
        if idx.size and idx.min() < 0:
            raise StateError(f"fem[{name}].prescribe: negative vertex index {int(idx.min())}")
        pos = _rows(positions, f"fem[{name}].prescribe: positions")
        if pos.shape != (idx.size, self.dimension):
            raise StateError(f"fem[{name}].prescribe: positions: shape {pos.shape}, expected "
                             f"({idx.size}, {self.dimension})")
        try:
            self._inner.prescribe(name, [int(i) for i in idx], pos)
        except _femp.StateError as e:
            raise _state_error(e) from None

    def set_friction(self, mu: float, between: Optional[Tuple[str, str]] = None) -> int:
        """Set the friction coefficient of every contact pair, or of the pairs between the two
        bodies ``between``, from the next step on (BFEMP); returns how many pairs changed."""
        try:
            return self._inner.set_friction(float(mu), between)
        except _femp.StateError as e:
            raise _state_error(e) from None

    def set_material(self, name: str, E: float, nu: float) -> None:
        """Set Young's modulus ``E`` (Pa) and Poisson's ratio ``nu`` of body ``name`` (MPM or
        FEM; its model and density kept) from the next step on (BFEMP)."""
        try:
            self._inner.set_material(name, float(E), float(nu))
        except _femp.StateError as e:
            raise _state_error(e) from None

    # -- recording ------------------------------------------------------------------------

    def record(self, out: Union[str, os.PathLike], *, frames: bool = True,
               overwrite: bool = False, metrics_every: int = 1,
               pictures: bool = False, checkpoint: bool = False,
               resume: bool = False) -> "Recording":
        """Record the steps that follow into the directory ``out`` as ``femp run`` would: the
        scene's copy, summary.json (kept current), the metrics row and frame of the state now,
        then every step's row and a frame at the scene's frame interval; key-frame PNGs and a
        GIF with ``pictures=True``. The same files as ``femp.run`` for the same steps. End it
        with :meth:`stop_recording` or use the returned :class:`Recording` in a ``with``
        block. A step that fails ends the recording (summary.json says why).

        ``checkpoint=True`` also writes ``checkpoint.femp`` into ``out`` at every frame time
        (a BFEMP World not steered from outside; else the step that would write it raises
        :class:`CheckpointError`). ``resume=True`` continues the recording whose checkpoint is
        in ``out``: the World is put where the checkpoint was taken (a World of the same scene;
        only ``time.duration`` may differ), metrics.csv cut back to it, later frames removed,
        and the steps that follow are those of a recording never stopped
        (:class:`CheckpointError` if there is none, it is damaged, or is another scene's)."""
        if not os.fspath(out):
            raise ValueError("World.record: out is empty: name the output directory")
        self._inner.record(os.fspath(out), frames, overwrite, metrics_every, pictures,
                           checkpoint, resume)
        return Recording(self, os.fspath(out))

    def checkpoint(self, path: Union[str, os.PathLike]) -> None:
        """Write the World's state to the file ``path``: positions, velocities, deformation
        gradients, the clock and the solvers' analyses — everything its later steps depend
        on. :meth:`restore` puts a World of the same scene back there. A BFEMP World not
        steered from outside (forces, targets or a state set between steps are not part of the
        scene: :class:`CheckpointError`)."""
        if not os.fspath(path):
            raise ValueError("World.checkpoint: path is empty: name the file")
        self._inner.checkpoint(os.fspath(path))

    def restore(self, path: Union[str, os.PathLike]) -> None:
        """Put the World where the state in the file ``path`` (:meth:`checkpoint`, or a run's
        ``checkpoint.femp``) was taken: its next steps are bit for bit those the World it was
        taken of took. :class:`CheckpointError`, the World unchanged, for another scene's or
        other bodies' state or a damaged file; not while recording."""
        self._inner.restore(os.fspath(path))

    @property
    def recording(self) -> bool:
        """Whether a recording is in progress."""
        return self._inner.recording

    def write_frame(self) -> None:
        """Write a frame of the World as it is now into the recording (outside the scene's
        frame interval)."""
        self._inner.write_frame()

    def stop_recording(self, error: Optional[BaseException] = None) -> "RunResult":
        """End the recording and return what it wrote: summary.json ``completed``, or with
        ``error`` (what stopped the Python loop driving the World) ``failed`` — ``interrupted``
        for a ``KeyboardInterrupt`` — and the error's text."""
        out = self._recording_out
        why = None if error is None else f"{type(error).__name__}: {error}"
        interrupted = isinstance(error, KeyboardInterrupt)
        summary, columns, rows = self._inner.stop_recording(why, interrupted)
        if not summary:
            # Ended by the error: what the recording wrote is on disk.
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                return RunResult(out, json.load(f), read_metrics(out))
        return _result(out, summary, columns, rows)

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
    checkpoint: bool = False,
    resume: bool = False,
) -> RunResult:
    """Run ``scene`` into the directory ``out`` as ``femp run`` does (frames unless
    ``frames=False``, metrics.csv, summary.json). ``metrics_every=N`` measures the state and
    writes a metrics row every N steps and after the last (``femp run --metrics-every N``).
    A run that fails part-way raises :class:`SimulationError` and keeps what it wrote;
    summary.json says why.

    ``checkpoint=True`` keeps ``checkpoint.femp`` in ``out`` at every frame time (BFEMP scenes;
    ``femp run --checkpoint``); ``resume=True`` continues the run whose checkpoint is in
    ``out`` (``femp run --resume``): its metrics.csv cut back to the checkpoint, later frames
    removed, and the steps that follow bit for bit those of a run never stopped; the scene may
    differ in ``time.duration`` only (continue a finished run further). ``metrics`` of the
    result then holds the rows from the resumption on (metrics.csv has them all;
    ``summary["resumed_at"]`` lists the resumptions). :class:`CheckpointError` if there is no
    checkpoint, it is damaged or another scene's, or with ``overwrite``."""
    try:
        if not isinstance(scene, Scene):
            raise TypeError(f"femp.run needs a femp.Scene, got {type(scene).__name__}")
        if not os.fspath(out):
            # As `femp run --out ''`: an empty name is not a directory to write into (it would
            # mean the current one).
            raise ValueError("femp.run: out is empty: name the output directory")
        summary, columns, rows = _femp.run(
            scene._inner, os.fspath(out), max_steps, frames, overwrite, progress, metrics_every,
            checkpoint, resume
        )
    except _femp.SceneError as e:
        raise _scene_error(e) from None
    return _result(os.fspath(out), summary, columns, rows)


def _result(out: str, summary: str, columns: List[str], rows: List[List[float]]) -> RunResult:
    table = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    metrics = {c: table[:, i] for i, c in enumerate(columns)}
    return RunResult(out, json.loads(summary), metrics)


class Recording:
    """A recording in progress (:meth:`World.record`). In a ``with`` block it stops when the
    block ends; ``result`` is then what it wrote (a :class:`RunResult`)."""

    __slots__ = ("world", "out", "result")

    def __init__(self, world: World, out: str):
        self.world = world
        self.out = out
        self.result: Optional[RunResult] = None
        world._recording_out = out

    def __enter__(self) -> "Recording":
        return self

    def __exit__(self, kind: Any, value: Any, tb: Any) -> None:
        # A step that failed has ended the recording already (summary.json says why); an
        # exception of the loop itself ends it as failed (interrupted for Ctrl-C).
        if self.world.recording:
            self.result = self.world.stop_recording(value)

    def __repr__(self) -> str:
        return f"femp.Recording(out={self.out!r}, active={self.world.recording})"


def read_metrics(path: Union[str, os.PathLike]) -> Dict[str, np.ndarray]:
    """metrics.csv (a file, or a run's output directory) as columns of numpy arrays."""
    path = os.fspath(path)
    if os.path.isdir(path):
        path = os.path.join(path, "metrics.csv")
    table = np.genfromtxt(path, delimiter=",", names=True, ndmin=1)
    return {name: np.asarray(table[name], dtype=float) for name in table.dtype.names or ()}


from . import sweep  # noqa: E402  (it uses Scene, run and RunResult above)
