"""femp.contact.ContactMesh: the barrier over a whole mesh equals the sum of its single terms,
its gradient matches finite differences, its sparse Hessian is the single terms' blocks
assembled (symmetric, PSD, blind to translations), shared features count once, and batched CCD
stops a motion before any point reaches a facet."""

import numpy as np
import pytest

import femp.contact as fc

DHAT, KAPPA = 0.01, 1e3


def plate(n=6, wave=0.02):
    """A wavy triangulated square [0, 1]² (3D): vertices, triangles."""
    g = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(g, g)
    v = np.stack([X.ravel(), Y.ravel(), wave * np.sin(3 * X.ravel()) * np.cos(2 * Y.ravel())], 1)
    idx = lambda i, j: j * (n + 1) + i  # noqa: E731
    f = [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)] for j in range(n) for i in range(n)]
    f += [[idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)] for j in range(n) for i in range(n)]
    return v, np.array(f)


def points_above(v, f, k=40, seed=1):
    """Points just above triangle interiors (face features), 0.2–0.8 d̂ away."""
    rng = np.random.default_rng(seed)
    tris = rng.choice(len(f), k, replace=False)
    out = []
    for t in tris:
        a, b, c = v[f[t]]
        w = rng.dirichlet([4, 4, 4])
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        out.append(w @ v[f[t]] + n * DHAT * rng.uniform(0.2, 0.8))
    return np.array(out)


def test_the_mesh_potential_is_its_single_terms_assembled():
    v, f = plate()
    p = points_above(v, f)
    m = fc.ContactMesh(v, f, DHAT, KAPPA)
    act = m.active(p)
    r = m.potential(p)
    assert r["terms"] == len(act["point"]) > 0
    n, nv = len(p), len(v)
    value = 0.0
    H = np.zeros((3 * (n + nv), 3 * (n + nv)))
    g = np.zeros((n + nv, 3))
    for q, kind, feat, w in zip(act["point"], act["kind"], act["feature"], act["weight"]):
        feat = feat[feat >= 0]
        if kind == 3:
            c = fc.point_triangle(p[q], *v[feat], DHAT, KAPPA, weight=w)
        elif kind == 2:
            c = fc.point_edge(p[q], *v[feat], DHAT, KAPPA, weight=w)
        else:
            pytest.fail("a point above a face interior has a vertex as its closest feature")
        value += c["value"]
        idx = [q] + [n + i for i in feat]
        for a, ia in enumerate(idx):
            g[ia] += c["gradient"][a]
            for b, ib in enumerate(idx):
                H[3 * ia:3 * ia + 3, 3 * ib:3 * ib + 3] += c["hessian"][3 * a:3 * a + 3,
                                                                        3 * b:3 * b + 3]
    assert r["value"] == pytest.approx(value, rel=1e-12)
    np.testing.assert_allclose(r["gradient"], g, rtol=1e-12, atol=1e-12 * np.abs(g).max())
    Hs = r["hessian"].toarray()
    np.testing.assert_allclose(Hs, H, rtol=1e-10, atol=1e-10 * np.abs(H).max())
    np.testing.assert_allclose(Hs, Hs.T, atol=1e-9 * np.abs(Hs).max())
    assert np.linalg.eigvalsh(Hs).min() > -1e-8 * np.abs(Hs).max()
    for axis in range(3):  # a rigid translation changes nothing
        t = np.zeros((n + nv, 3))
        t[:, axis] = 1
        assert np.abs(Hs @ t.ravel()).max() < 1e-8 * np.abs(Hs).max()


def test_the_gradient_matches_finite_differences():
    v, f = plate(4)
    p = points_above(v, f, 12, seed=3)
    m = fc.ContactMesh(v, f, DHAT, KAPPA)
    g = m.potential(p, hessian=False)["gradient"]
    n = len(p)
    rng = np.random.default_rng(0)
    h = 1e-7
    for row in list(rng.choice(n, 5, replace=False)) + list(n + rng.choice(len(v), 8,
                                                                           replace=False)):
        for a in range(3):
            def energy(s):
                pp, vv = p.copy(), v.copy()
                if row < n:
                    pp[row, a] += s
                else:
                    vv[row - n, a] += s
                m.set_vertices(vv)
                e = m.potential(pp, hessian=False)["value"]
                m.set_vertices(v)
                return e
            fd = (energy(h) - energy(-h)) / (2 * h)
            assert fd == pytest.approx(g[row, a], rel=1e-5, abs=1e-7 * np.abs(g).max())


def test_a_shared_vertex_counts_once_and_weights_scale():
    """Straight above an interior vertex of a flat mesh, the six triangles around it are each at
    distance d: each adds b(d), and the vertex's coefficient −(6 − 1) takes the five duplicates
    away (BFEMP eq. 31) — b(d) once in all."""
    v, f = plate(4, wave=0.0)
    assert np.allclose(v[6], [0.25, 0.25, 0]) and (f == 6).any(axis=1).sum() == 6
    p = np.array([v[6] + [0, 0, 0.5 * DHAT]])
    m = fc.ContactMesh(v, f, DHAT, KAPPA)
    act = m.active(p)
    vertex = act["kind"] == 1
    assert list(act["feature"][vertex, 0]) == [6] and list(act["weight"][vertex]) == [-5.0]
    assert act["weight"].sum() == 1.0
    b, _, _ = fc.barrier(0.5 * DHAT, DHAT, KAPPA)
    assert m.potential(p)["value"] == pytest.approx(b, rel=1e-12)
    assert m.potential(p, weights=[2.5])["value"] == pytest.approx(2.5 * b, rel=1e-12)


def test_batched_ccd_stops_before_the_mesh():
    v, f = plate()
    m = fc.ContactMesh(v, f, DHAT, KAPPA)
    rng = np.random.default_rng(5)
    p0 = np.column_stack([rng.uniform(0.05, 0.95, (200, 2)), rng.uniform(0.05, 0.2, 200)])
    p1 = p0 - [0, 0, 0.4]  # every point through the plate
    alpha, at = m.max_step(p0, p1)
    assert 0 < alpha < 1 and at is not None
    q, t = at
    mid = p0 + alpha * (p1 - p0)
    for k in range(len(p0)):  # no point has reached a facet at α
        d = min(fc.sq_distance(mid[k], *v[tri]) for tri in f)
        assert d > 0
    # The limiting point would reach its facet just after α.
    far = p0[q] + min(1.0, alpha * 1.05 + 1e-3) * (p1[q] - p0[q])
    assert far[2] < np.interp(far[0], [0, 1], [0, 0]) + 0.03
    # Moving away, or the mesh moving away with them: nothing limits the step.
    assert m.max_step(p0, p0 + [0, 0, 0.4]) == (1.0, None)
    assert m.max_step(p0, p1, v - [0, 0, 0.4])[0] == 1.0
    # 2D: a point through an edge.
    e = fc.ContactMesh([[0.0, 0.0], [1.0, 0.0]], [[0, 1]], DHAT, KAPPA)
    alpha, at = e.max_step([[0.5, 1.0]], [[0.5, -1.0]])
    assert 0.45 < alpha < 0.5 and at == (0, 0)


def test_bad_input_is_named():
    v, f = plate(2)
    with pytest.raises(ValueError, match=r"facet 0.*references vertex 99"):
        fc.ContactMesh(v, np.array([[0, 1, 99]]), DHAT, KAPPA)
    with pytest.raises(ValueError, match=r"facets: shape \(1, 2\), expected \(m, 3\)"):
        fc.ContactMesh(v, np.array([[0, 1]]), DHAT, KAPPA)
    m = fc.ContactMesh(v, f, DHAT, KAPPA)
    with pytest.raises(ValueError, match="hessian"):
        fc.ContactMesh(v, f, DHAT, KAPPA, hessian="exact-ish")
    with pytest.raises(ValueError, match="(?i)penetrat|distance 0|touch"):
        m.potential(v[:1])  # a point on the mesh
    with pytest.raises(ValueError, match="row 0 is not finite"):
        m.potential(np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="weights"):
        m.potential(v[:1] + [0, 0, 1], weights=[1, 2])
    with pytest.raises(ValueError, match="rows, the mesh has"):
        m.set_vertices(v[:3])


def test_two_spheres_touching_through_both_meshes():
    import mesh_from_stl

    a, fa = mesh_from_stl.icosphere(1.0, 2)
    b = a + [2.0 + 0.5 * DHAT, 0, 0]  # the two poles 0.5 d̂ apart
    ma, mb = fc.ContactMesh(a, fa, DHAT, KAPPA), fc.ContactMesh(b, fa, DHAT, KAPPA)
    ab, ba = mb.potential(a), ma.potential(b)
    assert ab["terms"] > 0 and ba["terms"] > 0
    # By symmetry, A's vertices against B and B's against A push apart equally.
    na = len(a)
    push_a = ab["gradient"][:na].sum(0) + ba["gradient"][na:].sum(0)
    push_b = ab["gradient"][na:].sum(0) + ba["gradient"][:na].sum(0)
    np.testing.assert_allclose(push_a, -push_b, rtol=1e-9)
    assert push_a[0] > 0  # the energy grows as A moves towards B


@pytest.mark.parametrize("case", [
    ("face", [0.2, 0.3, 0.4]), ("v0", [-0.3, -0.2, 0.1]), ("v1", [1.4, -0.1, 0.2]),
    ("v2", [-0.1, 1.3, -0.2]), ("e01", [0.5, -0.3, 0.2]), ("e12", [0.7, 0.6, 0.1]),
    ("e20", [-0.4, 0.5, 0.3]),
])
def test_distance_types_and_derivatives_against_finite_differences(case):
    """Each closest feature of a point against a (tilted) triangle, and the gradient and exact
    Hessian of the squared distance over the whole stencil against central differences."""
    kind, p = case
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [0.0, 1.0, -0.1]])
    x = np.vstack([p, tri])
    f, s, g, H = fc.sq_distance_derivatives(*x)
    assert f == kind and s == pytest.approx(fc.sq_distance(*x), rel=1e-12)
    h = 1e-6
    for i in range(4):
        for a in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, a] += h
            xm[i, a] -= h
            assert (fc.sq_distance(*xp) - fc.sq_distance(*xm)) / (2 * h) == pytest.approx(
                g[i, a], abs=1e-7)
            gp, gm = fc.sq_distance_derivatives(*xp)[2], fc.sq_distance_derivatives(*xm)[2]
            np.testing.assert_allclose((gp - gm).ravel() / (2 * h), H[3 * i + a], atol=1e-6)
    # 2D: a point against an edge.
    f2, s2, g2, H2 = fc.sq_distance_derivatives([0.5, 0.3], [0.0, 0.0], [1.0, 0.0])
    assert (f2, s2) == ("edge", pytest.approx(0.09)) and g2.shape == (3, 2) and H2.shape == (6, 6)
    np.testing.assert_allclose(g2[0], [0.0, 0.6], atol=1e-15)
