"""APIC transfers from Python: conservation and exactness for affine velocity fields."""

import numpy as np
import pytest

from femp.transfer import Transfer


@pytest.mark.parametrize("dim", [2, 3])
def test_apic_conserves_momentum_and_reproduces_affine_fields(dim):
    rng = np.random.default_rng(3 + dim)
    n, h = 300, 0.1
    x = rng.uniform(-0.5, 0.5, (n, dim))
    mass = rng.uniform(0.5, 2.0, n)
    v = rng.normal(size=(n, dim))
    B = rng.normal(size=(n, dim, dim)) * 0.01
    t = Transfer(x, h)
    assert t.num_particles == n and t.nodes.shape[1] == dim
    np.testing.assert_allclose(t.node_positions, t.nodes * h, atol=1e-12)
    gm, gp = t.p2g(mass, v, B)
    assert gm.sum() == pytest.approx(mass.sum(), rel=1e-12)
    np.testing.assert_allclose(gp.sum(axis=0), (mass[:, None] * v).sum(axis=0), rtol=1e-10)
    # Angular momentum (2D: z only): Σ m (x × v) + APIC's spin term = Σ_nodes m_i x_i × v_i.
    gv = gp / np.where(gm > 0, gm, 1)[:, None]
    if dim == 2:
        spin = lambda b: b[:, 1, 0] - b[:, 0, 1]  # noqa: E731
        cross = lambda a, b: a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]  # noqa: E731
        lp = (mass * (cross(x, v) + spin(B))).sum()
        lg = (gm * cross(t.node_positions, gv)).sum()
        assert lg == pytest.approx(lp, rel=1e-9, abs=1e-12)
    # An affine field v(x) = c + A x on the grid comes back exactly, with B = A D_p.
    c = rng.normal(size=dim)
    A = rng.normal(size=(dim, dim))
    vp, Bp = t.g2p(c + t.node_positions @ A.T)
    np.testing.assert_allclose(vp, c + x @ A.T, rtol=1e-10, atol=1e-12)
    # B_p = Σ_i w_ip v_i (x_i − x_p)ᵀ = A D_p with D_p = h²/4 I (quadratic B-splines).
    np.testing.assert_allclose(Bp, np.broadcast_to(A * h * h / 4, Bp.shape), rtol=1e-9, atol=1e-12)


def test_bad_transfer_input_is_refused():
    with pytest.raises(ValueError, match="h"):
        Transfer(np.zeros((3, 2)), -1.0)
    with pytest.raises(ValueError, match="columns"):
        Transfer(np.zeros((3, 4)), 0.1)
    t = Transfer(np.zeros((3, 2)), 0.1)
    with pytest.raises(ValueError, match="shape"):
        t.p2g(np.ones(3), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="kernel"):
        Transfer(np.zeros((3, 2)), 0.1, kernel="cubic")
