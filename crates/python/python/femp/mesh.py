"""Meshes for femp from surfaces: a closed triangulated surface (.stl or .obj) tetrahedralised,
or a closed 2D outline triangulated, by Gmsh (the ``gmsh`` package on PyPI), written as a Gmsh
``.msh`` file that a scene's ``{"file": {"path": …}}`` reads (a FEM body's ``"mesh"`` or an MPM
body's ``"shape"``).

    python -m femp.mesh bunny.stl bunny.msh --size 0.01      # 3D: tetrahedra inside the surface
    python -m femp.mesh outline.obj plate.msh --2d --size 0.05   # 2D: a planar OBJ polygon/polyline

From Python: :func:`tetrahedralize` and :func:`triangulate`. Needs ``pip install gmsh meshio``
(``pip install femp[mesh]``); meshio reads the surface files.

Without ``size`` the input surface's triangles are kept as the tet mesh's boundary (the volume
is exactly the surface's); with ``size`` the surface is re-meshed too (Gmsh classifies it into
patches at ``feature_angle`` first, so sharp edges stay sharp).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from typing import Any, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

PathLike = Union[str, "os.PathLike[str]"]


def _gmsh() -> Any:
    try:
        import gmsh
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("femp.mesh needs Gmsh's Python API: pip install gmsh meshio") from e
    return gmsh


def read_surface(path: PathLike) -> Tuple[np.ndarray, np.ndarray]:
    """Points (n×3) and triangles (m×3) of a .stl or .obj surface (meshio; quads are split)."""
    try:
        import meshio
    except ImportError as e:  # pragma: no cover
        raise ImportError("femp.mesh needs meshio to read surfaces: pip install meshio") from e
    import warnings

    if not os.path.isfile(path):
        raise FileNotFoundError(f"{os.fspath(path)}: no such file")
    with warnings.catch_warnings():
        # meshio's binary-STL probe overflows harmlessly on ASCII files.
        warnings.simplefilter("ignore", RuntimeWarning)
        m = _meshio_read(meshio, path)
    tris: List[np.ndarray] = []
    for block in m.cells:
        if block.type == "triangle":
            tris.append(block.data)
        elif block.type == "quad":
            q = block.data
            tris += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    if not tris:
        raise ValueError(f"{os.fspath(path)}: no triangles or quads in the file")
    points = np.asarray(m.points, dtype=float)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{os.fspath(path)}: points are not 2D or 3D coordinates")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    triangles = np.concatenate(tris).astype(np.int64)
    _check_indices(triangles, len(points), os.fspath(path))
    return points, triangles


def _meshio_read(meshio: Any, path: PathLike) -> Any:
    """meshio.read with its failures (a truncated file, an index out of range, text that is not
    the format) as a ``ValueError`` naming the file."""
    try:
        return meshio.read(os.fspath(path))
    except OSError:
        raise
    except Exception as e:  # meshio raises IndexError, ValueError, ReadError, …
        raise ValueError(f"{os.fspath(path)}: cannot read it as a mesh ({type(e).__name__}: {e})") from e


def _check_indices(cells: np.ndarray, n: int, where: str) -> None:
    """Every cell's vertex indices within the ``n`` points."""
    bad = (cells < 0) | (cells >= n)
    if bad.any():
        k = int(np.argwhere(bad.any(axis=1))[0, 0])
        raise ValueError(f"{where}: face {k} refers to vertex {int(cells[k][bad[k]][0])}, but the "
                         f"file has {n} vertices")


# Gmsh meshes in double precision: far beyond this its arithmetic overflows (at 1e300 the
# interpreter aborts inside Gmsh). Ample for metres or millimetres.
MAX_COORDINATE = 1e12


def _check_coordinates(points: np.ndarray, where: str) -> None:
    if not np.isfinite(points).all():
        raise ValueError(f"{where}: non-finite coordinates")
    big = float(np.abs(points).max()) if points.size else 0.0
    if big > MAX_COORDINATE:
        raise ValueError(f"{where}: coordinates up to {big:.3g} are beyond what Gmsh meshes "
                         f"(|x| ≤ {MAX_COORDINATE:.0e}): scale the geometry")


def surface_volume(points: np.ndarray, triangles: np.ndarray) -> float:
    """The signed volume a closed, outward-oriented triangulated surface encloses."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _check_closed(triangles: np.ndarray, where: str) -> None:
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                    triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = int((counts == 1).sum())
    if open_edges:
        raise ValueError(f"{where}: the surface is not closed ({open_edges} edges belong to one "
                         "triangle only): a volume mesh needs a watertight surface")
    if (counts > 2).any():
        raise ValueError(f"{where}: the surface is not a manifold ({int((counts > 2).sum())} "
                         "edges shared by more than two triangles)")


@contextlib.contextmanager
def _session(where: str, doing: str) -> Iterator[Any]:
    """A Gmsh session with a fresh model, finalised however it ends; Gmsh's own errors become
    ``ValueError``s naming ``where`` and what it was ``doing``."""
    gmsh = _gmsh()
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("femp")
        yield gmsh
    except ValueError:
        raise
    except Exception as e:
        raise ValueError(f"{where}: Gmsh could not {doing}: {e}") from e
    finally:
        gmsh.finalize()


def _cells(gmsh: Any, dim: int, none: str) -> Tuple[np.ndarray, np.ndarray]:
    """The linear simplices Gmsh made of dimension ``dim`` (node tags, cells × (dim+1)) and their
    corner coordinates (cells × (dim+1) × dim); ``ValueError(none)`` if there are none."""
    _, _, nodes = gmsh.model.mesh.getElements(dim)
    if not nodes:
        raise ValueError(none)
    cells = np.asarray(nodes[0]).reshape(-1, dim + 1)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = dict(zip(tags, np.asarray(coords).reshape(-1, 3)[:, :dim]))
    return cells, np.array([[xyz[t] for t in cell] for cell in cells])


def _write(gmsh: Any, out: PathLike, version: float) -> None:
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.fspath(out))


def tetrahedralize(surface: Union[PathLike, tuple], out: PathLike, size: Optional[float] = None,
                   feature_angle: float = 40.0, version: float = 4.1) -> dict:
    """Fill the closed surface ``surface`` (a .stl/.obj path, or ``(points, triangles)``) with
    linear tetrahedra and write them to ``out`` (.msh). Returns ``{"vertices", "tetrahedra",
    "volume"}`` of the written mesh. ``ValueError`` for an open or non-manifold surface or when
    Gmsh fails (its message included)."""
    where = os.fspath(surface) if not isinstance(surface, tuple) else "surface"
    points, tris = read_surface(surface) if not isinstance(surface, tuple) else (
        np.asarray(surface[0], float), np.asarray(surface[1], np.int64))
    if points.ndim != 2 or points.shape[1] != 3 or tris.ndim != 2 or tris.shape[1] != 3:
        raise ValueError(f"{where}: expected points (n×3) and triangles (m×3)")
    _check_coordinates(points, where)
    _check_indices(tris, len(points), where)
    if size is not None and not (size > 0 and np.isfinite(size)):
        raise ValueError(f"size = {size}: must be positive and finite")
    # Merge duplicate points (STL stores every triangle's own corners).
    scale = np.ptp(points, axis=0).max()
    keys = np.round(points / (scale * 1e-12)).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    points, tris = points[first], inverse.reshape(-1)[tris]
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 2] != tris[:, 0])]
    _check_closed(tris, where)
    if surface_volume(points, tris) < 0:
        tris = tris[:, [0, 2, 1]]  # inward-oriented: flip
    with _session(where, "tetrahedralise the surface") as gmsh:
        s = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(2, s, np.arange(1, len(points) + 1), points.reshape(-1))
        gmsh.model.mesh.addElementsByType(s, 2, [], (tris + 1).reshape(-1))
        if size is not None:
            gmsh.model.mesh.classifySurfaces(np.radians(feature_angle), True, True, np.pi)
            gmsh.model.mesh.createGeometry()
            surfaces = [e[1] for e in gmsh.model.getEntities(2)]
            gmsh.option.setNumber("Mesh.MeshSizeMax", size)
            gmsh.option.setNumber("Mesh.MeshSizeMin", size / 4)
            gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        else:
            surfaces = [s]
        loop = gmsh.model.geo.addSurfaceLoop(surfaces)
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.optimize("Netgen" if size is not None else "")
        tets, p = _cells(gmsh, 3, f"{where}: Gmsh made no tetrahedra")
        _write(gmsh, out, version)
        vol = np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0],
                               np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))).sum() / 6.0
        return {"vertices": len(np.unique(tets)), "tetrahedra": len(tets), "volume": float(vol)}


def triangulate(outline: Union[PathLike, np.ndarray, Sequence], out: PathLike,
                size: float, version: float = 4.1) -> dict:
    """Triangulate the inside of a closed 2D outline — an (n×2) array of its corners in order, or
    a planar .obj whose polygon or polyline is the outline — with triangles of edge length about
    ``size``, written to ``out`` (.msh, in the plane z = 0). Returns ``{"vertices", "triangles",
    "area"}``."""
    where = os.fspath(outline) if isinstance(outline, (str, os.PathLike)) else "outline"
    if isinstance(outline, (str, os.PathLike)):
        pts = _read_outline(outline)
    else:
        pts = np.asarray(outline, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise ValueError(f"{where}: expected at least 3 corners with 2 coordinates each")
    _check_coordinates(pts, where)
    if not (size > 0 and np.isfinite(size)):
        raise ValueError(f"size = {size}: must be positive and finite")
    if np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    _check_simple(pts, where)
    with _session(where, "triangulate the outline") as gmsh:
        corners = [gmsh.model.geo.addPoint(x, y, 0.0, size) for x, y in pts]
        lines = [gmsh.model.geo.addLine(corners[i], corners[(i + 1) % len(corners)])
                 for i in range(len(corners))]
        loop = gmsh.model.geo.addCurveLoop(lines)
        gmsh.model.geo.addPlaneSurface([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(2)
        tris, p = _cells(gmsh, 2, f"{where}: Gmsh made no triangles (a self-intersecting outline?)")
        _write(gmsh, out, version)
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2.0
        return {"vertices": len(np.unique(tris)), "triangles": len(tris), "area": float(area)}


def _check_simple(pts: np.ndarray, where: str) -> None:
    """Refuse an outline that repeats a corner or crosses or touches itself (Gmsh does not
    return on a self-intersecting outline)."""
    n = len(pts)
    scale = np.ptp(pts, axis=0).max()
    if not scale > 0:
        raise ValueError(f"{where}: the outline has no extent")
    for i in range(n):
        if np.linalg.norm(pts[(i + 1) % n] - pts[i]) <= 1e-12 * scale:
            raise ValueError(f"{where}: corners {i} and {(i + 1) % n} coincide")

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> int:
        v = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        return 0 if abs(v) <= 1e-12 * scale * scale else (1 if v > 0 else -1)

    def on(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:  # c on ab, given collinear
        return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and \
            min(a[1], b[1]) <= c[1] <= max(a[1], b[1])

    for i in range(n):
        a, b = pts[i], pts[(i + 1) % n]
        for j in range(i + 1, n):
            if j == i or (j + 1) % n == i or j == (i + 1) % n:
                continue  # adjacent edges share a corner
            c, d = pts[j], pts[(j + 1) % n]
            o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
            if (o1 != o2 and o3 != o4) or (o1 == 0 and on(a, b, c)) or \
                    (o2 == 0 and on(a, b, d)) or (o3 == 0 and on(c, d, a)) or \
                    (o4 == 0 and on(c, d, b)):
                raise ValueError(f"{where}: the outline crosses itself (edges {i} and {j})")
    area = 0.5 * np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    if abs(area) <= 1e-12 * scale * scale:
        raise ValueError(f"{where}: the outline encloses no area")


def _read_outline(path: PathLike) -> np.ndarray:
    """The outline of a planar .obj: its single polygon (``f``) or closed polyline (``l``)."""
    import meshio

    m = _meshio_read(meshio, path)
    for block in m.cells:
        if block.type in ("line", "polygon", "triangle", "quad") and len(block.data):
            if block.type == "line":
                order = [int(block.data[0][0])] + [int(e[1]) for e in block.data]
            else:
                if len(block.data) != 1:
                    raise ValueError(f"{os.fspath(path)}: expected one polygon (the outline), "
                                     f"found {len(block.data)} {block.type} cells")
                order = [int(v) for v in block.data[0]]
            _check_indices(np.asarray([order]), len(m.points), os.fspath(path))
            pts = np.asarray(m.points, dtype=float)[order]
            if pts.shape[1] == 3 and np.ptp(pts[:, 2]) > 1e-12 * max(np.ptp(pts), 1e-300):
                raise ValueError(f"{os.fspath(path)}: the outline is not in a plane z = const")
            return pts[:, :2]
    raise ValueError(f"{os.fspath(path)}: no polygon or polyline in the file")


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m femp.mesh",
        description="Mesh a closed surface (.stl/.obj → tetrahedra) or a planar outline "
                    "(.obj polygon → triangles, with --2d) into a Gmsh .msh file for femp.")
    ap.add_argument("input")
    ap.add_argument("output", help="the .msh file to write")
    ap.add_argument("--size", type=float, help="target edge length (3D: re-mesh the surface "
                    "too; without it the input triangles are kept)")
    ap.add_argument("--2d", dest="two_d", action="store_true",
                    help="triangulate a planar outline (needs --size)")
    args = ap.parse_args(argv)
    try:
        if args.two_d:
            if args.size is None:
                ap.error("--2d needs --size")
            r = triangulate(args.input, args.output, args.size)
        else:
            r = tetrahedralize(args.input, args.output, args.size)
    except (ValueError, OSError) as e:
        print(f"femp.mesh: {e}", file=sys.stderr)
        return 1
    print(f"{args.output}: " + ", ".join(f"{k} {v:g}" for k, v in r.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
