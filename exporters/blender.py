"""Blender replay scripts (format "blender"): the modelling history rebuilt with Blender's own operators.

The script is a copy of :mod:`~gsr_cad.exporters.hostside.blender_mesh` (surfaces: bmesh ops, then a
Subdivision Surface modifier) or :mod:`~gsr_cad.exporters.hostside.blender_curve` (curves: the control
polygon after every op as hidden objects, then the NURBS curve) with its ``DATA`` line filled by the
literal encoder; it is self-contained (Blender 3.4, no gsr_cad needed). Run from Blender's Text Editor it
builds the objects; run headless as ``blender -b --factory-startup --python script.py -- --control OUT.obj
--evaluated OUT2.obj`` (surfaces) or ``-- --json OUT.json`` (curves) it also writes what it built, and
``--blend FILE`` saves the Blender file.

Blender keeps coordinates in single precision, so a replay matches gsr_cad to about ``1e-7`` of the
model's size; extruding a thin face far amplifies that.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad import genome as genome_mod
from gsr_cad.atomic import write_text
from gsr_cad.errors import ConfigError, ExportError, OpError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import CatmullClark
from gsr_cad.ops.base import Op
from gsr_cad.ops.mesh import ALL_OPS_BY_LETTER
from gsr_cad.ops.mesh_kernel import bbox_centre

from . import hosts
from .base import (SAMPLE_TOL, Check, Exporter, expect_equal, failed, measured, point_deviation,
                   save_host_document, scratch_dir, skipped)
from .encode import fill_python
from .model import (CurveModel, CurveSpline, curve_model, read_obj, require_ops, same_mesh, surface_labels,
                    surface_model, xyz)

MAX_LEVELS = 6
_BOUNDARY = {"all": "ALL", "corners": "PRESERVE_CORNERS"}
CURVE_RESOLUTION = 12
SURFACE_OPS = ("translate_vertex", "translate_face", "scale", "extrude", "inset", "edge_loop", "bevel", "crease",
               "crease_rim", "hole", "extrude_region", "inset_region")
"""The surface ops the Blender mesh script replays."""
BLENDER_NAME_LIMIT = 63  # bytes in an ID name
CONTROL_TOL = 1e-6
"""Control geometry read back from Blender (single precision), relative to the diagonal."""
EVALUATED_TOL = 1e-5
"""Blender's Subdivision Surface output against our limit mesh, relative to the diagonal."""
CREASE_QUALITY = 10
"""The modifier's quality (OpenSubdiv's patch isolation level, Blender's largest) the script sets on a creased
mesh (Blender's default 3 elsewhere). Its limit points are exact but at infinitely sharp darts, where they are
OpenSubdiv's smooth stencil at this level: ``CatmullClark(..., dart_isolation=CREASE_QUALITY)`` reproduces them."""
DEFAULT_QUALITY = 3


def _blender_name(label: str) -> str:
    return label.encode("utf-8")[:BLENDER_NAME_LIMIT].decode("utf-8", "ignore")


def _title(stem: str) -> str:
    """A Blender object name from a file stem (letters, digits, ' -_.' only)."""
    return "".join(ch if ch.isalnum() or ch in " -_." else "_" for ch in stem) or "gsr"


def _op_params(op: Op, state: PolyMesh) -> dict[str, Any]:
    """The op as the script's helper takes it (its JSON form; a scale also gets the pivot it used)."""
    params = op.to_json()
    if op.name == "scale":
        params["pivot"] = list(bbox_centre(state))
    if op.name == "hole":  # the bridge quads as gsr_cad pairs the rims (Blender's float32 could pick another pairing)
        after = op.apply(state)
        params["quads"] = [list(after.faces[op.face_a]), list(after.faces[op.face_b])] + [
            list(f) for f in after.faces[state.n_faces:]]
    return params


def mesh_script(genome: Sequence[Op], states: Sequence[PolyMesh], levels: int, use_limit_surface: bool,
                name: str, boundary: str = "all") -> str:
    """The surface script text; ``states`` are the template and the mesh after every op of ``genome``."""
    require_ops(genome, SURFACE_OPS, "Blender mesh script")
    template = states[0]
    labels = surface_labels(genome)
    return fill_python("blender_mesh.py", {
        "name": name or "gsr_control_mesh", "levels": int(levels), "use_limit_surface": bool(use_limit_surface),
        "boundary": _BOUNDARY[boundary], "template_label": _blender_name(labels[0]),
        "template_vertices": template.vertices.tolist(), "template_faces": [list(f) for f in template.faces],
        "steps": [{"label": _blender_name(label), "op": _op_params(op, state)}
                  for label, op, state in zip(labels[1:], genome, states)],
        "creases": [[a, b, s] for (a, b), s in states[-1].creases.items()],
        "quality": CREASE_QUALITY if states[-1].creases else DEFAULT_QUALITY,
    })


def write_blender_script(genome: Sequence[Op], template: PolyMesh, path: str | os.PathLike[str], levels: int = 2,
                         use_limit_surface: bool = True, title: str = "", boundary: str = "all") -> Path:
    """Write a Blender 3.4 script that replays ``genome`` on ``template`` and adds a Subdivision Surface
    modifier (``levels`` for viewport and render, ``use_limit_surface`` set explicitly, ``boundary``
    "all" or "corners" as gsr_cad names Blender's boundary smoothing); atomically."""
    if boundary not in _BOUNDARY:
        raise ConfigError(f"boundary must be one of {', '.join(_BOUNDARY)}, got {boundary!r}")
    if isinstance(levels, bool) or not isinstance(levels, int) or not 0 <= levels <= MAX_LEVELS:
        raise ConfigError(f"subdivision levels must be an integer in [0, {MAX_LEVELS}], got {levels!r}")
    if not isinstance(template, PolyMesh):
        raise ExportError(f"no Blender writer for a {type(template).__name__} template")
    if title and not all(ch.isalnum() or ch in " -_." for ch in title):
        raise ConfigError(f"the title may hold letters, digits, spaces, '-', '_' and '.', got {title!r}")
    genome = tuple(genome)
    known = {cls.name for cls in ALL_OPS_BY_LETTER.values()}
    for op in genome:
        if op.name not in known:
            raise ExportError(f"the Blender writer knows only surface ops, got {op.name!r}")
    try:
        states = genome_mod.replay_states(template, genome)
    except OpError as exc:
        raise ExportError(f"the genome does not replay on the template: {exc}") from None
    return write_text(path, mesh_script(genome, states, levels, use_limit_surface, title, boundary))


CURVE_OPS = ("add_point", "move_point", "corner")
"""The curve ops the Blender curve script replays."""


def curve_script(model: CurveModel, name: str) -> str:
    """The curve script text (history replay + the curve as its exact Bezier spline)."""
    history = model.history
    require_ops(model.genome, CURVE_OPS, "Blender curve script")
    if history[0].corners:
        raise ExportError("the Blender curve script replays templates without corners")
    return fill_python("blender_curve.py", {
        "name": name or "gsr_curve", "degree": int(model.spline.degree), "closed": model.spline.closed,
        "resolution": CURVE_RESOLUTION,
        "template": history[0].points.tolist(),
        "steps": [{"label": _blender_name(h.label), "op": h.op} for h in history],
    })


class BlenderExporter(Exporter):
    """``*_blender.py``: a Blender 3.4 script that replays the modelling history with Blender's own tools.

    Validation runs the script in background Blender and compares what it built with our geometry: the
    control mesh (gsr_cad's order, within :data:`CONTROL_TOL` of the diagonal; Blender stores single
    precision) and the modifier's output (within :data:`EVALUATED_TOL`), or the curve's poles, NURBS
    settings, history polygons and Blender's own evaluated points.
    """

    name = "blender"
    kinds = ("curve", "surface")
    suffixes = ("_blender.py",)
    host = "blender"

    def render_surface(self, result: Any, stem: str) -> dict[str, str]:
        model = surface_model(result)
        if model.levels > MAX_LEVELS:
            raise ExportError(f"config levels must be at most {MAX_LEVELS} for Blender")
        text = mesh_script(model.genome, model.states, model.levels, True, _title(stem), model.boundary)
        return {self.filename(stem): text}

    def render_curve(self, result: Any, stem: str) -> dict[str, str]:
        return {self.filename(stem): curve_script(curve_model(result), _title(stem))}

    document_suffix = ".blend"

    def save_document(self, result: Any, path: Path) -> Path:
        """Run the script in background Blender and save the Blender file as ``path`` (a ``.blend``)."""
        (name, text), = self.render(result, Path(path).stem).items()
        return save_host_document(name, text, path,
                                  lambda script, doc: hosts.run_blender(script, ["--blend", doc], timeout=600))

    def _run(self, path: Path, args: Sequence[str]) -> Check | None:
        try:
            hosts.run_blender(path, args, timeout=300)
        except ExportError as exc:
            return failed(path, self.host, "run script", str(exc))
        return None

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("blender"):
            return [skipped(path, self.host, "run script", reason)]
        try:
            model = surface_model(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        with scratch_dir() as tmp:
            control, evaluated = tmp / "control.obj", tmp / "evaluated.obj"
            crash = self._run(path, ["--control", control, "--evaluated", evaluated])
            if crash:
                return [crash]
            try:
                cv, cf = read_obj(control)
                ev, ef = read_obj(evaluated)
            except (OSError, ValueError) as exc:
                return [failed(path, self.host, "read output", f"the script wrote no usable OBJ: {exc}")]
        ours, diag = model.control, model.diagonal
        checks = [expect_equal(path, self.host, "control faces", [tuple(f) for f in cf], ours.faces)]
        checks.append(measured(path, self.host, "control vertices",
                               point_deviation(cv, ours.vertices) / diag, CONTROL_TOL,
                               f"relative to the diagonal; tolerance {CONTROL_TOL:.3g}"))
        expected, darts = model.limit, ""
        if ours.creases:  # Blender's limit at infinitely sharp darts is OpenSubdiv's stencil at the quality level
            cc = CatmullClark(ours, model.levels, model.boundary, dart_isolation=CREASE_QUALITY)
            expected = cc.limit(ours.vertices)
            gap = np.abs(expected.vertices - model.limit.vertices).max() / diag
            if gap > 0:
                darts = f"; darts as OpenSubdiv evaluates them at quality {CREASE_QUALITY}, {gap:.2g} from the exact limit"
        dev, problem = same_mesh(expected, ev, ef)
        label = f"modifier (levels {model.levels}) vs our limit mesh"
        if problem:
            checks.append(failed(path, self.host, label, problem))
        else:
            checks.append(measured(path, self.host, label, dev / diag, EVALUATED_TOL,
                                   f"{model.limit.n_vertices} vertices, relative to the diagonal; "
                                   f"tolerance {EVALUATED_TOL:.3g}{darts}"))
        return checks

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("blender"):
            return [skipped(path, self.host, "run script", reason)]
        try:
            model = curve_model(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        with scratch_dir() as tmp:
            out = tmp / "built.json"
            crash = self._run(path, ["--json", out])
            if crash:
                return [crash]
            try:
                data = json.loads(out.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                return [failed(path, self.host, "read output", f"the script wrote no usable JSON: {exc}")]
        return self._compare_curve(path, data, model)

    def _compare_curve(self, path: Path, data: dict, model: CurveModel) -> list[Check]:
        spline, history = model.spline, model.history
        host, diag = self.host, spline.diagonal
        tol = CONTROL_TOL * max(diag, spline.scale)
        pieces = cubic_pieces(spline)
        closed, m = spline.closed, len(pieces)
        # Bezier points (handle_left, co, handle_right) as the pieces give them; open ends have handles on co
        co = np.concatenate([pieces[:, 0], pieces[-1:, 3]]) if not closed else pieces[:, 0]
        right = np.concatenate([pieces[:, 1], co[-1:]]) if not closed else pieces[:, 1]
        left = np.concatenate([co[:1], pieces[:, 2]]) if not closed else np.roll(pieces[:, 2], 1, axis=0)
        want = np.stack([left, co, right], axis=1)
        got = np.asarray(data["bezier"], dtype=float)
        checks = [
            expect_equal(path, host, "Bezier spline, free handles, cyclic if closed",
                         (data["type"], data["handle_types"], data["cyclic"]), ("BEZIER", ["FREE"], closed)),
            measured(path, host, f"{m} Bezier segments: points and handles",
                     point_deviation(got.reshape(-1, 3), want.reshape(-1, 3)) if got.shape == want.shape else math.inf,
                     tol, f"the exact Bezier pieces of the B-spline; tolerance {tol:.3g} (single precision)"),
        ]
        steps = data.get("history") or []
        checks += [
            expect_equal(path, host, "one object per op", len(steps), len(history)),
            expect_equal(path, host, "op labels", [s["name"] for s in steps],
                         [_blender_name(h.label) for h in history]),
            expect_equal(path, host, "only the last step visible", [not s["hidden"] for s in steps],
                         [i == len(history) - 1 for i in range(len(history))]),
        ]
        if len(steps) == len(history):
            dev = max(point_deviation(np.asarray(s["points"], dtype=float)[:, :3], xyz(h.points))
                      for s, h in zip(steps, history))
            checks.append(measured(path, host, "history polygons", dev, tol, f"tolerance {tol:.3g}"))
        samples = np.asarray(data["samples"], dtype=float)
        res = int(data["resolution"])
        t = np.arange(m * res + (0 if closed else 1)) / res  # Blender steps every segment uniformly in t
        knots = spline.breakpoints
        seg = np.minimum(t.astype(int), m - 1)
        params = knots[seg] + (t - seg) * (knots[seg + 1] - knots[seg])
        stol = SAMPLE_TOL * max(diag, spline.scale)
        checks.append(measured(path, host, f"{len(samples)} evaluated points",
                               point_deviation(samples, xyz(spline.points(params))), stol,
                               f"Blender's own Bezier evaluation; tolerance {stol:.3g}"))
        return checks


def cubic_pieces(spline: CurveSpline) -> np.ndarray:
    """The curve's exact Bezier pieces as cubics ``(n_spans, 4, 3)`` (quadratic pieces degree-raised)."""
    b = xyz_pieces(spline.bezier())
    if b.shape[1] == 4:
        return b
    p0, p1, p2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([p0, p0 + 2.0 * (p1 - p0) / 3.0, p2 + 2.0 * (p1 - p2) / 3.0, p2], axis=1)


def xyz_pieces(pieces: np.ndarray) -> np.ndarray:
    """Bezier pieces with (x, y, z) points (z = 0 for a planar curve)."""
    if pieces.shape[2] == 3:
        return pieces
    return np.concatenate([pieces, np.zeros(pieces.shape[:2] + (1,))], axis=2)
