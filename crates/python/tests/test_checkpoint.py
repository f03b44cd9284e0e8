"""Checkpoints from Python: a run or a World stopped and continued steps on bit for bit as one
never stopped, and what cannot be continued is refused with what is wrong."""

import os

import numpy as np
import pytest

import femp


@pytest.fixture
def plate(fixtures):
    # The block lands on the plate at about step 7 and slides on it with friction; a frame (and
    # a checkpoint) every 5 steps.
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    return s.with_changes({"contact.friction": 0.3, "time.duration": 0.3})


def _same_rows(a, b, since=0):
    """metrics.csv of two runs equal from step ``since`` on (the wall time aside)."""
    rows = a["step"] >= since
    assert list(a) == list(b)
    for k in a:
        if k != "wall_s":
            np.testing.assert_array_equal(a[k][rows], b[k][b["step"] >= since], err_msg=k)


def test_a_resumed_run_ends_as_one_never_stopped(plate, tmp_path):
    whole = femp.run(plate, tmp_path / "whole", frames=False)
    assert whole.summary["steps"] == 30
    out = tmp_path / "stopped"
    first = femp.run(plate, out, frames=False, checkpoint=True, max_steps=17)
    assert first.summary["steps"] == 17 and (out / "checkpoint.femp").is_file()
    # The last checkpoint is the frame time at step 15: the run continues from there.
    r = femp.run(plate, out, frames=False, checkpoint=True, resume=True)
    assert r.summary["status"] == "completed" and r.summary["steps"] == 30
    assert r.summary["resumed_at"] == [15]
    assert r.metrics["step"][0] == 16 and r.metrics["step"][-1] == 30
    # metrics.csv as one never stopped, and the rows returned (the values themselves) those
    # from the resumption on.
    _same_rows(femp.read_metrics(out), femp.read_metrics(tmp_path / "whole"))
    _same_rows(r.metrics, whole.metrics, since=16)
    # The totals carry on across the resumption (step 16 and 17 were taken twice, counted once).
    for k in ("newton_iterations", "friction_iterations", "stick_model_directions"):
        assert r.summary[k] == whole.summary[k], k


def test_a_world_restored_steps_on_as_the_world_it_was_taken_of(plate, tmp_path):
    a = femp.World(plate)
    a.step(12)
    path = tmp_path / "state.femp"
    a.checkpoint(path)
    a.step(6)
    b = femp.World(plate)
    b.restore(path)
    assert (b.steps, b.time) == (12, pytest.approx(0.12, abs=1e-15))
    b.step(6)
    assert b.steps == a.steps == 18
    pa, pb = a.particles(), b.particles()
    for k in ("x", "v", "F", "B", "contact_force"):
        np.testing.assert_array_equal(pa[k], pb[k], err_msg=k)
    np.testing.assert_array_equal(a.fem("plate")["x"], b.fem("plate")["x"])
    assert a.metrics()["total_energy"] == b.metrics()["total_energy"]


def test_a_recording_resumed_continues_its_files(plate, tmp_path):
    whole = femp.World(plate)
    with whole.record(tmp_path / "whole", frames=False) as w:
        whole.step(20)
    a = femp.World(plate)
    with a.record(tmp_path / "rec", frames=False, checkpoint=True):
        a.step(13)  # the last checkpoint: step 10
    b = femp.World(plate)
    with b.record(tmp_path / "rec", frames=False, checkpoint=True, resume=True) as rec:
        assert b.steps == 10
        b.step(10)
    assert rec.result is not None and rec.result.summary["resumed_at"] == [10]
    assert w.result is not None
    _same_rows(femp.read_metrics(tmp_path / "rec"), femp.read_metrics(tmp_path / "whole"))


def test_what_cannot_be_checkpointed_or_resumed_is_refused(plate, fixtures, tmp_path):
    with pytest.raises(femp.CheckpointError, match="no checkpoint"):
        femp.run(plate, tmp_path / "empty", resume=True)
    femp.run(plate, tmp_path / "ran", frames=False, checkpoint=True, max_steps=5)
    with pytest.raises(femp.CheckpointError, match="resumed or overwritten"):
        femp.run(plate, tmp_path / "ran", resume=True, overwrite=True)
    # Another scene's checkpoint: the field that differs is named.
    other = plate.with_changes({"contact.friction": 0.5})
    with pytest.raises(femp.CheckpointError, match="contact.friction"):
        femp.run(other, tmp_path / "ran", resume=True)
    w = femp.World(other)
    with pytest.raises(femp.CheckpointError, match="contact.friction"):
        w.restore(tmp_path / "ran" / "checkpoint.femp")
    assert w.steps == 0
    # A damaged file.
    bad = tmp_path / "bad.femp"
    data = bytearray((tmp_path / "ran" / "checkpoint.femp").read_bytes())
    data[len(data) // 2] ^= 1
    bad.write_bytes(bytes(data))
    with pytest.raises(femp.CheckpointError, match="checksum"):
        femp.World(plate).restore(bad)
    # A World steered from outside has no checkpoint: what steers it is not in the scene.
    steered = femp.World(plate)
    steered.apply_forces(particles=np.zeros_like(steered.particles()["x"]))
    with pytest.raises(femp.CheckpointError, match="steered"):
        steered.checkpoint(tmp_path / "steered.femp")
    # Augury keeps its state in its own explicit system.
    blocks = femp.Scene.load(os.path.join(fixtures, "augury_blocks.json"))
    with pytest.raises(femp.CheckpointError, match="BFEMP"):
        femp.run(blocks, tmp_path / "augury", checkpoint=True, max_steps=2)
    with pytest.raises(femp.CheckpointError, match="BFEMP"):
        femp.World(blocks).checkpoint(tmp_path / "augury.femp")
