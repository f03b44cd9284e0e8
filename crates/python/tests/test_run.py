"""Runs from Python write what `femp run` writes and return the same numbers."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import femp


def test_run_returns_the_metrics_and_summary_it_writes(fixtures, tmp_path):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    out = tmp_path / "plate"
    r = femp.run(s, out, max_steps=20)
    assert r.summary["status"] == "completed" and r.summary["steps"] == 20
    assert r.summary == json.loads((out / "summary.json").read_text())
    assert (out / "scene_copy.json").exists() and list((out / "frames").iterdir())
    csv = femp.read_metrics(out)
    assert list(csv) == list(r.metrics)
    assert len(r.metrics["step"]) == 21  # the initial state, then one row per step
    # The values themselves (Δt exactly as the scene gives it); metrics.csv holds them rounded
    # to at least 7 significant digits, counts exactly.
    assert np.all(r.metrics["dt"] == s.to_dict()["time"]["dt"])
    for k in r.metrics:
        if k in ("step", "penetrations", "newton_iterations", "contact_terms", "substeps"):
            np.testing.assert_array_equal(r.metrics[k], csv[k], err_msg=k)
        else:
            np.testing.assert_allclose(r.metrics[k], csv[k], rtol=5e-7, atol=0, err_msg=k)
    # Gravity: the momentum changes by m g Δt per step while the block falls freely.
    m = femp.World(s).particles()["mass"].sum()
    dp = np.diff(r.metrics["momentum_y"][:3])
    np.testing.assert_allclose(dp, -9.81 * m * r.metrics["dt"][0], rtol=1e-9)


def test_metrics_every_keeps_every_nth_row_and_the_last(fixtures, tmp_path):
    s = femp.Scene.load(os.path.join(fixtures, "augury_blocks.json"))
    full = femp.run(s, tmp_path / "full", max_steps=12, frames=False)
    r = femp.run(s, tmp_path / "sampled", max_steps=12, frames=False, metrics_every=5)
    assert list(r.metrics["step"]) == [0, 5, 10, 12]
    assert r.summary["steps"] == 12
    assert r.summary["augury_iterations"] == full.summary["augury_iterations"]
    rows = [int(k) for k in r.metrics["step"]]
    for k in r.metrics:
        if k != "wall_s":
            np.testing.assert_array_equal(r.metrics[k], full.metrics[k][rows], err_msg=k)
    assert list(femp.read_metrics(tmp_path / "sampled")["step"]) == [0, 5, 10, 12]
    with pytest.raises(ValueError, match="metrics_every"):
        femp.run(s, tmp_path / "bad", max_steps=1, frames=False, metrics_every=0)


def test_used_output_directories_are_refused_unless_overwrite(fixtures, tmp_path):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    femp.run(s, tmp_path, max_steps=2, frames=False)
    with pytest.raises(femp.OutputError, match="overwrite"):
        femp.run(s, tmp_path, max_steps=2, frames=False)
    r = femp.run(s, tmp_path, max_steps=3, frames=False, overwrite=True)
    assert r.summary["steps"] == 3
    # An empty name is not the current directory (as `femp run --out ''`).
    cwd = os.getcwd()
    with pytest.raises(ValueError, match="out is empty"):
        femp.run(s, "", max_steps=1, frames=False)
    assert not os.path.exists(os.path.join(cwd, "summary.json"))


def test_ctrl_c_stops_a_run_and_keeps_its_outputs(tmp_path, fixtures):
    """SIGINT to a Python process inside femp.run: KeyboardInterrupt within a step or so, and
    summary.json says `interrupted` with every metrics row whole."""
    out = tmp_path / "out"
    # Python turns SIGINT into KeyboardInterrupt only if SIGINT was not ignored when it started
    # — and a job started with `&` by a non-interactive shell (a CI script run in the
    # background) starts with it ignored — so the child installs the handler itself.
    script = textwrap.dedent(f"""
        import femp, signal, sys
        signal.signal(signal.SIGINT, signal.default_int_handler)
        s = femp.Scene.load({os.path.join(fixtures, "colliding_rings.json")!r})
        try:
            femp.run(s, {str(out)!r}, frames=False)
        except KeyboardInterrupt:
            print("KeyboardInterrupt", flush=True)
            sys.exit(7)
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    metrics = out / "metrics.csv"
    deadline = time.time() + 120
    while time.time() < deadline:
        if metrics.exists() and metrics.read_text().count("\n") >= 3:
            break
        time.sleep(0.05)
    else:
        p.kill()
        pytest.fail("the run wrote no metrics in 120 s")
    clock = time.time()
    p.send_signal(signal.SIGINT)
    stdout, _ = p.communicate(timeout=60)
    assert p.returncode == 7 and "KeyboardInterrupt" in stdout
    assert time.time() - clock < 30
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", summary["status"]
    lines = metrics.read_text().splitlines()
    width = len(lines[0].split(","))
    assert all(len(line.split(",")) == width for line in lines[1:])
    assert summary["steps"] == len(lines) - 2


def test_metrics_are_the_values_not_their_csv_text(fixtures, tmp_path):
    dt = 1.0 / 300.0  # not a 7-digit decimal
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    s = s.with_changes({"time.dt": dt})
    r = femp.run(s, tmp_path, max_steps=2, frames=False)
    assert np.all(r.metrics["dt"] == dt)
    assert np.all(r.metrics["t"] == dt * r.metrics["step"])
    csv = femp.read_metrics(tmp_path)
    assert np.all(csv["dt"] != dt)  # metrics.csv rounds it
    np.testing.assert_allclose(csv["dt"], dt, rtol=5e-7)
    # A World's metrics: counts as ints, reals as floats.
    w = femp.World(s)
    w.step(1)
    m = w.metrics()
    assert isinstance(m["step"], int) and m["step"] == 1
    assert isinstance(m["newton_iterations"], int) and m["newton_iterations"] > 0
    assert isinstance(m["dt"], float) and m["dt"] == dt
