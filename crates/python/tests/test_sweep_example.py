"""The shipped sweep example runs (quick mode, 2 jobs) and matches Coulomb's law."""

import csv

import friction_sweep


def test_friction_sweep_example_matches_coulomb(tmp_path):
    assert friction_sweep.main(["--out", str(tmp_path), "--quick", "--jobs", "2"]) == 0
    rows = list(csv.DictReader(open(tmp_path / "sweep.csv")))
    assert len(rows) == 6
    for r in rows:
        a, exact = float(r["acceleration"]), float(r["analytic"])
        assert r["status"] == "completed"
        if exact > 0:  # slides: within 0.1 % of g (sin θ − μ cos θ)
            assert abs(a - exact) <= 1e-3 * exact, r
        else:  # sticks
            assert abs(a) < 1e-3, r
    png = (tmp_path / "friction_sweep.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
