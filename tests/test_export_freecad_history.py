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

macro, out, number, prop, value = os.environ["GSR_ARGS"].split(os.pathsep)
os.environ["GSR_ARGS"] = ""  # the macro would save the document to its first argument
runpy.run_path(macro)
doc = App.ActiveDocument


def state():
    steps = doc.getObject("History").Group
    out = {"steps": [[[v.x, v.y, v.z] for v in obj.Points] for obj in steps], "ops": [obj.Op for obj in steps]}
    if doc.getObject("Curve") is not None:
        feature = doc.getObject("Curve")
        curve = feature.Shape.Edges[0].Curve
        out.update(poles=[[p.x, p.y] for p in curve.getPoles()], knots=curve.getKnots(),
                   mults=curve.getMultiplicities(), length=feature.Shape.Length, periodic=curve.isPeriodic(),
                   corners=[list(obj.Corners) for obj in steps])
    else:
        out["limit"] = [[p.x, p.y, p.z] for p in doc.getObject("LimitMesh").Mesh.Topology[0]]
    return out


before = state()
new = json.loads(value)
setattr(doc.getObject("Step%03d" % int(number)), prop, App.Vector(*new) if isinstance(new, list) else new)
doc.recompute()
after = state()
after["valid"] = all(obj.isValid() for obj in doc.Objects)
with open(out, "w") as fh:
    json.dump({"before": before, "after": after}, fh)
'''


def _edit(macro, tmp_path, number: int, prop: str, value) -> tuple[dict, dict]:
    """Run the macro in freecadcmd, set property ``prop`` of step ``number`` to ``value``, recompute; the
    document's state before and after (which must recompute without an invalid object)."""
    driver, out = tmp_path / "driver.py", tmp_path / "out.json"
    driver.write_text(DRIVER)
    hosts.run_freecad(driver, [macro, out, number, prop, json.dumps(value)], timeout=300)
    data = json.loads(out.read_text())
    assert data["after"]["valid"]
    return data["before"], data["after"]


@pytest.mark.freecad
def test_editing_an_op_in_freecad_recomputes_the_later_ops_and_the_curve(tmp_path):
    if hosts.find_host("freecad") is None:
        pytest.skip("FreeCAD (freecadcmd) is not installed")
    result = hand_result(seed=44, n_ops=8, scale=2.0)
    model = curve_model(result)
    (macro,) = FreecadMacroExporter().export(result, tmp_path, "curve")
    moves = [i for i, op in enumerate(result.genome) if op.name == "move_point"]
    k = moves[0]  # an early move: several later ops must be replayed after it
    delta = [result.genome[k].delta[0], result.genome[k].delta[1] + 0.05, 0.0]
    before, after = _edit(macro, tmp_path, k + 1, "Delta", delta)
    for got, step in zip(before["steps"], model.history):  # the macro first builds exactly our history
        np.testing.assert_allclose(np.array(got)[:, :2], step.points, atol=1e-12)
    # the edited op and every later one are replayed from the new point; earlier steps are untouched
    index = result.genome[k].index
    for number, (old, new) in enumerate(zip(before["steps"], after["steps"])):
        old, new = np.array(old)[:, :2], np.array(new)[:, :2]
        if number <= k:
            np.testing.assert_array_equal(old, new)
            continue
        moved = np.flatnonzero(np.abs(new - old).sum(axis=1) > 1e-12)
        assert len(moved) == 1 and np.allclose(new[moved[0]] - old[moved[0]], [0.0, 0.05], atol=1e-12)
        index = moved[0]
    assert json.loads(after["ops"][k + 1])["delta"][1] == pytest.approx(result.genome[k].delta[1] + 0.05, abs=1e-12)
    # the curve is rebuilt on the last step's points: the moved pole and a different length
    np.testing.assert_allclose(after["poles"], np.array(after["steps"][-1])[:, :2], atol=1e-12)
    assert np.allclose(np.array(after["poles"]) - np.array(before["poles"]),
                       np.eye(len(after["poles"]))[index][:, None] * [0.0, 0.05], atol=1e-12)
    assert after["length"] != pytest.approx(before["length"], rel=1e-9)
    assert after["mults"] == before["mults"] and np.allclose(after["knots"], model.spline.breakpoints, atol=1e-12)




@pytest.mark.freecad
def test_editing_an_op_of_a_closed_cornered_curve_keeps_it_periodic_with_its_corners(tmp_path):
    """FreeCAD's recompute after an edit is gsr_cad's replay of the edited genome: the same periodic B-spline
    (poles, knots, corner multiplicities)."""
    if hosts.find_host("freecad") is None:
        pytest.skip("FreeCAD (freecadcmd) is not installed")
    import dataclasses

    from test_export_curve_forms import _square

    from gsr_cad.errors import GsrError
    from gsr_cad.exporters.model import curve_spline
    from gsr_cad.reconstruct.curve import reconstruct_curve
    from gsr_cad.reconstruct.inputs import curve_target

    result = reconstruct_curve(curve_target(_square()), seed=1)
    assert result.config["closed"] and result.config["corners"]
    genome = list(result.genome)
    for k, op in enumerate(genome):  # the first move whose edit (0.01 further in y) still replays in gsr_cad
        if op.name != "move_point":
            continue
        new = dataclasses.replace(op, delta=(op.delta[0], op.delta[1] + 0.01))
        edited = dataclasses.replace(result, genome=(*genome[:k], new, *genome[k + 1:]))
        try:
            want = curve_spline(edited)
        except GsrError:
            continue
        break
    else:
        pytest.fail("no move op to edit")
    assert any(o.name == "corner" for o in genome[k + 1:])  # the corners come after the edited op
    (macro,) = FreecadMacroExporter().export(result, tmp_path, "curve")
    before, after = _edit(macro, tmp_path, k + 1, "Delta", [new.delta[0], new.delta[1], 0.0])
    poles, values, mults = want.periodic_forms()[0]
    assert before["periodic"] and after["periodic"]
    np.testing.assert_allclose(after["poles"], poles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(after["knots"], values, rtol=0, atol=1e-12)
    assert after["mults"] == mults.tolist() == before["mults"]
    assert after["corners"][-1] == list(edited.states[-1].corners)
    assert not np.allclose(after["poles"], before["poles"])


@pytest.mark.freecad
def test_editing_a_surface_op_in_freecad_recomputes_the_later_ops_and_the_limit_mesh(tmp_path):
    if hosts.find_host("freecad") is None:
        pytest.skip("FreeCAD (freecadcmd) is not installed")
    import dataclasses

    from test_export_surface_hosts import OPS, surface_result

    from gsr_cad.exporters.model import surface_model
    from gsr_cad.geometry.subdivision import limit_mesh
    from gsr_cad.geometry.polymesh import PolyMesh

    result = surface_result()
    assert OPS[0].name == "extrude" and {op.name for op in OPS} == {"extrude", "inset", "edge_loop", "translate_vertex",
                                                                    "bevel", "translate_face", "scale"}
    (macro,) = FreecadMacroExporter().export(result, tmp_path, "surface")
    before, after = _edit(macro, tmp_path, 1, "Distance", 0.5)
    ours = surface_model(result)
    for got, state in zip(before["steps"], ours.states):  # the macro's own replay is gsr_cad's, every op kind
        np.testing.assert_allclose(got, state.vertices, rtol=0, atol=1e-12)
    scale = float(np.abs(ours.limit.vertices).max())
    np.testing.assert_allclose(before["limit"], ours.limit.vertices, rtol=0, atol=1e-6 * scale)  # float32 mesh
    # the edit: gsr_cad's replay of the genome with the extrusion at 0.5 is what FreeCAD recomputed
    edited = dataclasses.replace(result, genome=(dataclasses.replace(OPS[0], distance=0.5), *OPS[1:]))
    assert json.loads(after["ops"][1]) == {"op": "extrude", "face": 5, "distance": 0.5}
    assert after["ops"][2:] == before["ops"][2:]
    for got, state in zip(after["steps"], edited.states):
        np.testing.assert_allclose(got, state.vertices, rtol=0, atol=1e-12)
    assert not np.allclose(after["steps"][-1], before["steps"][-1])
    want = limit_mesh(PolyMesh.from_faces(edited.control_mesh.vertices, edited.control_mesh.faces), 2)
    np.testing.assert_allclose(after["limit"], want.vertices, rtol=0, atol=1e-6 * scale)
    assert np.abs(np.array(after["limit"]) - np.array(before["limit"])).max() > 1e-3
