"""FreeCAD macro export: a self-contained ``*.FCMacro`` that rebuilds the modelling history and the curve.

The macro makes one ``Part::Polygon`` per step (the template, then the control polygon after each op,
labelled like ``"03 add point 2 at (0.41, 0.77)"``; all hidden but the last) in a ``History`` group, and
the final curve as an exact ``Part.BSplineCurve`` from poles, knots, multiplicities and degree. It runs in
``freecadcmd`` and from the GUI's macro menu; it saves an ``.FCStd`` when given a path (``build(path)``, the
first entry of ``GSR_ARGS`` as ``hosts.run_freecad`` passes it, or ``GSR_FCSTD``); it prints a JSON summary
on success, and under ``freecadcmd`` turns any error into exit code 1 (FreeCAD itself would exit 0).

Validation runs the macro with ``freecadcmd`` to save a document, opens that document in a second
``freecadcmd`` run, and compares every step's nodes and the curve (poles, knots, FreeCAD's own samples)
with ours.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad.atomic import write_text
from gsr_cad.errors import ExportError

from . import hosts
from .base import (EXACT_TOL, Check, CurveSpline, Exporter, HistoryStep, curve_checks, curve_history, curve_spline,
                   expect_equal, failed, measured, num, point_deviation, scratch_dir, skipped)

SAMPLES_PER_SPAN = 16

_MACRO = '''"""{title}

Rebuilt by gsr_cad from its modelling history: the group "History" holds one Part::Polygon per step (the
template, then the control polygon after each op; all hidden but the last) and "Curve" is the exact
{scheme} curve as a B-spline of degree {degree} from its poles, knots and multiplicities.

Run: freecadcmd {filename}          (GSR_FCSTD=/path/to/file.FCStd to save the document)
 or: FreeCAD > Macro > Macros... > Execute, or build("/path/to/file.FCStd") from FreeCAD's Python console.
"""
import json
import os
import sys

import FreeCAD as App
import Part

DOC_NAME = {doc_name!r}
SCHEME = {scheme!r}
DEGREE = {degree}
# (label, op as JSON, control polygon after the op)
STEPS = [
{steps}
]
POLES = [{poles}]
KNOTS = [{knots}]
MULTS = [{mults}]


def _vectors(points):
    return [App.Vector(x, y, 0.0) for x, y in points]


def build(fcstd_path=None):
    """Make the document (history polygons and curve); save it to fcstd_path when one is given."""
    doc = App.newDocument(DOC_NAME)
    history = doc.addObject("App::DocumentObjectGroup", "History")
    steps = []
    for number, (label, op, points) in enumerate(STEPS):
        step = doc.addObject("Part::Polygon", "Step%03d" % number)
        step.Label = label
        step.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        step.Op = op
        step.Nodes = _vectors(points)
        history.addObject(step)
        steps.append(step)
    spline = Part.BSplineCurve()
    spline.buildFromPolesMultsKnots(_vectors(POLES), MULTS, KNOTS, False, DEGREE)
    curve = doc.addObject("Part::Feature", "Curve")
    curve.Label = "curve (%s, degree %d)" % (SCHEME, DEGREE)
    curve.Shape = spline.toShape()
    doc.recompute()
    for step in steps[:-1]:
        step.Visibility = False
    if App.GuiUp:
        import FreeCADGui

        FreeCADGui.SendMsgToActiveView("ViewFit")
    if fcstd_path:
        doc.saveAs(str(fcstd_path))
    return doc


def summary(doc):
    """What was built, as a JSON-ready dict."""
    curve = doc.getObject("Curve").Shape
    return {{"document": doc.Name, "file": doc.FileName or None, "steps": len(STEPS),
            "labels": [label for label, _, _ in STEPS], "degree": DEGREE, "poles": len(POLES),
            "curve_length": curve.Length}}


def _path_from_environment():
    args = [a for a in os.environ.get("GSR_ARGS", "").split(os.pathsep) if a]
    return args[0] if args else os.environ.get("GSR_FCSTD")


try:
    print("\\n" + json.dumps(summary(build(_path_from_environment()))))
except Exception as exc:
    if App.GuiUp:
        raise
    print("error: %s: %s" % (type(exc).__name__, exc), file=sys.stderr)
    raise SystemExit(1)
'''

_CURVE_DUMP = '''
def dump_curve(edge, params):
    c = edge.Curve
    if c.TypeId != "Part::GeomBSplineCurve":
        return {"type": c.TypeId}
    return {"degree": c.Degree, "rational": bool(c.isRational()),
            "poles": [[p.x, p.y, p.z] for p in c.getPoles()], "knots": c.getKnots(),
            "mults": c.getMultiplicities(), "range": list(edge.ParameterRange),
            "samples": [[p.x, p.y, p.z] for p in (c.value(u) for u in params)]}
'''

_READER = '''import json
import os
import sys

import FreeCAD as App
import Part
{dump}
try:
    source, out = os.environ["GSR_ARGS"].split(os.pathsep)[:2]
    params = {params}
    if source.lower().endswith(".fcstd"):
        doc = App.openDocument(source)
        history = doc.getObject("History")
        steps = [{{"label": o.Label, "type": o.TypeId, "visible": bool(o.Visibility),
                   "nodes": [[v.x, v.y, v.z] for v in getattr(o, "Nodes", [])]}}
                 for o in (history.Group if history else [])]
        feature = doc.getObject("Curve")
        edges = feature.Shape.Edges if feature is not None else []
        data = {{"steps": steps, "curve": dump_curve(edges[0], params) if edges else None}}
    else:
        data = {{"curves": [dump_curve(e, params) for e in Part.read(source).Edges]}}
    with open(out, "w") as fh:
        json.dump(data, fh)
except Exception as exc:
    print("error: %s: %s" % (type(exc).__name__, exc), file=sys.stderr)
    raise SystemExit(1)
'''


def freecad_read(source: Path, params: np.ndarray, timeout: float = 120) -> dict[str, Any]:
    """Open an ``.FCStd`` (history steps and the "Curve" object) or read a STEP file (every edge) with
    ``freecadcmd`` and return what FreeCAD sees, B-splines evaluated by FreeCAD at ``params``.

    Raises ExportError when FreeCAD is missing or fails on the file.
    """
    with scratch_dir() as tmp:
        reader, out = tmp / "read_back.py", tmp / "read.json"
        write_text(reader, _READER.format(dump=_CURVE_DUMP, params=[float(u) for u in params]))
        hosts.run_freecad(reader, [source, out], timeout=timeout)
        try:
            return json.loads(out.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ExportError(f"FreeCAD's read-back gave no result: {exc}") from None


def _doc_name(stem: str) -> str:
    name = re.sub(r"\W", "_", stem) or "curve"
    return name if not name[0].isdigit() else "c" + name


def _pairs(points: np.ndarray) -> str:
    return ", ".join(f"({num(x)}, {num(y)})" for x, y in points)


class FreecadMacroExporter(Exporter):
    """``*.FCMacro``: self-contained FreeCAD macro with the op history and the exact B-spline."""

    name = "fcmacro"
    kinds = ("curve",)
    suffixes = (".FCMacro",)
    host = "freecad"

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        spline = curve_spline(result)
        history = curve_history(result)
        steps = ",\n".join(f"    ({h.label!r}, {json.dumps(h.op)!r}, [{_pairs(h.points)}])" for h in history)
        filename = self.filename(stem)
        scheme = str(result.config.get("scheme", "bspline"))
        text = _MACRO.format(
            title=f"{filename}: a gsr_cad {scheme} curve with {len(result.genome)} modelling ops",
            scheme=scheme, degree=spline.degree, filename=filename, doc_name=_doc_name(stem), steps=steps,
            poles=_pairs(spline.poles), knots=", ".join(num(k) for k in spline.breakpoints),
            mults=", ".join(str(int(m)) for m in spline.multiplicities))
        return [write_text(out_dir / filename, text)]

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if hosts.find_host("freecad") is None:
            return [skipped(path, self.host, "run macro", "FreeCAD is not installed (apt-get install freecad)")]
        spline = curve_spline(result)
        try:
            history = curve_history(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        params = spline.params(SAMPLES_PER_SPAN)
        with scratch_dir() as tmp:
            fcstd = tmp / "replayed.FCStd"
            try:
                proc = hosts.run_freecad(path, [fcstd], timeout=120)
            except ExportError as exc:
                return [failed(path, self.host, "run macro", str(exc))]
            checks = [self._summary_check(path, proc.stdout, len(history))]
            if not fcstd.is_file():
                return checks + [failed(path, self.host, "saved document", "the macro saved no .FCStd")]
            try:
                data = freecad_read(fcstd, params)
            except ExportError as exc:
                return checks + [failed(path, self.host, "reopen document", str(exc))]
        return checks + self._compare(path, data, history, spline, params)

    def _summary_check(self, path: Path, stdout: str, n_steps: int) -> Check:
        for line in reversed(stdout.splitlines()):
            if line.startswith('{"document"'):
                try:
                    steps = json.loads(line).get("steps")
                except ValueError:
                    break
                return expect_equal(path, self.host, "JSON summary", steps, n_steps)
        return failed(path, self.host, "JSON summary", "the macro printed no JSON summary")

    def _compare(self, path: Path, data: dict, history: list[HistoryStep], spline: CurveSpline,
                 params: np.ndarray) -> list[Check]:
        host, exact = self.host, EXACT_TOL * spline.scale
        steps = data.get("steps") or []
        checks = [
            expect_equal(path, host, "one object per op", len(steps), len(history)),
            expect_equal(path, host, "op labels", [s["label"] for s in steps], [h.label for h in history]),
            expect_equal(path, host, "only the last step visible", [s["visible"] for s in steps],
                         [i == len(history) - 1 for i in range(len(history))]),
        ]
        if len(steps) == len(history):
            dev = max(point_deviation(np.array(s["nodes"]),
                                      np.column_stack([h.points, np.zeros(len(h.points))]))
                      for s, h in zip(steps, history))
            checks.append(measured(path, host, "history polygons", dev, exact))
        curve = data.get("curve")
        if not curve or "poles" not in curve:
            return checks + [failed(path, host, "curve", f"no B-spline object 'Curve' ({curve})")]
        return checks + curve_checks(path, host, spline, params, degree=curve["degree"], rational=curve["rational"],
                                     poles=curve["poles"], knots=np.repeat(curve["knots"], curve["mults"]),
                                     samples=curve["samples"], param_range=curve["range"])
