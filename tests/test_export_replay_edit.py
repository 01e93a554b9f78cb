"""The ops are the source of truth: edit an op in result.json, ``gsr replay``, and every export follows."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import failures
from test_export_results import hand_result
from test_export_surface_hosts import surface_result

from gsr_cad.exporters import hosts
from gsr_cad.reconstruct.export import read_manifest, validate
from gsr_cad.reconstruct.result import Result

CURVE_FORMATS = "step,dxf,svg,scad,blender,fcmacro,cadquery"
SURFACE_FORMATS = "step,scad,blender,fcmacro,cadquery"


def _hosts_or_skip():
    if not all(hosts.find_host(h) for h in ("blender", "freecad", "openscad")):
        pytest.skip("needs Blender, FreeCAD and OpenSCAD")


def _host_rows(checks) -> set[str]:
    return {c.host for c in checks if c.passed}


def test_replay_without_control_points_rebuilds_them_from_the_genome(gsr, tmp_path):
    result = hand_result(seed=41, n_ops=6)
    doc = result.to_json()
    del doc["control_points"]
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "result.json").write_text(json.dumps(doc))
    run = gsr("replay", tmp_path / "in", "-o", tmp_path / "out", "--formats", "svg")
    assert run.code == 0, run.err
    np.testing.assert_array_equal(Result.load(tmp_path / "out").control_points, result.control_points)


def test_an_op_that_no_longer_applies_is_one_line(gsr, tmp_path):
    doc = hand_result(seed=42, n_ops=6).to_json()
    doc["genome"][0] = {"op": "add_point", "index": 50, "position": [0.5, 0.5]}
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "result.json").write_text(json.dumps(doc))
    run = gsr("replay", tmp_path / "in", "-o", tmp_path / "out")
    assert run.code == 2 and len(run.err.strip().splitlines()) == 1
    assert run.err.startswith("error: genome op 0 (add point) no longer applies: add_point index 50")


@pytest.mark.blender
@pytest.mark.freecad
@pytest.mark.openscad
def test_an_edited_curve_op_moves_every_export(gsr, tmp_path):
    _hosts_or_skip()
    result = hand_result(seed=43, n_ops=8, scale=3.0)
    first = tmp_path / "first"
    result.save(first)
    assert gsr("replay", first, "-o", first, "--formats", CURVE_FORMATS).code == 0
    doc = json.loads((first / "result.json").read_text())
    k = max(i for i, op in enumerate(doc["genome"]) if op["op"] == "move_point")
    doc["genome"][k]["delta"][1] += 0.05
    (first / "result.json").write_text(json.dumps(doc))
    second = tmp_path / "second"
    run = gsr("replay", first, "-o", second, "--formats", CURVE_FORMATS)
    assert run.code == 0 and "note: control_points in the result differ" in run.err and "genome wins" in run.err
    edited = Result.load(second)
    moved = edited.control_points - result.control_points  # later ops keep the moved point moved
    (row,) = np.flatnonzero(np.abs(moved).sum(axis=1) > 1e-12)
    np.testing.assert_allclose(moved[row], [0.0, 0.05], atol=1e-12)
    assert set(read_manifest(second)) == {p.name for p in second.iterdir()} - {"result.json", "control_points.csv",
                                                                                "exports.json"}
    checks = validate(second)
    assert failures(checks) == []
    assert {"blender", "freecad", "openscad", "OCP", "ezdxf"} <= _host_rows(checks)
    # first/ holds the edited result.json beside the old scripts: they are refused as modified, never run
    stale = [c for c in validate(first) if c.check == "written by gsr"]
    assert stale and all(c.passed is False and c.detail.startswith("modified") for c in stale)


@pytest.mark.blender
@pytest.mark.freecad
@pytest.mark.openscad
def test_an_edited_surface_op_moves_every_export(gsr, tmp_path):
    _hosts_or_skip()
    result = surface_result()
    first = tmp_path / "first"
    result.save(first)
    doc = json.loads((first / "result.json").read_text())
    assert doc["genome"][0] == {"op": "extrude", "face": 5, "distance": 0.42}
    doc["genome"][0]["distance"] = 0.5
    (first / "result.json").write_text(json.dumps(doc))
    second = tmp_path / "second"
    run = gsr("replay", first, "-o", second, "--formats", SURFACE_FORMATS)
    assert run.code == 0, run.err
    edited = Result.load(second)
    shift = np.linalg.norm(edited.states[1].vertices - result.states[1].vertices, axis=1)
    np.testing.assert_allclose(np.sort(shift)[-4:], 0.08, rtol=1e-9)  # the extruded cap moved by 0.5 - 0.42
    assert np.count_nonzero(shift > 1e-12) == 4
    assert not np.allclose(edited.control_mesh.vertices, result.control_mesh.vertices)
    checks = validate(second)
    assert failures(checks) == []
    assert {"blender", "freecad", "openscad", "OCP"} <= _host_rows(checks)


@pytest.mark.blender
@pytest.mark.freecad
def test_replay_saves_the_host_documents(gsr, tmp_path):
    import subprocess

    if not (hosts.find_host("blender") and hosts.find_host("freecad")):
        pytest.skip("needs Blender and FreeCAD")
    from gsr_cad.exporters.checks import freecad_read

    result = hand_result(seed=45, n_ops=5)
    result.save(tmp_path / "in")
    fcstd, blend = tmp_path / "docs" / "curve.FCStd", tmp_path / "docs" / "curve.blend"
    run = gsr("replay", tmp_path / "in", "-o", tmp_path / "out", "--formats", "svg", "--fcstd", fcstd, "--blend", blend)
    assert run.code == 0, run.err
    assert f"wrote {fcstd}" in run.out and f"wrote {blend}" in run.out
    seen = freecad_read(fcstd, params=[0.0, 1.0])
    assert len(seen["steps"]) == len(result.genome) + 1 and seen["curve"]["degree"] == 3
    np.testing.assert_allclose(np.array(seen["steps"][-1]["nodes"])[:, :2], result.control_points, atol=1e-12)
    probe = ("import bpy, json, sys; "
             "sys.stdout.write('OBJECTS ' + json.dumps(sorted(o.name for o in bpy.data.objects)) + '\\n')")
    proc = subprocess.run([hosts.find_host("blender"), "-b", str(blend), "--python-expr", probe], capture_output=True,
                          text=True, timeout=300)
    line = next(x for x in proc.stdout.splitlines() if x.startswith("OBJECTS "))
    names = json.loads(line[len("OBJECTS "):])
    assert "curve" in names and len(names) == len(result.genome) + 2  # the steps and the Bezier curve, no cube
    bad = gsr("replay", tmp_path / "in", "-o", tmp_path / "out2", "--fcstd", tmp_path / "x.step")
    assert bad.code == 2 and "--fcstd needs a file name ending in .fcstd" in bad.err
    assert not (tmp_path / "out2").exists()
