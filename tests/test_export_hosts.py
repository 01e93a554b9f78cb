"""FreeCAD macro, OpenSCAD and CadQuery exports, judged by running the real hosts on them."""

from __future__ import annotations

import ast
import json
import os
import re
import subprocess

import numpy as np
import pytest
from conftest import failures
from test_export_results import hand_result, polygon_result, reconstructed_result

from gsr_cad.errors import ExportError
from gsr_cad.exporters import hosts
from gsr_cad.exporters.base import num
from gsr_cad.exporters.model import curve_spline
from gsr_cad.exporters.cadquery import CadqueryExporter
from gsr_cad.exporters.encode import fill_python
from gsr_cad.exporters.hosts import cadquery_python
from gsr_cad.exporters.freecad import FreecadMacroExporter
from gsr_cad.exporters.openscad import OpenscadExporter, stroke_width
from gsr_cad.geometry import distance

needs_freecad = pytest.mark.skipif(hosts.find_host("freecad") is None, reason="FreeCAD (freecadcmd) not installed")
needs_openscad = pytest.mark.skipif(hosts.find_host("openscad") is None, reason="OpenSCAD not installed")
needs_cadquery = pytest.mark.skipif(cadquery_python() is None,
                                    reason="no .venv-cadquery (run scripts/cadquery-venv.sh)")

# A control polygon whose curve crosses itself (a loop), the hard case for a stroke outline.
LOOP = np.array([[0, 0], [6, 0], [7, 4], [3, 5], [2, 1], [8, -1], [10, 2]], dtype=float)


def statuses(checks) -> dict[str, str]:
    return {f"{c.host}:{c.check}": c.status for c in checks}


@pytest.fixture(scope="module")
def real_chaikin():
    return reconstructed_result("chaikin")


@needs_freecad
@pytest.mark.freecad
@pytest.mark.parametrize("which", ["hand", "reconstructed"])
def test_freecad_macro_rebuilds_history_and_curve(tmp_path, which, real_chaikin):
    result = hand_result(seed=11, n_ops=10, scale=5.0, offset=(100.0, -20.0)) if which == "hand" else real_chaikin
    exporter = FreecadMacroExporter()
    (path,) = exporter.export(result, tmp_path, "curve")
    checks = exporter.validate(path, result)
    assert failures(checks) == []
    got = statuses(checks)
    for name in ("one object per op", "op labels", "only the last step visible", "history polygons", "poles",
                 "knots", "JSON summary"):
        assert got[f"freecad:{name}"] == "pass"
    assert any(k.endswith("curve samples") for k in got)


@needs_freecad
@pytest.mark.freecad
def test_freecad_macro_runs_standalone_and_saves(tmp_path):
    result = hand_result(seed=12, n_ops=5)
    (path,) = FreecadMacroExporter().export(result, tmp_path, "my-curve")
    fcstd = tmp_path / "saved.FCStd"
    env = dict(os.environ, GSR_FCSTD=str(fcstd), QT_QPA_PLATFORM="offscreen")
    proc = subprocess.run([hosts.find_host("freecad"), str(path)], capture_output=True, text=True, env=env,
                          timeout=120, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(next(line for line in proc.stdout.splitlines() if line.startswith('{"document"')))
    assert summary["steps"] == len(result.genome) + 1 and summary["degree"] == 3
    assert summary["labels"][0] == "00 template" and summary["file"] == str(fcstd)
    assert fcstd.stat().st_size > 0
    # The curve length FreeCAD measures equals ours (dense polyline, converged to 1e-6).
    dense = curve_spline(result).dense(2048)
    assert summary["curve_length"] == pytest.approx(np.linalg.norm(np.diff(dense, axis=0), axis=1).sum(), rel=1e-6)


@needs_freecad
@pytest.mark.freecad
def test_freecad_macro_errors_exit_1_and_edits_fail_validation(tmp_path):
    result = hand_result(seed=13, n_ops=6, scale=2.0)
    exporter = FreecadMacroExporter()
    (path,) = exporter.export(result, tmp_path, "curve")
    text = path.read_text()
    # A hand-edited op parameter: the macro still runs and replays it, validation catches the moved points.
    data = data_of(text)
    last = data["steps"][-1]["op"]
    field = "position" if last["op"] == "add_point" else "delta"
    last[field][1] += 0.1
    path.write_text(fill_python("freecad_macro.py", data))
    got = statuses(exporter.validate(path, result))
    assert got["freecad:poles"] == "FAIL" and got["freecad:history polygons"] == "FAIL"
    assert [v for k, v in got.items() if k.endswith("curve samples")] == ["FAIL"]
    # A broken macro (an op index that does not exist) makes freecadcmd exit 1.
    last["index"] = 999
    path.write_text(fill_python("freecad_macro.py", data))
    with pytest.raises(ExportError, match=r"exit 1"):
        hosts.run_freecad(path, [tmp_path / "x.FCStd"], timeout=120)
    got = statuses(exporter.validate(path, result))
    assert got == {"freecad:run macro": "FAIL"}


def data_of(text: str) -> dict:
    """The DATA literal of a generated script."""
    (node,) = [n for n in ast.parse(text).body if isinstance(n, ast.Assign) and n.targets[0].id == "DATA"]
    return ast.literal_eval(node.value)


@needs_openscad
@pytest.mark.openscad
@pytest.mark.parametrize("case", ["hand-bspline", "tiny-chaikin", "loop-chaikin", "loop-bspline",
                                  "reconstructed-chaikin"])
def test_openscad_stroke_follows_the_curve(tmp_path, case, real_chaikin):
    if case == "hand-bspline":
        result = hand_result(seed=14, scale=30.0)
    elif case == "tiny-chaikin":  # a 4e-4 wide curve: finer than OpenSCAD's 1/65536 grid without gsr_unit
        result = hand_result(seed=15, scheme="chaikin", scale=1e-4)
    elif case == "reconstructed-chaikin":
        result = real_chaikin
    else:
        result = polygon_result(LOOP, case.split("-")[1])
    exporter = OpenscadExporter()
    (path,) = exporter.export(result, tmp_path, "curve")
    checks = exporter.validate(path, result)
    assert failures(checks) == [] and len(checks) == 6


@needs_openscad
@pytest.mark.openscad
def test_openscad_width_is_configurable_and_edits_fail(tmp_path):
    import trimesh

    result = polygon_result(LOOP)
    spline = curve_spline(result)
    exporter = OpenscadExporter()
    (path,) = exporter.export(result, tmp_path, "curve")
    wide = 4 * stroke_width(spline)
    stl = tmp_path / "wide.stl"
    hosts.run_openscad(path, stl, defines={"width": num(wide), "part": '"curve"', "height": "2"})
    mesh = trimesh.load(str(stl), force="mesh")
    d = distance.point_to_polyline(np.asarray(mesh.vertices)[:, :2], spline.dense(256))
    assert wide / 2 * 0.99 < d.max() <= wide / 2 * 1.02 + 1e-4
    assert np.ptp(mesh.vertices[:, 2]) == pytest.approx(2.0)
    # Moving one stroke sample off the curve is reported.
    text = path.read_text()
    first = re.search(r"gsr_curve_points = \[\s*\[([^\]]+)\]", text)
    x, y = (float(v) for v in first.group(1).split(","))
    path.write_text(text[:first.start(1)] + f"{x}, {y + 1.0}" + text[first.end(1):])
    got = statuses(exporter.validate(path, result))
    assert got["openscad:curve: vertices within half width of our curve"] == "FAIL"
    assert got["openscad:control_polygon: vertices within half width of our control polygon"] == "pass"


@needs_cadquery
def test_cadquery_script_rebuilds_the_exact_curve(tmp_path, real_chaikin):
    exporter = CadqueryExporter()
    (path,) = exporter.export(real_chaikin, tmp_path, "curve")
    assert path.name == "curve_cadquery.py"
    checks = exporter.validate(path, real_chaikin)
    assert failures(checks) == []
    assert {"cadquery:poles", "cadquery:knots", "cadquery:degree"} <= set(statuses(checks))
    # A hand-edited pole is caught.
    text = path.read_text()
    pole = real_chaikin.control_points[1]
    path.write_text(text.replace(num(pole[0]), repr(float(pole[0]) + 0.5), 1))
    got = statuses(exporter.validate(path, real_chaikin))
    assert got["cadquery:poles"] == "FAIL"
