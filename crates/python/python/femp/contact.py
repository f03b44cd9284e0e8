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
