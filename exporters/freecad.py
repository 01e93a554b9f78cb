"""FreeCAD macro export (format "fcmacro"): a self-contained ``*.FCMacro`` rebuilding the modelling history.

The macro is :mod:`~gsr_cad.exporters.hostside` ``freecad_macro.py`` with its
``DATA`` line filled by the literal encoder. Curves: one FeaturePython object per step (the template, then
the control polygon after each op, labelled like ``"03 add point 2 at (0.41, 0.77)"``; all hidden but the
last) in a ``History`` group, a parametric chain whose op parameters can be edited in FreeCAD (a recompute
replays the later ops and rebuilds the curve), and the curve as an exact B-spline on the last step's poles
with clamped uniform knots. Surfaces: the same parametric chain on the
connectivity gsr_cad found (each op's numbers editable; the macro carries its own copy of the op geometry
and the limit stencil, so a recompute rebuilds the later control meshes and the limit mesh), plus the limit
surface as the exported, sewn B-spline patches. The macro runs in ``freecadcmd`` and from the GUI's macro
menu; it saves an ``.FCStd`` when given a path (``build(path)``, the first entry of ``GSR_ARGS`` as
``hosts.run_freecad`` passes it, or ``GSR_FCSTD``); it prints a JSON summary on success, and under
``freecadcmd`` turns any error into exit code 1 (FreeCAD itself would exit 0).

Validation runs the macro with ``freecadcmd`` to save a document, opens that document in a second
``freecadcmd`` run (:func:`~gsr_cad.exporters.checks.freecad_read`), and compares every step and the curve
or surface with ours.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from gsr_cad.errors import ExportError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.ops import mesh_kernel
from gsr_cad.ops.mesh_conn import mesh_view

from . import hosts
from .base import EXACT_TOL, SAMPLE_TOL, Check, Exporter, curve_checks, expect_equal, failed, measured, \
    point_deviation, save_host_document, scratch_dir, skipped
from .checks import PATCH_GRID, freecad_read
from .encode import fill_python
from .model import CurveModel, CurveSpline, HistoryStep, SurfaceModel, curve_model, patch_data, require_ops, \
    same_mesh, surface_model, triangle_faces, xyz

SAMPLES_PER_SPAN = 16
CURVE_OPS = ("add_point", "move_point", "corner")
"""The curve ops the macro's own replay knows (hostside/freecad_macro.py, ``OPS``)."""
SURFACE_OPS = ("translate_vertex", "translate_face", "scale", "extrude", "inset", "edge_loop", "bevel", "crease",
               "crease_rim", "hole", "extrude_region", "inset_region")
"""The surface ops the macro's own replay knows (hostside/freecad_macro.py, ``PARAMETERS``)."""
HISTORY_TIMEOUT = 600
"""Seconds each freecadcmd run of a surface macro's check may take (a refined history: hundreds of objects)."""
MESH_TOL = 1e-6
"""FreeCAD's Mesh module stores single precision: the limit mesh comes back within this much of the diagonal."""


def _rows(matrix: Any) -> list[list[list[float]]]:
    """A sparse matrix as ``[[column indices], [weights]]`` per row (the limit stencil of the control mesh)."""
    m = matrix.tocsr()
    return [[m.indices[m.indptr[i]:m.indptr[i + 1]].tolist(), m.data[m.indptr[i]:m.indptr[i + 1]].tolist()]
            for i in range(m.shape[0])]


def _recipe(op: Any, state: PolyMesh) -> dict[str, Any]:
    """How the op places its vertices on ``state``, for the macro's own replay of the history: the element
    indices it uses, resolved once (the connectivity is fixed; the op's numbers stay editable)."""
    conn = mesh_view(state).conn
    if op.name in ("translate_face", "extrude", "inset"):
        return {"cycle": list(state.faces[op.face])}
    if op.name in ("extrude_region", "inset_region"):
        rim, rim_vertices, _ = mesh_kernel.region_rim(mesh_view(state), op.faces, op.name)
        cycles = [list(state.faces[f]) for f in op.faces]
        if op.name == "extrude_region":
            on_rim = set(rim_vertices)
            inner = list(dict.fromkeys(c for f in op.faces for c in state.faces[f] if c not in on_rim))
            return {"cycles": cycles, "inner": inner, "rim": rim_vertices}
        after, before = dict(rim), {v: u for u, v in rim}
        return {"corners": [[before[v], v, after[v]] for v in rim_vertices],
                "around": [[c for c in cycles if v in c] for v in rim_vertices]}
    if op.name == "edge_loop":
        return {"ring": [list(conn.edges[e]) for e in mesh_kernel.edge_ring(conn, op.edge)[0]]}
    if op.name == "bevel":
        a, b = conn.edges[op.edge]
        f1, f2 = conn.edge_faces(op.edge)
        ends = []
        for v, w, start in ((a, b, f1), (b, a, f2)):
            fan = mesh_kernel._fan(conn, v, start, "bevel")
            ends.append([[fan[j][1], j in (0, len(fan) - 2)] for j in range(len(fan) - 1)])
        return {"a": a, "b": b, "ends": ends}
    return {}


def _doc_name(stem: str) -> str:
    name = re.sub(r"\W", "_", stem, flags=re.ASCII) or "curve"
    return name if not name[0].isdigit() else "c" + name


class FreecadMacroExporter(Exporter):
    """``*.FCMacro``: self-contained FreeCAD macro with the op history and the exact B-spline."""

    name = "fcmacro"
    kinds = ("curve", "surface")
    suffixes = (".FCMacro",)
    host = "freecad"

    def render_curve(self, result: Any, stem: str) -> dict[str, str]:
        model = curve_model(result)
        require_ops(result.genome, CURVE_OPS, "FreeCAD macro")
        spline = model.spline
        if model.history[0].corners:
            raise ExportError("the FreeCAD macro replays templates without corners")
        text = fill_python("freecad_macro.py", {
            "kind": "curve", "doc_name": _doc_name(stem), "scheme": result.scheme, "degree": int(spline.degree),
            "dimension": spline.dim, "closed": spline.closed,
            "steps": [{"label": h.label, "op": h.op, "points": h.points.tolist()} for h in model.history]})
        return {self.filename(stem): text}

    document_suffix = ".FCStd"

    def save_document(self, result: Any, path: Path) -> Path:
        """Run the macro in ``freecadcmd`` and save its document as ``path`` (an ``.FCStd``)."""
        (name, text), = self.render(result, Path(path).stem).items()
        return save_host_document(name, text, path, lambda script, doc: hosts.run_freecad(script, [doc], timeout=600))

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("freecad"):
            return [skipped(path, self.host, "run macro", reason)]
        try:
            model = curve_model(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        params = model.spline.params(SAMPLES_PER_SPAN)
        checks, data = self._replay(path, len(model.history), params, timeout=120)
        return checks if data is None else checks + self._compare(path, data, model, params)

    def _replay(self, path: Path, n_steps: int, params: Any, timeout: float) -> tuple[list[Check], dict | None]:
        """Run the macro to save a document and reopen that with FreeCAD: the checks so far and what FreeCAD
        saw (None when a step failed)."""
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
                return checks, freecad_read(fcstd, params, PATCH_GRID, timeout)
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

    def _compare(self, path: Path, data: dict, model: CurveModel, params: np.ndarray) -> list[Check]:
        history: tuple[HistoryStep, ...] = model.history
        spline: CurveSpline = model.spline
        host, exact = self.host, EXACT_TOL * spline.scale
        steps = data.get("steps") or []
        checks = [
            expect_equal(path, host, "one object per op", len(steps), len(history)),
            expect_equal(path, host, "op labels", [s["label"] for s in steps], [h.label for h in history]),
            expect_equal(path, host, "only the last step visible", [s["visible"] for s in steps],
                         [i == len(history) - 1 for i in range(len(history))]),
        ]
        if len(steps) == len(history):
            dev = max(point_deviation(np.array(s["nodes"]), xyz(h.points)) for s, h in zip(steps, history))
            checks.append(measured(path, host, "history polygons", dev, exact))
            checks.append(expect_equal(path, host, "history corners", [s.get("corners") for s in steps],
                                       [list(h.corners) for h in history]))
        curve = data.get("curve")
        if not curve or "poles" not in curve:
            return checks + [failed(path, host, "curve", f"no B-spline object 'Curve' ({curve})")]
        return checks + curve_checks(path, host, spline, params, degree=curve["degree"], rational=curve["rational"],
                                     poles=curve["poles"], knots=np.repeat(curve["knots"], curve["mults"]),
                                     samples=curve["samples"], param_range=curve["range"],
                                     periodic=curve["periodic"], closed=curve["closed"])

    def render_surface(self, result: Any, stem: str) -> dict[str, str]:
        model = surface_model(result)
        require_ops(model.genome, SURFACE_OPS, "FreeCAD macro")
        patch_set = model.patches
        sew_tol = max(2.0 * patch_set.max_deviation, 1e-7 * model.diagonal)
        topologies: dict[tuple, int] = {}

        def topology(state: PolyMesh) -> int:
            return topologies.setdefault(tuple(tuple(int(v) for v in f) for f in state.faces), len(topologies))

        steps: list[dict[str, Any]] = []
        for first, last in surface_steps(model):
            state = model.states[last]
            if first == 0:
                steps.append({"label": model.labels[0], "op": None, "vertices": state.vertices.tolist(),
                              "topology": topology(state)})
            elif first == last:
                steps.append({"label": model.labels[first], "op": model.ops[first], "topology": topology(state),
                              "recipe": _recipe(model.genome[first - 1], model.states[first - 1])})
            else:
                steps.append({"label": _run_label(model.labels[first], model.labels[last], last - first + 1),
                              "labels": list(model.labels[first:last + 1]), "moves": list(model.ops[first:last + 1]),
                              "topology": topology(state)})
        text = fill_python("freecad_macro.py", {
            "kind": "surface", "doc_name": _doc_name(stem), "levels": int(model.levels),
            "sew_tolerance": float(sew_tol),
            "patch_deviation": float(patch_set.max_deviation),
            "topologies": [[list(f) for f in faces] for faces in topologies],
            "steps": steps,
            "limit_rows": _rows(get_catmull_clark(model.control, model.levels, model.boundary).limit_matrix),
            "limit_points": model.limit.vertices.tolist(),
            "limit_triangles": [list(t) for t in triangle_faces(model.limit)],
            "patches": [patch_data(p) for p in patch_set.patches]})
        return {self.filename(stem): text}

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        host = self.host
        if reason := hosts.missing("freecad"):
            return [skipped(path, host, "run macro", reason)]
        try:
            model = surface_model(result)
            patch_set = model.patches
        except ExportError as exc:
            return [failed(path, host, "history", str(exc))]
        checks, data = self._replay(path, len(model.states), (), timeout=HISTORY_TIMEOUT)
        if data is None:
            return checks
        return (checks + _check_history(path, host, data["steps"], model)
                + _check_surface(path, host, data["surface"], patch_set, model)
                + _check_mesh(path, host, data["mesh"], model))


def surface_steps(model: SurfaceModel) -> list[tuple[int, int]]:
    """The macro's history objects as ``(first, last)`` indices into ``model.states``: the template, each
    structural op, and each run of two or more consecutive vertex moves as one object (a refined result holds
    thousands of moves; one object per move made the macro's data and FreeCAD's document grow with moves times
    vertices: a 1,310-vertex cage with 9,300 moves ran the exporter out of 23 GB of memory)."""
    out = [(0, 0)]
    for i in range(1, len(model.states)):
        first, last = out[-1]
        if first > 0 and model.ops[i]["op"] == model.ops[first]["op"] == "translate_vertex":
            out[-1] = (first, i)
        else:
            out.append((i, i))
    return out


def _run_label(first: str, last: str, count: int) -> str:
    """A run of vertex moves' label: its first and last numbers (``"05-12 8 vertex moves"``)."""
    return f"{first.split(' ', 1)[0]}-{last.split(' ', 1)[0]} {count} vertex moves"


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
    """The history objects FreeCAD saved against ours: one per op or run of moves (:func:`surface_steps`), every
    op's label and record (a run's in its "Labels" and "Op" lists), the visibility, and each object's face
    polygons against the control mesh after its last op."""
    spans = surface_steps(model)
    n = len(spans)
    labels, records = [], []
    for s in steps:
        labels += s.get("labels") or [s["label"]]
        op = s["op"] or ""
        records += [json.dumps(r) for r in json.loads(op)] if op.startswith("[") else [op]
    checks = [
        expect_equal(path, host, "one object per op or run of moves", len(steps), n),
        expect_equal(path, host, "op labels", labels, list(model.labels)),
        expect_equal(path, host, "op records", records,
                     [json.dumps(op) if op is not None else "" for op in model.ops]),
        expect_equal(path, host, "only the last step visible", [s["visible"] for s in steps],
                     [i == n - 1 for i in range(n)]),
    ]
    if len(steps) != n:
        return checks
    dev = 0.0
    for s, (_, last) in zip(steps, spans):
        state = model.states[last]
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
