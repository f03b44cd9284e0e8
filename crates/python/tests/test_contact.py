"""Single contacts, the barrier and CCD from Python, against finite differences and geometry."""

import numpy as np
import pytest

import femp
from femp import contact


def fd_gradient(f, x, h=1e-7):
    g = np.zeros_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e.flat[i] = h
        g.flat[i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


@pytest.mark.parametrize("dim", [2, 3])
def test_point_edge_derivatives_match_finite_differences(dim):
    rng = np.random.default_rng(dim)
    for _ in range(20):
        e0 = rng.uniform(-1, 1, dim)
        e1 = e0 + rng.uniform(0.5, 1.0, dim)
        normal = np.zeros(dim)
        normal[:2] = [-(e1 - e0)[1], (e1 - e0)[0]]
        normal /= np.linalg.norm(normal)
        t = rng.uniform(-0.05, 1.05)
        p = e0 + t * (e1 - e0) + rng.uniform(0.02, 0.08) * normal
        x = np.concatenate([p, e0, e1])

        def value(y):
            c = contact.point_edge(y[:dim], y[dim:2 * dim], y[2 * dim:], 0.1, 1e3, 0.5, "exact")
            return c["value"]

        c = contact.point_edge(p, e0, e1, 0.1, 1e3, 0.5, "exact")
        g = c["gradient"].reshape(-1)
        np.testing.assert_allclose(g, fd_gradient(value, x), rtol=1e-5, atol=1e-6 * abs(g).max())
        hfd = np.array([fd_gradient(lambda y, i=i: contact.point_edge(
            y[:dim], y[dim:2 * dim], y[2 * dim:], 0.1, 1e3, 0.5, "exact")["gradient"].reshape(-1)[i], x)
            for i in range(x.size)])
        np.testing.assert_allclose(c["hessian"], hfd, rtol=1e-4, atol=1e-5 * abs(c["hessian"]).max())
        proj = contact.point_edge(p, e0, e1, 0.1, 1e3, 0.5)["hessian"]
        assert np.linalg.eigvalsh(proj).min() >= -1e-9 * abs(proj).max()


def test_point_triangle_and_distances():
    t = [np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])]
    p = np.array([0.2, 0.3, 0.05])
    assert contact.sq_distance(p, *t) == pytest.approx(0.05 ** 2)
    c = contact.point_triangle(p, *t, dhat=0.1, kappa=1e3, weight=2.0)
    b, db, _ = contact.barrier(0.05, 0.1, 1e3)
    assert c["value"] == pytest.approx(2.0 * b) and c["gradient"].shape == (4, 3)
    np.testing.assert_allclose(c["gradient"][0], [0, 0, 2.0 * db], atol=1e-9 * abs(db))
    np.testing.assert_allclose(c["gradient"].sum(axis=0), 0, atol=1e-9 * abs(db))
    assert c["hessian"].shape == (12, 12)
    assert contact.point_triangle(p + [0, 0, 1], *t, dhat=0.1, kappa=1e3) is None
    with pytest.raises(ValueError, match="distance|penetration"):
        contact.point_triangle(np.array([0.2, 0.2, 0.0]), *t, dhat=0.1, kappa=1e3)
    with pytest.raises(ValueError, match="dhat"):
        contact.point_edge([0, 1], [-1, 0], [1, 0], dhat=-1, kappa=1)


def test_barrier_derivatives():
    for d in [1e-4, 0.01, 0.05, 0.099]:
        b, b1, b2 = contact.barrier(d, 0.1, 7.0)
        h = 1e-7 * d
        assert b1 == pytest.approx((contact.barrier(d + h, 0.1, 7)[0] - contact.barrier(d - h, 0.1, 7)[0]) / (2 * h), rel=1e-6)
        assert b2 == pytest.approx((contact.barrier(d + h, 0.1, 7)[1] - contact.barrier(d - h, 0.1, 7)[1]) / (2 * h), rel=1e-5)
    assert contact.barrier(0.2, 0.1, 7.0) == (0.0, 0.0, 0.0)


def test_ccd_is_conservative_and_tight():
    # A point falling through a static edge at y = 0 from y = 1 to y = -1: contact at t = 0.5.
    start = np.array([[0.3, 1.0], [-1.0, 0.0], [1.0, 0.0]])
    end = np.array([[0.3, -1.0], [-1.0, 0.0], [1.0, 0.0]])
    toi = contact.ccd(start, end)
    assert toi is not None and 0.499 < toi <= 0.5
    assert contact.ccd(start, start + [[0.0, 0.5], [0, 0], [0, 0]]) is None  # moving away
    # 3D point–triangle, the triangle moving up to meet the point.
    s3 = np.array([[0.2, 0.2, 1.0], [0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    e3 = s3 + [[0, 0, 0], [0, 0, 2], [0, 0, 2], [0, 0, 2]]
    toi = contact.ccd(s3, e3)
    assert toi is not None and 0.499 < toi <= 0.5
    with pytest.raises(ValueError, match="shape"):
        contact.ccd(np.zeros((5, 3)), np.zeros((5, 3)))


def test_ccd_degenerate_and_non_finite_inputs():
    """Issue 39: a triangle with two coincident vertices is an edge (no false contact at t = 0),
    coordinates of 1e300 do not overflow, and a NaN anywhere names its row."""
    # t0 = t1: the point passes 0.5 beside the degenerate triangle — no contact.
    s = np.array([[0.0, 0.5, 1.0], [0, 0, 0], [0, 0, 0], [1, 0, 0]], dtype=float)
    e = s + [[0, 0, -2], [0, 0, 0], [0, 0, 0], [0, 0, 0]]
    assert contact.ccd(s, e) is None
    # ... and through its edge: contact at t = 0.5.
    s[0] = [0.5, 0.0, 1.0]
    e = s + [[0, 0, -2], [0, 0, 0], [0, 0, 0], [0, 0, 0]]
    toi = contact.ccd(s, e)
    assert toi is not None and 0.499 < toi <= 0.5
    # Far apart at 1e300: no contact, no overflow into a false one.
    big = np.array([[0.0, 1e300, 0.0], [-1e300, -1e300, 0], [1e300, -1e300, 0], [0, -1e300, 1e300]])
    assert contact.ccd(big, big + [[0, 1e299, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]]) is None
    # NaN in a triangle vertex: named by its row, not "the point".
    bad = s.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"start\[2\] \(vertex 1 of the primitive\)"):
        contact.ccd(bad, s)
    with pytest.raises(ValueError, match=r"end\[0\] \(the point\)"):
        contact.ccd(s, np.where(np.arange(12).reshape(4, 3) == 0, np.inf, s))
