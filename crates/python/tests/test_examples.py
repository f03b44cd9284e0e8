"""The examples in crates/python/examples run and their checks hold (each returns 0 only when
its own comparison — against the run's metrics, finite differences, the plate's position —
holds)."""

import contact_on_a_mesh
import control_loop
import pytest
import read_frames


def test_read_frames_follows_the_metrics_and_the_free_fall(tmp_path, capsys):
    assert read_frames.main(["--out", str(tmp_path / "frames")]) == 0
    out = capsys.readouterr().out
    assert "momentum as in metrics.csv: True" in out and "False" not in out
    assert len(read_frames.frames(str(tmp_path / "frames" / "particles.pvd"))) == 5


def test_contact_on_a_mesh_matches_finite_differences_and_stops_at_the_plate(capsys):
    assert contact_on_a_mesh.main([]) == 0
    assert "stops at t = 0.49" in capsys.readouterr().out


def test_control_loop_brings_the_block_to_its_goal_and_records_it(tmp_path, capsys):
    out = tmp_path / "control"
    assert control_loop.main(["--out", str(out), "--pictures"]) == 0
    assert "particles inside a body: 0" in capsys.readouterr().out
    assert (out / "pictures" / "animation.gif").read_bytes()[:6] == b"GIF89a"
    assert (out / "frames").is_dir() and (out / "particles.pvd").exists()


def test_mesh_from_stl_fills_the_surface_and_the_ball_falls_freely(tmp_path, capsys):
    pytest.importorskip("gmsh")
    import mesh_from_stl

    assert mesh_from_stl.main(["--out", str(tmp_path / "stl")]) == 0
    assert "volume exact, mass within 5 %" in capsys.readouterr().out
