"""Worlds stepped from Python: state as numpy arrays, forces, metrics."""

import os

import numpy as np
import pytest

import femp


def test_state_arrays_and_names(fixtures):
    w = femp.World(femp.Scene.load(os.path.join(fixtures, "block_on_plate.json")))
    assert w.dimension == 2 and w.steps == 0 and w.fem_bodies == ["plate"]
    p = w.particles()
    n = len(p["x"])
    assert p["x"].shape == (n, 2) and p["v"].shape == (n, 2) and p["F"].shape == (n, 2, 2)
    assert p["stress"].shape == (n, 2, 2) and p["mass"].shape == (n,)
    assert [p["body_names"][b] for b in set(p["body"])] == w.mpm_bodies == ["block"]
    np.testing.assert_allclose(p["volume"], p["rest_volume"])  # F = I at the start
    f = w.fem("plate")
    assert f["elements"].shape[1] == 3 and f["facets"].shape[1] == 2
    assert f["elements"].max() < len(f["x"]) and f["facets"].max() < len(f["x"])
    with pytest.raises(ValueError, match="plate"):
        w.fem("no_such_body")
    r = w.step(3)
    assert w.steps == 3 and abs(w.time - 3 * w.dt) < 1e-15
    assert set(r) >= {"newton_iterations", "contact_terms", "min_distance"}


def test_contact_forces_are_the_momentum_change_minus_gravity(slope):
    """A block resting on a slope: over each step, Δp = (m g + F_contact) Δt, with F_contact
    the block's contact force in metrics() and the sum of the per-particle forces."""
    s = femp.Scene.load(slope).with_changes({"contact.friction": 0.5})
    w = femp.World(s)
    mass = w.particles()["mass"].sum()
    w.step(20)  # landed: sticking on the slope
    before = w.metrics()
    checked = 0
    for _ in range(5):
        w.step()
        m = w.metrics()
        assert m["contact_terms"] > 0 and m["newton_iterations"] > 0
        force = np.array([m["force_block_x"], m["force_block_y"]])
        per_particle = w.particles()["contact_force"].sum(axis=0)
        np.testing.assert_allclose(per_particle, force, rtol=1e-9, atol=1e-12)
        dp = np.array([m["momentum_x"] - before["momentum_x"],
                       m["momentum_y"] - before["momentum_y"]])
        expected = (force + mass * np.array([0.0, -9.81])) * w.dt
        np.testing.assert_allclose(dp, expected, rtol=0, atol=1e-6 * mass * 9.81 * w.dt)
        # It holds the block up: the normal force is about m g cos θ.
        assert force[1] > 0.5 * mass * 9.81
        before = m
        checked += 1
    assert checked == 5
