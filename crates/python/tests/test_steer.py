"""Steering a World from Python: a PD controller driving a FEM pusher, a force coupled from
outside, states refused by name, and recordings that write what ``femp run`` writes."""

import json
import os

import numpy as np
import pytest

import femp

from control_loop import SCENE as PUSHER_SCENE  # noqa: E402  (the example's pusher scene)


def block_x(w):
    p = w.particles()
    return (np.average(p["x"][:, 0], weights=p["mass"]),
            np.average(p["v"][:, 0], weights=p["mass"]))


def test_a_pd_controlled_pusher_brings_the_block_to_its_goal(tmp_path):
    """The pusher (every vertex prescribed from Python each step) is driven at a speed set by a
    PD law on the block's position: the block, resting on a plate with friction, ends within
    5 mm of the goal 0.15 m away, no particle ever inside a body, and the recording of the loop
    has one metrics row per step with the pusher's contact force."""
    w = femp.World(femp.Scene.from_dict(PUSHER_SCENE))
    pusher = np.arange(len(w.fem("pusher")["x"]))
    goal = 0.15
    with w.record(tmp_path / "pd") as rec:
        for _ in range(200):
            x, v = block_x(w)
            u = float(np.clip(4.0 * (goal - x) - 0.5 * v, 0.0, 0.5))
            w.prescribe("pusher", pusher, w.fem("pusher")["x"] + [u * w.dt, 0.0])
            w.step()
            assert w.metrics()["penetrations"] == 0
    x, v = block_x(w)
    assert abs(x - goal) < 5e-3 and abs(v) < 0.01, (x, v)
    m = rec.result.metrics
    assert len(m["step"]) == 201 and rec.result.summary["status"] == "completed"
    assert m["force_pusher_x"].min() < -1e-3  # the block pushes back on the pusher
    assert rec.result.summary["max_penetrations"] == 0


def test_a_spring_coupled_from_outside_follows_symplectic_euler():
    """A free FEM block tied by a spring computed in Python (force proportional to mass: a
    rigid motion): BFEMP with backward Euler and the force held over each step is symplectic
    Euler, v' = v + Δt F(x)/M, x' = x + Δt v', to round-off — the coupling adds nothing and
    loses nothing."""
    d = json.loads(json.dumps(PUSHER_SCENE))
    d["gravity"] = [0, 0]
    d["bodies"] = [d["bodies"][1]]
    w = femp.World(femp.Scene.from_dict(d))
    mass = w.fem("pusher")["mass"]
    total = mass.sum()
    k, anchor = 40.0 * total, np.array([-0.2, 0.06])

    def com(b):
        return mass @ b["x"] / total, mass @ b["v"] / total

    x, v = com(w.fem("pusher"))
    for _ in range(50):
        a = -k / total * (x - anchor)
        w.apply_forces(fem={"pusher": mass[:, None] * a})
        w.step()
        v = v + w.dt * a
        x = x + w.dt * v
        bx, bv = com(w.fem("pusher"))
        np.testing.assert_allclose(bx, x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(bv, v, rtol=0, atol=1e-8)
    assert np.abs(x - anchor).max() > 1e-3  # it does oscillate


def test_impulses_and_velocities_change_the_momentum_by_what_was_set():
    d = json.loads(json.dumps(PUSHER_SCENE))
    d["gravity"] = [0, 0]
    w = femp.World(femp.Scene.from_dict(d))
    p = w.particles()
    j = np.zeros_like(p["v"])
    j[:, 0] = 1e-3
    w.apply_impulses(particles=j)
    m = w.metrics()
    assert m["momentum_x"] == pytest.approx(j[:, 0].sum(), rel=1e-12)
    w.set_fem("pusher", v=np.tile([0.0, 0.5], (len(w.fem("pusher")["x"]), 1)))
    m = w.metrics()
    pusher_mass = w.fem("pusher")["mass"].sum()
    assert m["momentum_y"] == pytest.approx(0.5 * pusher_mass, rel=1e-12)


def test_bad_states_are_state_errors_naming_what_and_the_world_is_unchanged():
    w = femp.World(femp.Scene.from_dict(PUSHER_SCENE))
    x0 = w.particles()["x"]
    into = x0.copy()
    into[0] = [0.0, -0.02]
    with pytest.raises(femp.StateError, match=r"particles\.x: would put `block` into .*`plate`"):
        w.set_particles(x=into)
    np.testing.assert_array_equal(w.particles()["x"], x0)
    with pytest.raises(ValueError, match=r"particles\.v: .*rows, expected"):
        w.set_particles(v=np.zeros((3, 2)))
    with pytest.raises(femp.StateError, match=r"shape \(\d+, 3\), expected \(n, 2\)"):
        w.set_particles(v=np.zeros((len(x0), 3)))
    with pytest.raises(femp.StateError, match=r"particles\.v: 1-D array"):
        w.set_particles(v=np.zeros(len(x0)))
    nan = x0.copy()
    nan[5, 1] = np.nan
    with pytest.raises(femp.StateError, match="row 5 is not finite"):
        w.set_particles(x=nan)
    # Velocities set with refused positions are not kept either.
    v0 = w.particles()["v"]
    with pytest.raises(femp.StateError):
        w.set_particles(x=into, v=np.ones_like(v0))
    np.testing.assert_array_equal(w.particles()["v"], v0)
    plate = w.fem("plate")["x"]
    with pytest.raises(femp.StateError, match="prescribed"):
        w.prescribe("plate", [0], plate[:1] + [0.0, 0.01])
    with pytest.raises(femp.StateError, match="negative vertex index"):
        w.prescribe("pusher", [-1], [[0.0, 0.0]])
    with pytest.raises(femp.StateError, match=r"positions: shape \(1, 3\)"):
        w.prescribe("pusher", [0], [[0.0, 0.0, 0.0]])
    with pytest.raises(femp.StateError, match="no FEM body of that name"):
        w.apply_forces(fem={"ghost": np.zeros((1, 2))})
    with pytest.raises(femp.StateError, match="inverted"):
        px = w.fem("pusher")["x"].copy()
        px[0] = px[-1] + [0.05, 0.05]
        w.set_fem("pusher", x=px)
    with pytest.raises(femp.StateError, match="≥ 0"):
        w.set_friction(-1.0)
    assert w.set_friction(0.6, between=("block", "plate")) == 1
    with pytest.raises(femp.StateError, match=r"bodies\[block\]\.material: .*nu"):
        w.set_material("block", 1e5, 0.6)
    w.set_material("block", 2e5, 0.3)
    w.step()


def test_a_recorded_world_writes_what_a_run_writes(tmp_path, fixtures):
    """femp.run and a World stepped by hand and recorded, on the same scene and steps: every
    frame and the PVD byte for byte, metrics.csv but for its wall-clock column."""
    scene = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    ran = femp.run(scene, tmp_path / "run", max_steps=12)
    w = femp.World(scene)
    with w.record(tmp_path / "rec") as rec:
        for _ in range(12):
            w.step()
    def listing(d):
        return sorted(os.path.relpath(os.path.join(r, f), d)
                      for r, _, fs in os.walk(d) for f in fs)

    names = listing(tmp_path / "run")
    assert names == listing(tmp_path / "rec")
    vtu = [n for n in names if n.endswith((".vtu", ".pvd"))]
    assert len(vtu) >= 4
    for n in vtu:
        assert (tmp_path / "run" / n).read_bytes() == (tmp_path / "rec" / n).read_bytes(), n
    for c, col in ran.metrics.items():
        if c != "wall_s":
            np.testing.assert_array_equal(col, rec.result.metrics[c], err_msg=c)
    assert rec.result.summary["steps"] == ran.summary["steps"] == 12
    assert rec.result.summary["frames"] == ran.summary["frames"]


def test_write_frame_adds_a_frame_and_a_loop_error_ends_the_recording_as_failed(tmp_path):
    w = femp.World(femp.Scene.from_dict(PUSHER_SCENE))
    out = tmp_path / "rec"
    with pytest.raises(RuntimeError, match="controller diverged"):
        with w.record(out, metrics_every=2) as rec:
            w.step()
            w.write_frame()  # frame 1 is not due until t = 0.1 s
            w.step(2)
            raise RuntimeError("controller diverged")
    assert not w.recording
    s = rec.result.summary
    assert s["status"] == "failed" and "RuntimeError: controller diverged" in s["error"]
    assert s["frames"] == 2
    # Rows for the initial state and step 2 (every second step); the loop's error came after
    # step 3, so no row for it.
    assert list(rec.result.metrics["step"]) == [0, 2]
    with pytest.raises(ValueError, match="not recording"):
        w.write_frame()
    with pytest.raises(femp.OutputError, match="earlier run.*pass overwrite=True") as e:
        w.record(out)
    assert "--" not in str(e.value)
    w.record(out, overwrite=True)
    w.step()
    assert w.stop_recording().summary["status"] == "completed"
