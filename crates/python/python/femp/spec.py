"""Scenes built from typed values instead of nested dicts: one class per section of the scene
format (docs/scenes.md), its fields the JSON's fields by the same names, numpy arrays accepted
wherever a list of numbers is::

    from femp import spec
    s = spec.SceneSpec(
        dimension=2, gravity=[0, -9.81],
        time=spec.Time(dt=0.01, duration=0.5, frame_interval=0.05),
        mpm=spec.MpmGrid(grid_spacing=0.05),
        bodies=[
            spec.MpmBody("block", spec.Box(min=[-0.2, 0.02], max=[0.2, 0.32]),
                         spec.Material(E=1e5, nu=0.3, rho=1000)),
            spec.FemBody("plate", spec.Rectangle(min=[-1, -0.1], max=[1, 0], cells=[20, 1]),
                         spec.Material(E=1e7, nu=0.3, rho=1000),
                         prescribed=[spec.Prescribed("all")]),
        ],
        contact=spec.Contact(dhat=0.005, kappa=1e5, friction=0.3),
    )
    scene = s.build()            # a validated femp.Scene
    s.to_dict()                  # the scene file's structure

A field left ``None`` is left out (the scene format's default applies). Nothing is checked here
that femp checks anyway: :meth:`SceneSpec.build` raises :class:`femp.SceneError` naming the
field by the same path as the attribute, e.g. ``bodies[1].material.nu`` for
``s.bodies[1].material.nu``. A mistyped keyword is Python's ``TypeError`` at once.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__all__ = [
    "SceneSpec", "Time", "Solver", "MpmGrid", "Material", "Transform", "MpmBody", "FemBody",
    "Box", "Disk", "Ball", "Ring", "SemicircularRing", "MeshFile",
    "Rectangle", "Cuboid", "DiskMesh", "RingMesh", "SemicircularRingMesh", "CosineStrip",
    "Prescribed", "Below", "Above", "Motion", "Contact", "Pair", "Boundary", "HalfPlane",
    "Cosine", "Augury", "Penalty",
]

Vector = npt.ArrayLike
"""A list, tuple or numpy array of numbers (D of them for a point or a velocity)."""


def _value(v: Any) -> Any:
    """``v`` as JSON values: specs as their dicts, numpy arrays as lists, numpy scalars as
    Python numbers."""
    if isinstance(v, _Spec):
        return v.to_dict()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, (list, tuple)):
        return [_value(x) for x in v]
    if isinstance(v, dict):
        return {k: _value(x) for k, x in v.items()}
    return v


class _Spec:
    """A section of the scene format: its fields, ``None`` ones left out, under the variant's
    key for the one-key objects of the format (shapes, meshes, boundary shapes)."""

    _key: ClassVar[Optional[str]] = None

    def to_dict(self) -> Any:
        """The section as the scene file's structure."""
        body = {f.name: _value(getattr(self, f.name)) for f in fields(self)  # type: ignore
                if getattr(self, f.name) is not None}
        return {self._key: body} if self._key else body


# -- time, solver, grid, materials, placement ---------------------------------------------------

@dataclass
class Time(_Spec):
    """``time``: the step ``dt`` (s), the ``duration`` (s), the ``integrator``
    (``"backward_euler"``, ``"newmark"``, ``"contact_stabilized_newmark"``) and the interval
    between frames ``frame_interval`` (s; default every step)."""

    dt: float
    duration: float
    integrator: Optional[str] = None
    frame_interval: Optional[float] = None


@dataclass
class Solver(_Spec):
    """``solver``: Newton's tolerance and limits, the Hessian's projection, the linear solver,
    friction's loop and substeps (docs/scenes.md, the solver table)."""

    tolerance: Optional[float] = None
    max_newton_iterations: Optional[int] = None
    max_friction_iterations: Optional[int] = None
    projection: Optional[str] = None
    linear: Optional[str] = None
    pcg_rtol: Optional[float] = None
    pcg_max_iterations: Optional[int] = None
    factor_cg_rtol: Optional[float] = None
    factor_cg_iterations: Optional[int] = None
    pcg_rtol_max: Optional[float] = None
    reuse_hessian_below: Optional[float] = None
    friction_update_below: Optional[float] = None
    friction_update_later: Optional[bool] = None
    friction_forcing: Optional[float] = None
    friction_extrapolation: Optional[bool] = None
    friction_relaxation: Optional[bool] = None
    friction_aitken: Optional[bool] = None
    friction_anderson: Optional[int] = None
    friction_stick_model: Optional[bool] = None
    line_search_expansion: Optional[float] = None
    newton_test: Optional[str] = None
    retry_other_projection: Optional[bool] = None
    ordering: Optional[str] = None
    max_substeps: Optional[int] = None


@dataclass
class MpmGrid(_Spec):
    """``mpm``: the background grid's spacing (m), the ``transfer`` (``"apic"``, ``"pic"``,
    ``"flip"``) and FLIP's ratio."""

    grid_spacing: float
    transfer: Optional[str] = None
    flip_ratio: Optional[float] = None


@dataclass
class Material(_Spec):
    """A body's ``material``: Young's modulus ``E`` (Pa), Poisson's ratio ``nu``, density
    ``rho`` (kg/m³; kg/m² in 2D) and ``model`` (``"neo_hookean"``, default, or ``"linear"``)."""

    E: float
    nu: float
    rho: float
    model: Optional[str] = None


@dataclass
class Transform(_Spec):
    """A rigid placement: rotate by ``rotate_deg`` (3D: about ``axis``, default z) about
    ``about`` (default the origin), then ``translate``."""

    rotate_deg: Optional[float] = None
    axis: Optional[Vector] = None
    about: Optional[Vector] = None
    translate: Optional[Vector] = None


# -- MPM shapes, FEM meshes, mesh files --------------------------------------------------------

@dataclass
class MeshFile(_Spec):
    """A Gmsh ``.msh`` file (relative to the scene's directory), as an MPM body's ``shape`` (the
    inside of its cells) or a FEM body's ``mesh``; ``reorient`` flips a mesh whose cells are all
    inverted. Make one from a surface with ``python -m femp.mesh``."""

    _key = "file"
    path: Union[str, "os.PathLike[str]"]
    reorient: Optional[bool] = None

    def to_dict(self) -> Any:
        d: Dict[str, Any] = {"path": os.fspath(self.path)}
        if self.reorient is not None:
            d["reorient"] = self.reorient
        return {"file": d}


@dataclass
class Box(_Spec):
    """An MPM ``box`` from ``min`` to ``max`` (before ``transform``)."""

    _key = "box"
    min: Vector
    max: Vector
    transform: Optional[Transform] = None


@dataclass
class Disk(_Spec):
    """An MPM ``disk`` (2D) or ball (3D) of ``radius`` about ``center``; ``sampling``
    ``"lattice"`` (default) or ``"polar"`` (2D: a round boundary)."""

    _key = "disk"
    center: Vector
    radius: float
    sampling: Optional[str] = None


@dataclass
class Ball(Disk):
    """A 3D ball of MPM particles (the scene format's ``disk`` in 3D)."""


@dataclass
class Ring(_Spec):
    """A 2D MPM annulus between ``r_in`` and ``r_out`` about ``center``."""

    _key = "ring"
    center: Vector
    r_in: float
    r_out: float
    sampling: Optional[str] = None


@dataclass
class SemicircularRing(_Spec):
    """The upper half of a 2D MPM annulus."""

    _key = "semicircular_ring"
    center: Vector
    r_in: float
    r_out: float


@dataclass
class Rectangle(_Spec):
    """A 2D FEM mesh of ``cells = [nx, ny]`` cells (two triangles each) from ``min`` to
    ``max``."""

    _key = "rectangle"
    min: Vector
    max: Vector
    cells: Sequence[int]


@dataclass
class Cuboid(_Spec):
    """A 3D FEM mesh of ``cells = [nx, ny, nz]`` cells (tetrahedra) from ``min`` to ``max``."""

    _key = "cuboid"
    min: Vector
    max: Vector
    cells: Sequence[int]


@dataclass
class DiskMesh(_Spec):
    """A 2D FEM disk of ``rings`` rings."""

    _key = "disk"
    center: Vector
    radius: float
    rings: int


@dataclass
class RingMesh(_Spec):
    """A 2D FEM annulus of ``cells = [across, around]``."""

    _key = "ring"
    center: Vector
    r_in: float
    r_out: float
    cells: Sequence[int]


@dataclass
class SemicircularRingMesh(_Spec):
    """The upper half of a 2D FEM annulus, ``cells = [across, along]``."""

    _key = "semicircular_ring"
    center: Vector
    r_in: float
    r_out: float
    cells: Sequence[int]


@dataclass
class CosineStrip(_Spec):
    """A 2D FEM band of ``thickness`` (below the curve if negative) along ``y = offset +
    amplitude cos(2π x / wavelength)`` for ``x`` in ``[x0, x1]``."""

    _key = "cosine_strip"
    amplitude: float
    wavelength: float
    offset: float
    x0: float
    x1: float
    thickness: float
    cells: Sequence[int]


Shape = Union[Box, Disk, Ring, SemicircularRing, MeshFile]
Mesh = Union[Rectangle, Cuboid, DiskMesh, RingMesh, SemicircularRingMesh, CosineStrip, MeshFile]


# -- prescribed motion, bodies -----------------------------------------------------------------

@dataclass
class Motion(_Spec):
    """One segment of a motion script, until time ``until`` (s): a ``velocity``, an
    ``angular_velocity`` (a number in 2D, a vector in 3D) about ``center``."""

    until: float
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Union[float, Vector]] = None
    center: Optional[Vector] = None


@dataclass
class Below(_Spec):
    """The vertices whose coordinate ``axis`` (0 = x) is below ``value``."""

    _key = "below"
    axis: int
    value: float


@dataclass
class Above(_Spec):
    """The vertices whose coordinate ``axis`` is above ``value``."""

    _key = "above"
    axis: int
    value: float


@dataclass
class Prescribed(_Spec):
    """A FEM vertex set with prescribed motion: ``vertices`` ``"all"``, :class:`Below`,
    :class:`Above` or a list (array) of vertex indices; ``motion`` the segments (none: the
    vertices stay where they are)."""

    vertices: Union[str, Below, Above, Sequence[int], npt.NDArray[np.integer]]
    motion: List[Motion] = field(default_factory=list)

    def to_dict(self) -> Any:
        v = self.vertices
        if isinstance(v, (str, _Spec)):
            vertices = _value(v)
        else:
            vertices = {"list": _value(np.asarray(v).astype(int))}
        return {"vertices": vertices, "motion": _value(self.motion)}


@dataclass
class MpmBody(_Spec):
    """An MPM body: its ``name``, the ``shape`` filled with particles, its ``material``,
    ``particles_per_cell`` (a square or cube number), initial ``velocity`` and
    ``angular_velocity``."""

    name: str
    shape: Shape
    material: Material
    particles_per_cell: Optional[int] = None
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Union[float, Vector]] = None

    def to_dict(self) -> Any:
        return {"kind": "mpm", **super().to_dict()}


@dataclass
class FemBody(_Spec):
    """A FEM body: its ``name``, ``mesh``, ``material``, placement ``transform``, initial
    ``velocity`` and ``angular_velocity``, and ``prescribed`` vertex sets."""

    name: str
    mesh: Mesh
    material: Material
    transform: Optional[Transform] = None
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Union[float, Vector]] = None
    prescribed: Optional[List[Prescribed]] = None

    def to_dict(self) -> Any:
        return {"kind": "fem", **super().to_dict()}


# -- contact, boundaries, augury ---------------------------------------------------------------

@dataclass
class Pair(_Spec):
    """Settings of one pair of ``bodies`` (two names) over the contact section's: ``enabled``,
    ``dhat``, ``kappa``, ``friction``, ``eps_v``."""

    bodies: Sequence[str]
    enabled: Optional[bool] = None
    dhat: Optional[float] = None
    kappa: Optional[float] = None
    friction: Optional[float] = None
    eps_v: Optional[float] = None


@dataclass
class Contact(_Spec):
    """``contact`` (BFEMP): activation distance ``dhat`` (m), barrier stiffness ``kappa``,
    Coulomb ``friction``, the static-friction velocity ``eps_v`` (m/s), the barrier Hessian
    (``"projected"``, ``"gauss_newton"``) and per-pair ``pairs``."""

    dhat: float
    kappa: float
    friction: Optional[float] = None
    eps_v: Optional[float] = None
    hessian: Optional[str] = None
    pairs: Optional[List[Pair]] = None


@dataclass
class HalfPlane(_Spec):
    """A level set solid behind the plane through ``point`` with ``normal`` into the free
    side."""

    _key = "half_plane"
    point: Vector
    normal: Vector


@dataclass
class Cosine(_Spec):
    """A 2D level set solid above (``solid_above``) or below ``y = offset + amplitude cos(2π x
    / wavelength)``."""

    _key = "cosine"
    amplitude: float
    wavelength: float
    offset: float
    solid_above: bool


@dataclass
class Boundary(_Spec):
    """A level-set boundary on the MPM grid: its ``shape``, the ``condition`` (``"no_slip"`` or
    ``"slip"``) and its ``motion`` (translation segments)."""

    shape: Union[HalfPlane, Cosine]
    condition: str
    motion: Optional[List[Motion]] = None


@dataclass
class Penalty(_Spec):
    """The search-based penalty baseline of augury scenes: ``stiffness`` and ``band`` (m)."""

    stiffness: float
    band: float


@dataclass
class Augury(_Spec):
    """``augury`` (scenes with ``method="augury"``): the background grid (``grid_spacing`` or
    ``grid_ratio``), ``kernel``, ``transfer``, look-ahead ``tau``, ``iterations``, contact
    ``model`` and ``friction``, ``contact`` (``"augury"``, ``"penalty"``, ``"none"``),
    ``penalty``, ``obstacles`` and ``penetration_limit`` (docs/scenes.md)."""

    grid_spacing: Optional[float] = None
    grid_ratio: Optional[float] = None
    kernel: Optional[str] = None
    transfer: Optional[str] = None
    tau: Optional[float] = None
    iterations: Optional[int] = None
    model: Optional[str] = None
    friction: Optional[float] = None
    contact: Optional[str] = None
    penalty: Optional[Penalty] = None
    obstacles: Optional[str] = None
    penetration_limit: Optional[float] = None


# -- the scene ---------------------------------------------------------------------------------

@dataclass
class SceneSpec(_Spec):
    """A whole scene: ``dimension`` (2 or 3), ``bodies``, ``time``, and the optional sections.
    :meth:`build` validates it into a :class:`femp.Scene`."""

    dimension: int
    bodies: List[Union[MpmBody, FemBody]]
    time: Time
    name: Optional[str] = None
    method: Optional[str] = None
    gravity: Optional[Vector] = None
    solver: Optional[Solver] = None
    mpm: Optional[MpmGrid] = None
    contact: Optional[Contact] = None
    boundaries: Optional[List[Boundary]] = None
    augury: Optional[Augury] = None

    def build(self, base_dir: Union[str, "os.PathLike[str]"] = ".") -> Any:
        """The validated :class:`femp.Scene` (relative mesh paths resolve against
        ``base_dir``); :class:`femp.SceneError` names a bad field by its attribute path."""
        from . import Scene

        return Scene.from_spec(self, base_dir)
