"""The FreeCAD macro's history is a lever: edit an op's property in FreeCAD, recompute, and the later ops
and the curve follow (run in ``freecadcmd``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_export_results import hand_result

from gsr_cad.exporters import hosts
from gsr_cad.exporters.freecad import FreecadMacroExporter
from gsr_cad.exporters.model import curve_model

DRIVER = '''import json
import os
import runpy

import FreeCAD as App

macro, out, number, dy = os.environ["GSR_ARGS"].split(os.pathsep)
os.environ["GSR_ARGS"] = ""  # the macro would save the document to its first argument
runpy.run_path(macro)
doc = App.ActiveDocument


def state():
    steps = [obj for obj in doc.getObject("History").Group]
    curve = doc.getObject("Curve").Shape.Edges[0].Curve
    return {"steps": [[[v.x, v.y] for v in obj.Points] for obj in steps], "ops": [obj.Op for obj in steps],
            "poles": [[p.x, p.y] for p in curve.getPoles()], "knots": curve.getKnots(),
            "mults": curve.getMultiplicities(), "length": doc.getObject("Curve").Shape.Length}


before = state()
step = doc.getObject("Step%03d" % int(number))
step.Delta = App.Vector(step.Delta.x, step.Delta.y + float(dy), 0.0)
doc.recompute()
after = state()
after["valid"] = all(obj.isValid() for obj in doc.Objects)
with open(out, "w") as fh:
    json.dump({"before": before, "after": after}, fh)
'''


@pytest.mark.freecad
def test_editing_an_op_in_freecad_recomputes_the_later_ops_and_the_curve(tmp_path):
    if hosts.find_host("freecad") is None:
        pytest.skip("FreeCAD (freecadcmd) is not installed")
    result = hand_result(seed=44, n_ops=8, scale=2.0)
    model = curve_model(result)
    (macro,) = FreecadMacroExporter().export(result, tmp_path, "curve")
    moves = [i for i, op in enumerate(result.genome) if op.name == "move_point"]
    k = moves[0]  # an early move: several later ops must be replayed after it
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    out = tmp_path / "out.json"
    hosts.run_freecad(driver, [macro, out, k + 1, 0.05], timeout=300)
    data = json.loads(out.read_text())
    before, after = data["before"], data["after"]
    assert after["valid"]
    for got, step in zip(before["steps"], model.history):  # the macro first builds exactly our history
        np.testing.assert_allclose(got, step.points, atol=1e-12)
    # the edited op and every later one are replayed from the new point; earlier steps are untouched
    index = result.genome[k].index
    for number, (old, new) in enumerate(zip(before["steps"], after["steps"])):
        old, new = np.array(old), np.array(new)
        if number <= k:
            np.testing.assert_array_equal(old, new)
            continue
        moved = np.flatnonzero(np.abs(new - old).sum(axis=1) > 1e-12)
        assert len(moved) == 1 and np.allclose(new[moved[0]] - old[moved[0]], [0.0, 0.05], atol=1e-12)
        index = moved[0]
    assert json.loads(after["ops"][k + 1])["delta"][1] == pytest.approx(result.genome[k].delta[1] + 0.05, abs=1e-12)
    # the curve is rebuilt on the last step's points: the moved pole and a different length
    np.testing.assert_allclose(after["poles"], after["steps"][-1], atol=1e-12)
    assert np.allclose(np.array(after["poles"]) - np.array(before["poles"]),
                       np.eye(len(after["poles"]))[index][:, None] * [0.0, 0.05], atol=1e-12)
    assert after["length"] != pytest.approx(before["length"], rel=1e-9)
    assert after["mults"] == before["mults"] and np.allclose(after["knots"], model.spline.breakpoints, atol=1e-12)
