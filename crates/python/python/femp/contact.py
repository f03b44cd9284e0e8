"""Contact building blocks, one call each: femp's barrier (BFEMP eq. 27), a point against an
edge or triangle with derivatives, squared distances, and CCD.

The barrier acts on the distance ``d``: ``b(d) = -kappa (d/dhat - 1)^2 ln(d/dhat)``. The IPC
Toolkit's acts on ``d^2`` against ``dhat^2``, so a ``kappa``/``dhat`` tuned there does not give
the same forces here (docs/contact.md).
"""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

import numpy as np
import numpy.typing as npt

from . import _femp


def barrier(d: float, dhat: float, kappa: float) -> Tuple[float, float, float]:
    """``(b(d), b'(d), b''(d))``; zero for ``d >= dhat``; ``ValueError`` for ``d <= 0``."""
    return _femp.barrier(float(d), float(dhat), float(kappa))


def point_edge(p: npt.ArrayLike, e0: npt.ArrayLike, e1: npt.ArrayLike, dhat: float,
               kappa: float, weight: float = 1.0,
               hessian: str = "projected") -> Optional[Dict[str, Any]]:
    """Potential ``weight * b(d)`` of point ``p`` against edge ``e0 e1`` (2D or 3D).

    Returns ``None`` when ``d >= dhat``, else a dict: ``distance``, ``value``, ``gradient``
    (3 x D: rows p, e0, e1) and ``hessian`` (3D x 3D; ``"projected"``: PSD as Newton uses it,
    or ``"exact"``). ``ValueError`` when ``d`` is 0 to round-off (penetration)."""
    return _femp.point_edge_potential(_v(p), _v(e0), _v(e1), float(dhat), float(kappa),
                                      float(weight), hessian)


def point_triangle(p: npt.ArrayLike, t0: npt.ArrayLike, t1: npt.ArrayLike,
                   t2: npt.ArrayLike, dhat: float, kappa: float, weight: float = 1.0,
                   hessian: str = "projected") -> Optional[Dict[str, Any]]:
    """As :func:`point_edge` for a triangle (3D): gradient 4 x 3, Hessian 12 x 12."""
    return _femp.point_triangle_potential(_v(p), _v(t0), _v(t1), _v(t2), float(dhat),
                                          float(kappa), float(weight), hessian)


def sq_distance(p: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike,
                c: Optional[npt.ArrayLike] = None) -> float:
    """Squared distance from ``p`` to the edge ``a b``, or to the triangle ``a b c``."""
    return _femp.sq_distance(_v(p), _v(a), _v(b), None if c is None else _v(c))


def sq_distance_derivatives(p: npt.ArrayLike, a: npt.ArrayLike, b: npt.ArrayLike,
                            c: Optional[npt.ArrayLike] = None
                            ) -> Tuple[str, float, np.ndarray, np.ndarray]:
    """The squared distance from ``p`` to the edge ``a b`` or the triangle ``a b c`` with its
    closest feature and derivatives over the whole stencil (``p``, then the edge's or triangle's
    vertices): ``(feature, s, gradient (N × D), hessian (ND × ND))``, the Hessian exact (not
    projected; piecewise smooth across features); the feature is
    ``"v0"``, ``"v1"``, ``"v2"`` (a vertex), ``"edge"`` (the edge's interior), ``"e01"``,
    ``"e12"``, ``"e20"`` (a triangle edge's interior) or ``"face"``."""
    return _femp.sq_distance_derivatives(_v(p), _v(a), _v(b), None if c is None else _v(c))


def ccd(start: npt.ArrayLike, end: npt.ArrayLike,
        max_iterations: int = 800) -> Optional[float]:
    """Conservative time of impact in [0, 1] of a point against an edge or triangle, all moving
    linearly from ``start`` to ``end`` (rows: point, then the feature's vertices; shapes (3, 2),
    (3, 3) or (4, 3)); ``None`` if they never come within the CCD's separation."""
    toi, _ = _femp.ccd_toi(np.ascontiguousarray(start, dtype=float),
                           np.ascontiguousarray(end, dtype=float), int(max_iterations))
    return toi


def _v(x: npt.ArrayLike) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float).reshape(-1)


class ContactMesh:
    """femp's barrier contact over a whole mesh: points (particles, or another body's boundary
    vertices) against this mesh's boundary facets — edges in 2D, triangles in 3D — with the
    broad phase, the active terms, the potential's gradient and sparse Hessian, and batched CCD
    of the BFEMP step (femp-contact's parallel code; the GIL is released).

    Two bodies that may touch each other are two one-sided problems, as in a BFEMP scene: body
    A's vertices against B's ``ContactMesh`` and B's vertices against A's; the gradients add.

    The barrier acts on the distance ``d`` (``b(d) = -kappa (d/dhat - 1)^2 ln(d/dhat)``), not on
    ``d^2`` as the IPC Toolkit's does, and a point near several facets counts each closest
    feature once (vertices and edges shared by facets are not counted twice: BFEMP eqs. 31–32).
    """

    def __init__(self, vertices: npt.ArrayLike, facets: npt.ArrayLike, dhat: float,
                 kappa: float, hessian: str = "projected"):
        self._inner = _femp.ContactMesh(_m(vertices), np.ascontiguousarray(facets, np.int64),
                                        float(dhat), float(kappa), hessian)

    @property
    def dimension(self) -> int:
        """2 or 3."""
        return int(self._inner.dimension)

    @property
    def num_vertices(self) -> int:
        return int(self._inner.num_vertices)

    def set_vertices(self, vertices: npt.ArrayLike) -> None:
        """Move the mesh (every vertex, nv × D)."""
        self._inner.set_vertices(_m(vertices))

    def candidates(self, points: npt.ArrayLike,
                   within: Optional[float] = None) -> Tuple[np.ndarray, np.ndarray]:
        """Broad phase: ``(point, facet)`` index arrays of the pairs whose boxes come within
        ``within`` (default ``dhat``)."""
        return self._inner.candidates(_m(points), within)

    def potential(self, points: npt.ArrayLike, weights: Optional[npt.ArrayLike] = None,
                  hessian: bool = True) -> Dict[str, Any]:
        """The potential ``sum w b(d)`` of ``points`` (weights ``w``, default 1) against the
        mesh: a dict of ``value``, ``terms`` (active point–feature terms), ``gradient``
        ((n + nv) × D: the points' rows, then the mesh vertices') and ``hessian`` (PSD, as
        Newton uses it: a ``scipy.sparse.csr_matrix`` of size D(n + nv), in the gradient's
        order flattened row by row; needs scipy). ``ValueError`` when a point touches a facet
        (distance 0: penetration)."""
        w = None if weights is None else np.ascontiguousarray(weights, dtype=float)
        value, terms, grad, h = self._inner.potential(_m(points), w, hessian)
        out: Dict[str, Any] = {"value": value, "terms": terms, "gradient": grad}
        if hessian:
            try:
                import scipy.sparse as sp
            except ImportError as e:  # pragma: no cover - scipy is a test dependency
                raise ImportError("ContactMesh.potential's Hessian is a scipy.sparse matrix: "
                                  "pip install scipy (or pass hessian=False)") from e
            n = grad.size
            out["hessian"] = sp.csr_matrix((h["values"], (h["rows"], h["cols"])), shape=(n, n))
        return out

    def active(self, points: npt.ArrayLike,
               weights: Optional[npt.ArrayLike] = None) -> Dict[str, np.ndarray]:
        """The active terms (distance below ``dhat``): arrays ``point``, ``kind`` (the closest
        feature: 1 vertex, 2 edge, 3 face), ``feature`` (its mesh vertices, -1 padded, × 3),
        ``distance`` and ``weight`` (w times the feature's duplicate-removal coefficient)."""
        w = None if weights is None else np.ascontiguousarray(weights, dtype=float)
        return self._inner.active(_m(points), w)

    def max_step(self, points0: npt.ArrayLike, points1: npt.ArrayLike,
                 vertices1: Optional[npt.ArrayLike] = None) -> Tuple[float, Optional[Tuple[int, int]]]:
        """Batched CCD: the largest ``alpha`` in (0, 1] such that no point reaches a facet on
        the straight motion ``points0 -> points1`` while the mesh moves to ``vertices1``
        (default: it stays) — conservative — and the ``(point, facet)`` that limits it
        (``None`` when nothing does)."""
        v1 = None if vertices1 is None else _m(vertices1)
        alpha, p, f = self._inner.max_step(_m(points0), _m(points1), v1)
        return float(alpha), (None if p < 0 else (int(p), int(f)))

    def __repr__(self) -> str:
        return f"femp.contact.ContactMesh(dimension={self.dimension}, vertices={self.num_vertices})"


def _m(x: npt.ArrayLike) -> np.ndarray:
    a = np.ascontiguousarray(x, dtype=float)
    if a.ndim != 2:
        raise ValueError(f"expected an (n, D) array, got shape {a.shape}")
    return a
