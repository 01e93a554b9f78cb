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
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from gsr_cad.atomic import write_text
from gsr_cad.errors import ExportError
from gsr_cad.geometry.polymesh import PolyMesh

from . import hosts
from .base import (EXACT_TOL, SAMPLE_TOL, Check, CurveSpline, Exporter, HistoryStep, curve_checks, curve_history,
                   curve_spline, expect_equal, failed, measured, num, patch_literals, point_deviation, scratch_dir,
                   skipped, surface_patches)
from .blender import SurfaceModel, same_mesh, surface_model, triangle_faces

SAMPLES_PER_SPAN = 16

# The end of every generated macro: run build(), print a JSON summary, exit 1 on failure (freecadcmd exits 0
# on an uncaught exception) but let the GUI show the traceback.
_MACRO_TAIL = '''

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
''' + _MACRO_TAIL

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
    return _read_back(_curve_reader(params), source, timeout)


def _curve_reader(params: np.ndarray) -> str:
    return _READER.format(dump=_CURVE_DUMP, params=[float(u) for u in params])


def _read_back(script: str, source: Path, timeout: float) -> dict[str, Any]:
    """Run a reader ``script`` (arguments: ``source`` and the JSON file it writes) with ``freecadcmd``."""
    with scratch_dir() as tmp:
        reader, out = tmp / "read_back.py", tmp / "read.json"
        write_text(reader, script)
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
    kinds = ("curve", "surface")
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
        if reason := hosts.missing("freecad"):
            return [skipped(path, self.host, "run macro", reason)]
        spline = curve_spline(result)
        try:
            history = curve_history(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        params = spline.params(SAMPLES_PER_SPAN)
        checks, data = self._replay(path, len(history), _curve_reader(params), timeout=120)
        return checks if data is None else checks + self._compare(path, data, history, spline, params)

    def _replay(self, path: Path, n_steps: int, reader: str, timeout: float) -> tuple[list[Check], dict | None]:
        """Run the macro to save a document and reopen that with the ``reader`` script: the checks so far
        and what the reader saw (None when a step failed)."""
        with scratch_dir() as tmp:
            fcstd = tmp / "replayed.FCStd"
            try:
                proc = hosts.run_freecad(path, [fcstd], timeout=timeout)
            except ExportError as exc:
                return [failed(path, self.host, "run macro", str(exc))], None
            checks = [self._summary_check(path, proc.stdout, n_steps)]
            if not fcstd.is_file():
                return checks + [failed(path, self.host, "saved document", "the macro saved no .FCStd")], None
            try:
                return checks, _read_back(reader, fcstd, timeout)
            except ExportError as exc:
                return checks + [failed(path, self.host, "reopen document", str(exc))], None

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

    def export_surface(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        model = surface_model(result)
        patch_set = surface_patches(result)
        filename = self.filename(stem)
        steps = ",\n".join(
            f"    ({label!r}, {json.dumps(op) if op is not None else ''!r}, [{_rows3(state.vertices)}], "
            f"{[list(f) for f in state.faces]!r})"
            for label, op, state in zip(model.labels, model.ops, model.states))
        sew_tol = max(2.0 * patch_set.max_deviation, 1e-7 * model.diagonal)
        text = _SURFACE_MACRO.format(
            title=f"{filename}: a gsr_cad Catmull-Clark surface with {len(result.genome)} modelling ops",
            n_patches=len(patch_set.patches), patch_dev=patch_set.max_deviation, levels=model.levels,
            filename=filename, doc_name=_doc_name(stem), sew_tol=float(sew_tol), steps=steps,
            limit_points=_rows3(model.limit.vertices),
            limit_triangles=", ".join(f"({a}, {b}, {c})" for a, b, c in triangle_faces(model.limit)),
            patches="\n".join(_patch_text(p) for p in patch_set.patches))
        return [write_text(out_dir / filename, text)]

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        host = self.host
        if reason := hosts.missing("freecad"):
            return [skipped(path, host, "run macro", reason)]
        try:
            model = surface_model(result)
            patch_set = surface_patches(result)
        except ExportError as exc:
            return [failed(path, host, "history", str(exc))]
        checks, data = self._replay(path, len(model.states), _SURFACE_READER.format(grid=list(PATCH_GRID)),
                                    timeout=300)
        if data is None:
            return checks
        return (checks + _check_history(path, host, data["steps"], model)
                + _check_surface(path, host, data["surface"], patch_set, model)
                + _check_mesh(path, host, data["mesh"], model))


# --- Surfaces ---------------------------------------------------------------------------------------------

_SURFACE_MACRO = '''"""{title}

Rebuilt by gsr_cad from its modelling history. The group "History" holds one object per step, named after
it (the template, then the control mesh after each op, as a compound of its face polygons; all hidden but
the last). "LimitSurface" is the Catmull-Clark limit surface built by FreeCAD's Part module from {n_patches}
B-spline patches (the same patches as gsr_cad's STEP export; fitted within {patch_dev:.3g} of the exact limit
surface, exact on regular faces), sewn into a shell and, when closed, a solid. "LimitMesh" is the level-{levels}
limit mesh (Mesh module).

Run: freecadcmd {filename}          (GSR_FCSTD=/path/to/file.FCStd to save the document)
 or: FreeCAD > Macro > Macros... > Execute, or build("/path/to/file.FCStd") from FreeCAD's Python console.
"""
import json
import os
import sys

import FreeCAD as App
import Mesh
import Part

DOC_NAME = {doc_name!r}
SEW_TOLERANCE = {sew_tol!r}
# (label, op as JSON, control-mesh vertices, faces) after each op
STEPS = [
{steps}
]
LIMIT_POINTS = [{limit_points}]
LIMIT_TRIANGLES = [{limit_triangles}]
# (poles[u][v] as (x, y, z), u knots, u multiplicities, v knots, v multiplicities, u degree, v degree)
PATCHES = [
{patches}
]


def cage_shape(vertices, faces):
    """The control mesh as a compound of closed face polygons."""
    pts = [App.Vector(*p) for p in vertices]
    return Part.Compound([Part.makePolygon([pts[i] for i in face] + [pts[face[0]]]) for face in faces])


def limit_surface():
    """The B-spline patches sewn into a shell (a solid when the shell is closed)."""
    faces = []
    for poles, uknots, umults, vknots, vmults, udegree, vdegree in PATCHES:
        surface = Part.BSplineSurface()
        surface.buildFromPolesMultsKnots([[App.Vector(*p) for p in row] for row in poles], umults, vmults,
                                         uknots, vknots, False, False, udegree, vdegree)
        faces.append(surface.toShape())
    sewn = Part.Compound(faces)
    sewn.sewShape(SEW_TOLERANCE)
    shell = Part.Shell(sewn.Faces)
    if shell.isClosed():
        solid = Part.Solid(shell)
        if solid.Volume < 0:
            solid.reverse()
        return solid
    return shell


def build(fcstd_path=None):
    """Make the document (history, limit surface, limit mesh); save it to fcstd_path when one is given."""
    doc = App.newDocument(DOC_NAME)
    history = doc.addObject("App::DocumentObjectGroup", "History")
    steps = []
    for number, (label, op, vertices, faces) in enumerate(STEPS):
        step = doc.addObject("Part::Feature", "Step%03d" % number)
        step.Label = label
        step.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        step.Op = op
        step.Shape = cage_shape(vertices, faces)
        history.addObject(step)
        steps.append(step)
    surface = doc.addObject("Part::Feature", "LimitSurface")
    surface.Label = "limit surface (%d B-spline patches)" % len(PATCHES)
    surface.Shape = limit_surface()
    mesh = doc.addObject("Mesh::Feature", "LimitMesh")
    mesh.Label = "limit mesh (%d triangles)" % len(LIMIT_TRIANGLES)
    mesh.Mesh = Mesh.Mesh(([App.Vector(*p) for p in LIMIT_POINTS], LIMIT_TRIANGLES))
    doc.recompute()
    for step in steps[:-1]:
        step.Visibility = False
    mesh.Visibility = False
    if App.GuiUp:
        import FreeCADGui

        FreeCADGui.SendMsgToActiveView("ViewFit")
    if fcstd_path:
        doc.saveAs(str(fcstd_path))
    return doc


def summary(doc):
    """What was built, as a JSON-ready dict."""
    shape = doc.getObject("LimitSurface").Shape
    return {{"document": doc.Name, "file": doc.FileName or None, "steps": len(STEPS),
            "labels": [label for label, _, _, _ in STEPS], "patches": len(PATCHES), "shape": shape.ShapeType,
            "valid": shape.isValid(), "volume": shape.Volume if shape.ShapeType == "Solid" else None,
            "area": shape.Area}}
''' + _MACRO_TAIL

_SURFACE_READER = '''import json
import os
import sys

import FreeCAD as App

GRID = {grid}
try:
    source, out = os.environ["GSR_ARGS"].split(os.pathsep)[:2]
    doc = App.openDocument(source)
    history = doc.getObject("History")
    steps = [{{"label": o.Label, "visible": bool(o.Visibility), "op": getattr(o, "Op", None),
               "wires": [[[v.X, v.Y, v.Z] for v in w.OrderedVertexes] for w in o.Shape.Wires]}}
             for o in (history.Group if history else [])]
    data = {{"steps": steps, "surface": None, "mesh": None}}
    feature = doc.getObject("LimitSurface")
    if feature is not None:
        shape = feature.Shape
        faces = []
        for face in shape.Faces:
            s = face.Surface
            if s.TypeId != "Part::GeomBSplineSurface":
                faces.append({{"type": s.TypeId}})
                continue
            faces.append({{"type": s.TypeId, "degrees": [s.UDegree, s.VDegree],
                          "rational": bool(s.isURational() or s.isVRational()),
                          "poles": [[[p.x, p.y, p.z] for p in row] for row in s.getPoles()],
                          "uknots": s.getUKnots(), "umults": s.getUMultiplicities(),
                          "vknots": s.getVKnots(), "vmults": s.getVMultiplicities(),
                          "range": list(face.ParameterRange),
                          "samples": [[[p.x, p.y, p.z] for p in (s.value(u, v) for v in GRID)] for u in GRID]}})
        data["surface"] = {{"type": shape.ShapeType, "valid": shape.isValid(), "closed": shape.isClosed(),
                           "shells": len(shape.Shells), "volume": shape.Volume, "faces": faces}}
    mesh = doc.getObject("LimitMesh")
    if mesh is not None:
        points, facets = mesh.Mesh.Topology
        data["mesh"] = {{"points": [[p.x, p.y, p.z] for p in points], "facets": [list(f) for f in facets],
                        "visible": bool(mesh.Visibility)}}
    with open(out, "w") as fh:
        json.dump(data, fh)
except Exception as exc:
    print("error: %s: %s" % (type(exc).__name__, exc), file=sys.stderr)
    raise SystemExit(1)
'''

PATCH_GRID = (0.0, 0.25, 0.5, 0.75, 1.0)
MESH_TOL = 1e-6
"""FreeCAD's Mesh module stores single precision: the limit mesh comes back within this much of the diagonal."""


def _rows3(points: np.ndarray) -> str:
    return ", ".join(f"({num(x)}, {num(y)}, {num(z)})" for x, y, z in points)


def _patch_text(patch: Any) -> str:
    return f"    ({', '.join(patch_literals(patch))}, {patch.degree_u}, {patch.degree_v}),"


def _check_surface(path: Path, host: str, data: dict | None, patch_set: Any, model: SurfaceModel) -> list[Check]:
    if not data:
        return [failed(path, host, "limit surface", "no object 'LimitSurface'")]
    diag = model.diagonal
    exact = EXACT_TOL * max(diag, float(np.abs(model.limit.vertices).max()))
    ours = patch_set.patches
    kind = "Solid" if patch_set.closed else "Shell"
    checks = [
        expect_equal(path, host, f"limit surface: valid {'closed solid' if patch_set.closed else 'shell'}",
                     (data["type"], data["valid"], data["shells"]), (kind, True, 1)),
        expect_equal(path, host, "limit surface: one B-spline face per patch",
                     [f["type"] for f in data["faces"]], ["Part::GeomBSplineSurface"] * len(ours)),
    ]
    if patch_set.closed:
        checks.append(expect_equal(path, host, "limit surface: volume positive", data["volume"] > 0, True))
    faces = [f for f in data["faces"] if "poles" in f]
    if len(faces) != len(ours):
        return checks
    grid = np.asarray(PATCH_GRID)
    want = np.array([p.evaluate(grid, grid) for p in ours])
    got = np.array([f["samples"] for f in faces], dtype=float)
    # sewing may reorder faces: match them by their centre samples
    centre = len(grid) // 2
    _, order = cKDTree(got[:, centre, centre]).query(want[:, centre, centre])
    if len(np.unique(order)) != len(ours):
        return checks + [failed(path, host, "limit surface: patches", "the faces do not match our patches one to one")]
    matched = [faces[i] for i in order]
    pole_dev, knot_dev, structure = 0.0, 0.0, []
    for f, p in zip(matched, ours):
        structure.append((tuple(f["degrees"]), f["rational"]) == ((p.degree_u, p.degree_v), False))
        pole_dev = max(pole_dev, point_deviation(np.asarray(f["poles"], dtype=float), p.poles))
        knot_dev = max(knot_dev, point_deviation(np.repeat(f["uknots"], f["umults"]), p.knots_u),
                       point_deviation(np.repeat(f["vknots"], f["vmults"]), p.knots_v),
                       point_deviation(np.asarray(f["range"], dtype=float), np.array([0.0, 1.0, 0.0, 1.0])))
    return checks + [
        expect_equal(path, host, "limit surface: degrees, non-rational", all(structure), True),
        measured(path, host, "limit surface: poles", pole_dev, exact, f"{len(ours)} patches; tolerance {exact:.3g}"),
        measured(path, host, "limit surface: knots and parameter ranges", knot_dev, EXACT_TOL),
        measured(path, host, f"limit surface: FreeCAD's {got.shape[1] ** 2} samples per patch",
                 point_deviation(got[order], want), SAMPLE_TOL * diag,
                 f"against our patches (within {patch_set.max_deviation / diag:.2g} of the exact limit surface, "
                 f"relative to the diagonal)"),
    ]


def _check_mesh(path: Path, host: str, data: dict | None, model: SurfaceModel) -> list[Check]:
    if not data:
        return [failed(path, host, "limit mesh", "no object 'LimitMesh'")]
    tri = PolyMesh.from_faces(model.limit.vertices, triangle_faces(model.limit))
    dev, problem = same_mesh(tri, np.asarray(data["points"], dtype=float), data["facets"])
    label = f"limit mesh (level {model.levels})"
    if problem:
        return [failed(path, host, label, problem)]
    return [measured(path, host, label, dev / model.diagonal, MESH_TOL,
                     f"{tri.n_vertices} vertices, {tri.n_faces} triangles, relative to the diagonal")]


def _check_history(path: Path, host: str, steps: list[dict], model: SurfaceModel) -> list[Check]:
    n = len(model.states)
    checks = [
        expect_equal(path, host, "one object per op", len(steps), n),
        expect_equal(path, host, "op labels", [s["label"] for s in steps], list(model.labels)),
        expect_equal(path, host, "op records", [s["op"] for s in steps],
                     [json.dumps(op) if op is not None else "" for op in model.ops]),
        expect_equal(path, host, "only the last step visible", [s["visible"] for s in steps],
                     [i == n - 1 for i in range(n)]),
    ]
    if len(steps) != n:
        return checks
    dev = 0.0
    for s, state in zip(steps, model.states):
        wires = s["wires"]
        if len(wires) != state.n_faces:
            dev = math.inf
            break
        for wire, face in zip(wires, state.faces):
            dev = max(dev, point_deviation(np.asarray(wire, dtype=float), state.vertices[list(face)]))
    scale = max(1.0, float(max(np.abs(st.vertices).max() for st in model.states)))
    checks.append(measured(path, host, "history control meshes", dev, EXACT_TOL * scale,
                           "every face polygon of every step"))
    return checks
