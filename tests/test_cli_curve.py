"""``gsr curve`` end to end, and every bad input: one line, exit 2, nothing written."""

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.interpolate import BSpline

from gsr_cad.geometry.bspline import clamped_uniform_knots

FAST = ["--initial-population", "200", "--population", "40", "--generations", "30", "--quiet",
        "--formats", "none"]


@pytest.fixture
def curve_csv(tmp_path):
    ctrl = np.array([[0, 0], [1, 2], [3, 2.5], [4, -1], [6, 0.5], [7, 2]], float)
    pts = BSpline(clamped_uniform_knots(len(ctrl), 3), ctrl, 3)(np.linspace(0, 1, 150))
    path = tmp_path / "pts.csv"
    path.write_text("x,y\n" + "\n".join(f"{x:.17g},{y:.17g}" for x, y in pts) + "\n")
    truth = tmp_path / "truth.csv"
    truth.write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in ctrl) + "\n")
    return path, truth, ctrl


def test_curve_end_to_end(gsr, curve_csv, tmp_path):
    path, truth, ctrl = curve_csv
    out = tmp_path / "out"
    run = gsr("curve", path, "-o", out, "--seed", "3", "--truth", truth, *FAST)
    assert run.code == 0, run.err
    data = json.loads((out / "result.json").read_text())
    assert data["kind"] == "curve" and data["version"] == 1 and data["seed"] == 3
    assert len(data["control_points"]) == len(ctrl)
    assert {"generation", "best_fitness", "mean_fitness", "seconds"} <= set(data["history"][0])
    for key in ("fitness", "mean_distance", "max_distance", "n_control_points", "seconds"):
        assert key in data["metrics"]
    csv = np.loadtxt(out / "control_points.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(csv, data["control_points"])
    assert (out / "report.png").stat().st_size > 10_000
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_same_seed_same_result(gsr, curve_csv, tmp_path):
    path, _, _ = curve_csv
    for name in ("a", "b"):
        assert gsr("curve", path, "-o", tmp_path / name, "--seed", "11", "--preset", "paper", *FAST).code == 0
    a = json.loads((tmp_path / "a" / "result.json").read_text())
    b = json.loads((tmp_path / "b" / "result.json").read_text())
    assert a["genome"] == b["genome"] and a["control_points"] == b["control_points"]


BAD_FILES = {
    "empty.csv": "",
    "words.csv": "x,y\n0,0\n1,one\n2,2\n3,3\n",
    "nan.csv": "0,0\n1,nan\n2,2\n3,3\n",
    "inf.csv": "0,0\n1,1\n2,-inf\n3,3\n",
    "three.csv": "0,0\n1,1\n2,2\n",
    "cols.csv": "0,0,0,0\n1,1,0,0\n2,2,0,0\n3,3,0,0\n",
    "equal.csv": "2,2\n2,2\n2,2\n2,2\n2,2\n",
    "dups.csv": "0,0\n1,1\n1,1\n2,3\n3,3\n",
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_input_files(gsr, tmp_path, name):
    path = tmp_path / name
    path.write_text(BAD_FILES[name])
    out = tmp_path / "out"
    run = gsr("curve", path, "-o", out, *FAST)
    assert run.code == 2
    assert run.err.startswith("error: ") and run.err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("flags", [
    ["--population", "-5"], ["--generations", "0"], ["--mutation-rate", "1.5"], ["--scheme", "nurbs"],
    ["--population", "many"], ["--threshold", "nan"],
])
def test_absurd_flags(gsr, curve_csv, tmp_path, flags):
    path, _, _ = curve_csv
    out = tmp_path / "out"
    run = gsr("curve", path, "-o", out, "--quiet", *flags)
    assert run.code == 2
    assert run.err.startswith("error: ") and run.err.count("\n") == 1
    assert not out.exists()


def test_missing_file_and_unwritable_out(gsr, curve_csv, tmp_path):
    run = gsr("curve", tmp_path / "missing.csv", "-o", tmp_path / "out", *FAST)
    assert run.code == 2 and "no such file" in run.err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    path, _, _ = curve_csv
    run = gsr("curve", path, "-o", blocker / "sub", *FAST)
    assert run.code == 2 and run.err.startswith("error: ")


def test_python_dash_m_entry_point(curve_csv, tmp_path):
    path, _, _ = curve_csv
    proc = subprocess.run([sys.executable, "-m", "gsr_cad", "curve", str(path), "-o", str(tmp_path / "o"),
                           "--population", "0"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr
