"""Host checkers shared by the exporters: reading STEP files back with OCP and files or documents with
FreeCAD, and comparing what they hold with a result's model. Beside :mod:`~gsr_cad.exporters.hosts`,
which runs the hosts; no exporter imports another, they share these.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad.atomic import write_text
from gsr_cad.errors import ExportError
from gsr_cad.geometry.patches import PatchSet, limit_grids

from . import hosts
from .base import Check, curve_checks, expect_equal, failed, measured, scratch_dir, skipped
from .encode import fill_python
from .model import CurveSpline, surface_model

SAMPLES_PER_SPAN = 16
DEVIATION_SLACK = 1e-9
"""Slack, relative to the diagonal, on the stated deviation when a re-read file is measured (rounding in the
STEP text); OCCT's projector may also land up to 0.1 % above our own foot points."""
PATCH_GRID = (0.0, 0.25, 0.5, 0.75, 1.0)


def patch_statement(patches: PatchSet) -> str:
    """One line stating what the patches achieve (the STEP header's description)."""
    return (f"gsr_cad Catmull-Clark limit surface: {len(patches.patches)} bicubic B-spline patches "
            f"({patches.n_exact} exact, {len(patches.patches) - patches.n_exact} fitted); deviation from the limit "
            f"max {patches.max_deviation:.6g}, mean {patches.mean_deviation:.6g} (tolerance {patches.tolerance:.6g}, "
            f"diagonal {patches.diagonal:.6g})")


def freecad_read(source: Path, params: Any = (), grid: Any = PATCH_GRID, timeout: float = 120) -> dict[str, Any]:
    """Open an ``.FCStd`` (history steps, "Curve", "LimitSurface", "LimitMesh") or read another file (every
    edge) with ``freecadcmd`` and return what FreeCAD sees, B-splines evaluated by FreeCAD at ``params``
    (curves) and on ``grid`` x ``grid`` (patches). ExportError when FreeCAD is missing or fails."""
    script = fill_python("freecad_read.py", {"params": [float(u) for u in params],
                                             "grid": [float(u) for u in grid]})
    with scratch_dir() as tmp:
        reader, out = tmp / "read_back.py", tmp / "read.json"
        write_text(reader, script)
        hosts.run_freecad(reader, [source, out], timeout=timeout)
        try:
            return json.loads(out.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ExportError(f"FreeCAD's read-back gave no result: {exc}") from None


@dataclasses.dataclass(frozen=True)
class StepCurve:
    """A B-spline edge as read from a STEP file: 3-D poles, flattened knots, degree, evaluated points."""

    poles: np.ndarray
    knots: np.ndarray
    degree: int
    rational: bool
    first: float
    last: float
    samples: np.ndarray
    periodic: bool = False
    closed: bool = False


def read_step_curves(path: Path, params: np.ndarray) -> list[StepCurve]:
    """Every edge of a STEP file that is a B-spline, evaluated by OCCT at ``params``.

    Raises ExportError when OCP cannot read the file or an edge is not a B-spline.
    """
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_BSplineCurve
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopoDS import TopoDS

    curves = []
    for edge in sub_shapes(read_step_shape(path), TopAbs_EDGE):
        adaptor = BRepAdaptor_Curve(TopoDS.Edge(edge))
        if adaptor.GetType() != GeomAbs_BSplineCurve:
            raise ExportError(f"{path.name} holds an edge that is not a B-spline")
        c = adaptor.BSpline()
        poles = np.array([[p.X(), p.Y(), p.Z()] for p in (c.Pole(i) for i in range(1, c.NbPoles() + 1))])
        knots = np.repeat([c.Knot(i) for i in range(1, c.NbKnots() + 1)],
                          [c.Multiplicity(i) for i in range(1, c.NbKnots() + 1)])
        pts = [adaptor.Value(float(u)) for u in params]
        curves.append(StepCurve(poles, knots, c.Degree(), bool(c.IsRational()), adaptor.FirstParameter(),
                                adaptor.LastParameter(), np.array([[p.X(), p.Y(), p.Z()] for p in pts]),
                                bool(c.IsPeriodic()), bool(c.IsClosed())))
    return curves


def check_step_curve(step: Path, host: str, spline: CurveSpline, path: Path | None = None) -> list[Check]:
    """Compare the one B-spline edge of the STEP file ``step`` with ``spline`` (structure, numbers, OCCT
    samples); checks are reported under ``path`` (default: ``step``), e.g. the script that wrote it."""
    path = path or step
    params = spline.params(SAMPLES_PER_SPAN)
    try:
        curves = read_step_curves(step, params)
    except ExportError as exc:
        return [failed(path, host, "read", str(exc))]
    checks = [expect_equal(path, host, "one B-spline edge", len(curves), 1)]
    if len(curves) != 1:
        return checks
    c = curves[0]
    return checks + curve_checks(path, host, spline, params, degree=c.degree, rational=c.rational, poles=c.poles,
                                 knots=c.knots, samples=c.samples, param_range=(c.first, c.last),
                                 periodic=c.periodic, closed=c.closed)


def read_step_shape(path: Path) -> Any:
    """The shape in a STEP file, read with OCP; ExportError when it cannot be read."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone or reader.TransferRoots() == 0:
        raise ExportError(f"OCP cannot read {path.name} as STEP")
    return reader.OneShape()


def sub_shapes(shape: Any, kind: Any) -> list:
    from OCP.TopExp import TopExp_Explorer

    out, explorer = [], TopExp_Explorer(shape, kind)
    while explorer.More():
        out.append(explorer.Current())
        explorer.Next()
    return out


def stated_deviation(step: Path) -> dict[str, Any] | None:
    """The figures the export stated in ``<file>.json`` beside the STEP file, or None."""
    try:
        return json.loads(step.with_name(step.name + ".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


NEAR_ENOUGH = 0.1
"""A foot point found from a neighbour's within this fraction of the allowed deviation is taken without OCCT's
global search: either is a point on the face, so its distance bounds the true one from above. A creased 164-patch
solid (178,596 limit points): 40 s with the global search of every point, 6 s so, the same max and mean."""


def _foot_on_face(analysis: Any, point: Any, hint: Any, precision: float, near_enough: float) -> tuple[Any, float]:
    """A point of the face near ``point`` (its UV) and their distance: OCCT's search from ``hint`` (a neighbour's
    foot point), then, where that is not within ``near_enough``, its global search too, the nearer of the two."""
    uv, gap = None, math.inf
    if hint is not None:
        uv = analysis.NextValueOfUV(hint, point, precision, -1.0)
        gap = analysis.Gap()
    if not gap <= near_enough:
        far = analysis.ValueOfUV(point, precision)
        if uv is None or analysis.Gap() < gap:
            uv, gap = far, analysis.Gap()
    return uv, gap


def check_step_surface(step: Path, host: str, result: Any, path: Path | None = None,
                       stated: dict[str, Any] | None = None) -> list[Check]:
    """Compare the shape in the STEP file ``step`` with ``result``'s limit surface: one face per patch, for a
    closed mesh one valid solid of positive volume, and the distance from exact limit points (a grid one
    level finer than the fit, every patch) to the face they belong to, projected by OCCT (:func:`_foot_on_face`:
    from a neighbour's foot point, and globally where that is not near enough), within the stated
    deviation (``stated``, default the figures of our own fit). Checks are reported under ``path``."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.BRepGProp import BRepGProp
    from OCP.BRepTools import BRepTools
    from OCP.GProp import GProp_GProps
    from OCP.gp import gp_Pnt
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
    from OCP.TopoDS import TopoDS
    from scipy.spatial import cKDTree

    path = path or step
    try:
        model = surface_model(result)
        patches = model.patches
        shape = read_step_shape(step)
    except ExportError as exc:
        return [failed(path, host, "read", str(exc))]
    faces = [TopoDS.Face(f) for f in sub_shapes(shape, TopAbs_FACE)]
    checks = [expect_equal(path, host, "one face per patch", len(faces), len(patches.patches)),
              expect_equal(path, host, "BRepCheck_Analyzer valid", bool(BRepCheck_Analyzer(shape).IsValid()), True)]
    if patches.closed:
        solids = sub_shapes(shape, TopAbs_SOLID)
        shells = sub_shapes(shape, TopAbs_SHELL)
        checks.append(expect_equal(path, host, "one closed solid", (len(solids), len(shells),
                                   all(BRep_Tool.IsClosed_s(s) for s in shells)), (1, 1, True)))
        props = GProp_GProps()
        BRepGProp.VolumeProperties_s(shape, props)
        checks.append(expect_equal(path, host, "positive volume", props.Mass() > 0, True))
    stated = stated or patches.summary()
    limit = float(stated.get("max_deviation", patches.max_deviation))
    allowed = min(limit * (1 + 1e-3), float(stated.get("tolerance", patches.tolerance))) \
        + DEVIATION_SLACK * patches.diagonal
    grids = limit_grids(model.control, patches.level + 1, model.boundary)
    m = grids.shape[1]
    tree = cKDTree(grids[:, m // 2, m // 2])
    seen, worst, total, count = set(), 0.0, 0.0, 0
    precision, near_enough = 1e-10 * patches.diagonal, NEAR_ENOUGH * allowed
    for face in faces:
        surface = BRep_Tool.Surface_s(face)
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        centre = surface.Value(0.5 * (u0 + u1), 0.5 * (v0 + v1))
        _, p = tree.query([centre.X(), centre.Y(), centre.Z()])
        if p in seen:
            return checks + [failed(path, host, "deviation from the limit surface",
                                    f"two faces lie on patch {p}: the faces do not match the patches")]
        seen.add(p)
        analysis = ShapeAnalysis_Surface(surface)
        row_start = None
        for row in grids[p].tolist():
            previous = row_start
            for column, (x, y, z) in enumerate(row):
                uv, gap = _foot_on_face(analysis, gp_Pnt(x, y, z), previous, precision, near_enough)
                previous = uv
                row_start = uv if column == 0 else row_start
                worst = max(worst, gap) if math.isfinite(gap) else math.inf
                total += gap
                count += 1
    detail = (f"stated max {limit:.3g}, mean {float(stated.get('mean_deviation', 0.0)):.3g}; measured mean "
              f"{total / max(count, 1):.3g} over {count} limit points")
    return checks + [measured(path, host, "deviation from the limit surface", worst if count else math.inf,
                              allowed, detail)]


def check_step_in_freecad(path: Path, spline: CurveSpline) -> list[Check]:
    """Read a STEP file with ``freecadcmd`` and compare its one B-spline edge with ``spline``."""
    if reason := hosts.missing("freecad"):
        return [skipped(path, "freecad", "read", reason)]
    params = spline.params(SAMPLES_PER_SPAN)
    try:
        curves = freecad_read(path, params)["curves"]
    except (ExportError, KeyError) as exc:
        return [failed(path, "freecad", "read", str(exc))]
    checks = [expect_equal(path, "freecad", "one B-spline edge", [("poles" in c) for c in curves], [True])]
    if not checks[0].passed:
        return checks
    c = curves[0]
    return checks + curve_checks(path, "freecad", spline, params, degree=c["degree"], rational=c["rational"],
                                 poles=c["poles"], knots=np.repeat(c["knots"], c["mults"]), samples=c["samples"],
                                 param_range=c["range"], periodic=bool(c.get("periodic", False)),
                                 closed=c.get("closed"))
