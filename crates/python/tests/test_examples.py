"""The examples in crates/python/examples run and their checks hold (each returns 0 only when
its own comparison — against the run's metrics, finite differences, the plate's position —
holds)."""

import contact_on_a_mesh
import read_frames


def test_read_frames_follows_the_metrics_and_the_free_fall(tmp_path, capsys):
    assert read_frames.main(["--out", str(tmp_path / "frames")]) == 0
    out = capsys.readouterr().out
    assert "momentum as in metrics.csv: True" in out and "False" not in out
    assert len(read_frames.frames(str(tmp_path / "frames" / "particles.pvd"))) == 5


def test_contact_on_a_mesh_matches_finite_differences_and_stops_at_the_plate(capsys):
    assert contact_on_a_mesh.main([]) == 0
    assert "stops at t = 0.49" in capsys.readouterr().out
