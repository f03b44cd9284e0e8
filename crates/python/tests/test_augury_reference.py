"""femp's augury method against a second implementation written from the paper's equations
(augury_reference.py: numpy only, no femp code): the same scenes stepped by both agree to
round-off — two blocks colliding (APIC and PIC, separation, friction, sticky, the 4-node
spline, a spinning block) and the block on the 30° ramp of the paper's §3.3 at h = 1 and 0.5
(μ = 0.2 and 0, ten friction iterations, the validation's 2D settings) for 800 steps.

Each case also steps a reference with one setting changed slightly (τ by 1 %, one iteration
fewer): those must disagree by far more than the tolerance, so the agreement is not the
comparison being blind.
"""

import copy
import json
import os

import numpy as np
import pytest

import femp
import augury_reference as ref

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))

# Agreement: positions to 1e-12 of the scene's 1 m size, velocities to 1e-9 of the fastest
# vertex at any step (measured: ≤ 1e-14 m and ≤ 1.4e-12 m/s after 600-800 steps; the stiff ramp's
# E = 1e10 turns position round-off into velocity round-off).
X_TOL = 1e-12
V_TOL = 1e-9


def ramp_scene(h, mu, transfer="apic", iterations=10, steps=800):
    """The §3.3 ramp as femp builds it for the validation's 2D rows (crates/augury/src/scenes.rs
    `ramp`): ramp [0, 4] x [-0.25, 0] and block [0.5, 1.5] x [0, 1], both rotated by -30°,
    bottom of the ramp fixed, g = 100, E = 1e10, ρ = 1e6, grid 0.5 h, τ = Δt = 2.5e-4 h."""
    dt = 2.5e-4 * h

    def cells(length):
        return max(1, round(length / h))

    material = {"E": 1e10, "nu": 0.3, "rho": 1e6}
    rot = {"rotate_deg": -30}
    spec = {
        "name": "ramp_reference", "dimension": 2, "method": "augury", "gravity": [0, -100],
        "time": {"dt": dt, "duration": steps * dt, "frame_interval": steps * dt},
        "augury": {"grid_spacing": 0.5 * h, "transfer": transfer, "model": "friction",
                   "friction": mu, "iterations": iterations, "penetration_limit": None},
        "bodies": [
            {"kind": "fem", "name": "ramp", "material": material, "transform": rot,
             "mesh": {"rectangle": {"min": [0, -0.25], "max": [4, 0],
                                    "cells": [cells(4), cells(0.25)]}},
             # The rectangle's first row of vertices is its bottom face.
             "prescribed": [{"vertices": {"list": list(range(cells(4) + 1))}, "motion": []}]},
            {"kind": "fem", "name": "block", "material": material, "transform": rot,
             "mesh": {"rectangle": {"min": [0.5, 0], "max": [1.5, 1],
                                    "cells": [cells(1), cells(1)]}}},
        ],
    }
    return spec, {"ramp": list(range(cells(4) + 1))}


def blocks_scene(**augury):
    with open(os.path.join(ROOT, "fixtures", "scenes", "augury_blocks.json")) as f:
        spec = json.load(f)
    spec["augury"]["penetration_limit"] = None
    spec["augury"].update(augury)
    return spec


def reference_of(world, spec, fixed, **override):
    """A reference system with the World's initial state and the scene's settings."""
    a = dict(spec["augury"])
    a.update(override)
    bodies = []
    for b in spec["bodies"]:
        d = world.fem(b["name"])
        mask = np.zeros(len(d["x"]), bool)
        mask[fixed.get(b["name"], [])] = True
        m = b["material"]
        bodies.append(ref.Body(b["name"], d["rest"], d["elements"], d["x"], d["v"],
                               m["E"], m["nu"], m["rho"], mask))
    system = ref.System(
        bodies, spec["time"]["dt"], spec.get("gravity", [0.0, 0.0]), a["grid_spacing"],
        kernel=a.get("kernel", "quadratic"), apic=a.get("transfer", "apic") == "apic",
        tau=a.get("tau"), iterations=a.get("iterations", 1), model=a.get("model", "friction"),
        friction=a.get("friction", 0.0), obstacles=a.get("obstacles", "lumped"))
    if system.transfer.apic:
        system.set_rigid_b([float(b.get("angular_velocity", 0.0)) for b in spec["bodies"]])
    return system


def differences(world, system):
    """Largest position and velocity differences over all vertices, and the fastest vertex."""
    dx = dv = speed = 0.0
    for b in system.bodies:
        d = world.fem(b.name)
        dx = max(dx, float(np.abs(d["x"] - b.x).max()))
        dv = max(dv, float(np.abs(d["v"] - b.v).max()))
        speed = max(speed, float(np.abs(b.v).max()))
    return dx, dv, speed


def check(spec, fixed, steps, perturbed, contact_check):
    world = femp.World(femp.Scene.from_dict(spec))
    system = reference_of(world, spec, fixed)
    other = reference_of(world, spec, fixed, **perturbed)
    iterations = 0
    speed = 0.0
    for _ in range(steps):
        system.step()
        other.step()
        iterations = max(iterations, system.last_iterations)
        speed = max(speed, max(float(np.abs(b.v).max()) for b in system.bodies))
    world.step(steps)
    contact_check(system)
    dx, dv, _ = differences(world, system)
    assert dx <= X_TOL, f"positions differ by {dx:.3e} m after {steps} steps"
    assert dv <= V_TOL * speed, f"velocities differ by {dv:.3e} m/s (fastest {speed:.3e})"
    pdx, pdv, _ = differences(world, other)
    assert pdv > 1e3 * V_TOL * speed and pdx > 1e3 * X_TOL, (
        f"changing {perturbed} moved the result only by {pdx:.3e} m, {pdv:.3e} m/s")
    return system, iterations


def collided(system):
    """The blocks met and came apart or stuck: block `a` no longer moves at +1 m/s."""
    a = system.bodies[0]
    vx = float(np.sum(a.mass * a.v[:, 0]) / np.sum(a.mass))
    assert vx < 0.9, f"block a still moves at {vx} m/s: no contact happened"


BLOCK_CASES = {
    "apic_separation": {},
    "pic_separation": {"transfer": "pic"},
    "apic_friction": {"model": "friction", "friction": 0.3, "iterations": 4},
    "pic_friction": {"transfer": "pic", "model": "friction", "friction": 0.3, "iterations": 4},
    "sticky": {"model": "sticky"},
    "four_node_spline": {"kernel": "quadratic4"},
    "tau_twice_dt": {"tau": 2.4e-3, "iterations": 3},
}


@pytest.mark.parametrize("case", sorted(BLOCK_CASES))
def test_two_blocks_agree_with_the_reference(case):
    spec = blocks_scene(**BLOCK_CASES[case])
    tau = spec["augury"].get("tau", spec["time"]["dt"])
    check(spec, {}, 600, {"tau": 1.01 * tau}, collided)


def test_a_spinning_block_agrees_and_keeps_its_angular_momentum():
    """Block `a` spins (ω = 3 rad/s): APIC's initial B_p = L D_p and the B terms all count."""
    spec = blocks_scene(model="friction", friction=0.5, iterations=2)
    spec["bodies"][0]["angular_velocity"] = 3.0
    world = femp.World(femp.Scene.from_dict(spec))
    system = reference_of(world, spec, {})
    l0, p0 = system.angular_momentum(), system.momentum()
    system, _ = check(spec, {}, 600, {"iterations": 1}, collided)
    # Exact conservation in the reference itself (no external force, no fixed vertex).
    assert abs(system.angular_momentum() - l0) <= 1e-12 * abs(l0)
    scale = sum(float(np.sum(b.mass)) for b in system.bodies) * 1.0  # the blocks' 1 m/s
    assert np.abs(system.momentum() - p0).max() <= 1e-12 * scale


@pytest.mark.parametrize("h,mu,transfer", [(1.0, 0.2, "apic"), (1.0, 0.2, "pic"),
                                          (1.0, 0.0, "apic"), (0.5, 0.2, "apic")])
def test_the_ramp_agrees_with_the_reference(h, mu, transfer):
    spec, fixed = ramp_scene(h, mu, transfer)

    def slid(system):
        block = system.bodies[1]
        along = np.array([np.cos(np.radians(30)), -np.sin(np.radians(30))])
        v = float(np.sum(block.mass * (block.v @ along)) / np.sum(block.mass))
        assert v > 0.1, f"the block does not slide (v = {v})"

    _, iterations = check(spec, fixed, 800, {"iterations": 9}, slid)
    assert iterations >= 2, "the friction iterations never ran"
