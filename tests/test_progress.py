"""The progress output: a bar that ends full and marked done, then a status line for every phase."""

from __future__ import annotations

from cli_subprocess import TINY_CURVE, gsr

from gsr_cad.reconstruct.samples import get_sample


def test_every_phase_has_a_status_line_and_the_bar_ends_done(tmp_path):
    get_sample("bspline_05").write(tmp_path / "c.csv")
    flags = [f for f in TINY_CURVE if f not in ("--quiet",)]
    run = gsr(["curve", "c.csv", "-o", "out", *flags], tmp_path)
    assert run.code == 0, run.describe()
    err = run.err
    phases = ["search done", "writing result.json", "writing control_points.csv", "drawing report.png",
              "writing the exports"]
    positions = [err.find(p) for p in phases]
    assert all(p >= 0 for p in positions) and positions == sorted(positions), err
    bar = next(line for line in run.err_lines if line.startswith("curve c"))
    assert " done " in bar and "gen    2" in bar, bar
    assert "Traceback" not in err and "warning" not in err.lower()
