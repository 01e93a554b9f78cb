"""``gsr surface`` end to end: the files it writes, the Blender replay of its genome, one-line errors with
nothing written, Ctrl-C keeping the best so far, and the quick benchmark."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gsr_cad import plots
from gsr_cad.exporters.hosts import find_host
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.reconstruct.meshio import load_mesh, save_mesh
from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES

REPO = Path(__file__).resolve().parents[1]
SMALL = ["--population", "12", "--initial-population", "12", "--n-parents", "4", "--max-children", "2",
         "--n-perturb", "2", "--n-newcomers", "2"]


@pytest.fixture(scope="module")
def extended_obj(tmp_path_factory) -> Path:
    return save_mesh(SURFACE_SAMPLES["extended"]().target, tmp_path_factory.mktemp("t") / "extended.obj")


def test_surface_writes_result_meshes_report_and_blender_script(gsr, tmp_path, extended_obj):
    out = tmp_path / "out"
    res = gsr("surface", extended_obj, "-o", out, "--seed", "1", "--formats", "blender", "--quiet")
    assert res.code == 0, res.err
    assert {p.name for p in out.iterdir()} == {"result.json", "control_mesh.obj", "limit_mesh.obj", "report.png",
                                              "report.html", "surface_blender.py", "exports.json"}
    result = Result.load(out)
    data = json.loads((out / "result.json").read_text())
    assert data["kind"] == "surface" and data["config"]["template"]["source"] == "cube"
    assert result.metrics["mean_distance"] <= 1e-4
    control = load_mesh(out / "control_mesh.obj")
    np.testing.assert_array_equal(control.vertices, result.control_mesh.vertices)
    lim = load_mesh(out / "limit_mesh.obj")
    np.testing.assert_array_equal(lim.vertices, limit_mesh(result.control_mesh, 2).vertices)
    assert (out / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a result read back from result.json (no target, no snapshots) still draws its final mesh
    again = plots.surface_report(result, tmp_path / "again.png")
    assert again.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "data to fit:" in res.out and "fit to data:" in res.out and "wrote" in res.out
    if find_host("blender") is None:
        pytest.skip("Blender is not installed: the replay script is written but not run")
    check = gsr("validate", out)
    assert check.code == 0, check.out + check.err
    assert " 0 FAIL" in check.out and "blender" in check.out and "pass" in check.out


def test_a_quad_mesh_template_file_and_a_cloud_target(gsr, tmp_path):
    s = SURFACE_SAMPLES["flattened_extended"]()
    cloud = tmp_path / "cloud.xyz"
    s.write_cloud(cloud)
    template = save_mesh(s.truth_control, tmp_path / "template.obj")  # the answer as template: nothing to do
    out = tmp_path / "out"
    res = gsr("surface", cloud, "-o", out, "--template", template, "--seed", "2", "--formats", "none", "--quiet",
              *SMALL, "--generations", "2")
    assert res.code == 0, res.err
    result = Result.load(out)
    assert result.config["template"]["source"] == str(template)
    assert result.config["target"]["kind"] == "cloud"
    assert result.metrics["mean_distance"] <= 1e-4


BAD_TARGETS = {
    "missing.obj": None,
    "empty.xyz": "",
    "nan.xyz": "0 0 0\n1 nan 0\n0 1 0\n0 0 1\n",
    "three.xyz": "0 0 0\n1 0 0\n0 1 1\n",
    "planar.csv": "0,0\n1,0\n0,1\n1,1\n",
    "flat.xyz": "0 0 1\n1 0 1\n0 1 1\n3 4 1\n2 7 1\n",
    "point.xyz": "1 1 1\n1 1 1\n1 1 1\n1 1 1\n",
}


@pytest.mark.parametrize("name", sorted(BAD_TARGETS))
def test_bad_targets_are_one_line_errors_and_nothing_is_written(gsr, tmp_path, name):
    target = tmp_path / name
    if BAD_TARGETS[name] is not None:
        target.write_text(BAD_TARGETS[name])
    out = tmp_path / "out"
    res = gsr("surface", target, "-o", out, "--quiet")
    assert res.code == 2 and res.out == ""
    assert res.err.startswith("error: ") and res.err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--template", "triangles.obj"], "not a valid quad mesh"),
    (["--template", "nowhere.obj"], "no such file"),
    (["--generations", "0"], "generations"),
    (["--formats", "nosuchformat"], "unknown format"),
    (["--workers", "0"], "workers"),
    (["--preset", "fastest"], "preset"),
])
def test_bad_options_are_one_line_errors_and_nothing_is_written(gsr, tmp_path, extended_obj, args, message):
    (tmp_path / "triangles.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    args = [str(tmp_path / a) if a.endswith(".obj") else a for a in args]
    out = tmp_path / "out"
    res = gsr("surface", extended_obj, "-o", out, "--quiet", *args)
    assert res.code == 2 and message in res.err and res.err.count("\n") == 1
    assert not out.exists()


def test_ctrl_c_writes_the_best_so_far(tmp_path):
    target = tmp_path / "ring.obj"
    save_mesh(SURFACE_SAMPLES["unreachable"]().target, target)
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "gsr_cad", "surface", str(target), "-o", str(out), "--seed", "1",
                             "--formats", "none", "--quiet", "--generations", "100000", "--threshold", "0", *SMALL],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 60
    while not out.exists() and time.monotonic() < deadline:  # the output folder appears once input is checked
        time.sleep(0.2)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    assert stdout.startswith("interrupted: best so far")
    data = json.loads((out / "result.json").read_text())
    assert data["interrupted"] is True and data["genome"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file left behind


def test_quick_benchmark_writes_its_table(tmp_path):
    table = tmp_path / "surfaces.md"
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / "surfaces.py"), "--quick", "--samples",
                           "extended", "--kinds", "mesh", "cloud", "--out", str(table)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    text = table.read_text()
    assert "| extended | mesh |" in text and "| extended | cloud |" in text
    assert "Done-when targets" in text and "extended: mean" in text
