"""STEP export through OCP (the OpenCascade binding build123d brings): curves and limit surfaces.

Curves: the exact B-spline as one edge.

The curve is written as a ``Geom_BSplineCurve`` built from our poles, distinct knots, multiplicities and
degree: what ``build123d.Edge.make_bspline`` builds, without importing build123d (3x slower to import
than the few OCP modules used here). Validation reads the file back with OCP's STEP reader and with FreeCAD
(when installed), takes the curve's poles, knots and degree, and evaluates it at parameters spread over
every span.

Surfaces: the Catmull-Clark limit surface as bicubic B-spline patches
(:func:`gsr_cad.geometry.patches.limit_patches`: exact where the control mesh is regular, fitted within
the tolerance elsewhere; ``config["patch_tolerance"]``, default 1e-4 of the diagonal), one face per patch,
sewn (``BRepBuilderAPI_Sewing``) into a shell, and into a solid when the control mesh is closed. The
achieved deviations go into the STEP header's description and a sidecar ``*.step.json``. Validation
reads the STEP back with OCP, checks the solid (``BRepCheck_Analyzer``, one closed shell, positive volume),
and projects exact limit points onto the faces they belong to with OCCT's own projector
(``ShapeAnalysis_Surface``): the largest distance must stay within the stated deviation.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad.atomic import atomic_path, write_text
from gsr_cad.errors import ExportError
from gsr_cad.geometry.patches import PatchSet, limit_grids

from . import hosts
from .base import (Check, CurveSpline, Exporter, curve_checks, curve_spline, expect_equal, failed, measured,
                   skipped, surface_patches)
from .freecad import freecad_read

SAMPLES_PER_SPAN = 16
SEW_TOLERANCE = 1e-7
"""Sewing tolerance relative to the diagonal: shared patch edges are the same curve up to rounding."""
DEVIATION_SLACK = 1e-9
"""Slack, relative to the diagonal, on the stated deviation when a re-read file is measured (rounding in the
STEP text); OCCT's projector may also land up to 0.1 % above our own foot points."""


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


def read_step_curves(path: Path, params: np.ndarray) -> list[StepCurve]:
    """Every edge of a STEP file that is a B-spline, evaluated by OCCT at ``params``.

    Raises ExportError when OCP cannot read the file or an edge is not a B-spline.
    """
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_BSplineCurve
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopoDS import TopoDS

    curves = []
    for edge in _sub_shapes(read_step_shape(path), TopAbs_EDGE):
        adaptor = BRepAdaptor_Curve(TopoDS.Edge(edge))
        if adaptor.GetType() != GeomAbs_BSplineCurve:
            raise ExportError(f"{path.name} holds an edge that is not a B-spline")
        c = adaptor.BSpline()
        poles = np.array([[p.X(), p.Y(), p.Z()] for p in (c.Pole(i) for i in range(1, c.NbPoles() + 1))])
        knots = np.repeat([c.Knot(i) for i in range(1, c.NbKnots() + 1)],
                          [c.Multiplicity(i) for i in range(1, c.NbKnots() + 1)])
        pts = [adaptor.Value(float(u)) for u in params]
        curves.append(StepCurve(poles, knots, c.Degree(), bool(c.IsRational()), adaptor.FirstParameter(),
                                adaptor.LastParameter(), np.array([[p.X(), p.Y(), p.Z()] for p in pts])))
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
                                 knots=c.knots, samples=c.samples, param_range=(c.first, c.last))


def _arrays():
    try:
        from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int
    except ImportError:  # OCP before 8 (e.g. CadQuery's)
        from OCP.TColgp import TColgp_Array1OfPnt as Array1_gp_Pnt
        from OCP.TColStd import TColStd_Array1OfInteger as Array1_int
        from OCP.TColStd import TColStd_Array1OfReal as Array1_double
    return Array1_gp_Pnt, Array1_double, Array1_int


def bspline_edge(spline: CurveSpline) -> Any:
    """The curve as an OCP ``TopoDS_Edge`` on an exact, non-rational ``Geom_BSplineCurve`` in z = 0."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt

    point_array, real_array, int_array = _arrays()
    poles = point_array(1, len(spline.poles))
    for i, (x, y) in enumerate(spline.poles.tolist(), start=1):
        poles.SetValue(i, gp_Pnt(x, y, 0.0))
    knots = real_array(1, len(spline.breakpoints))
    mults = int_array(1, len(spline.breakpoints))
    for i, (k, m) in enumerate(zip(spline.breakpoints.tolist(), spline.multiplicities.tolist()), start=1):
        knots.SetValue(i, k)
        mults.SetValue(i, int(m))
    try:
        curve = Geom_BSplineCurve(poles, knots, mults, spline.degree, False)
        return BRepBuilderAPI_MakeEdge(curve).Edge()
    except Exception as exc:  # OCCT raises Standard_Failure subclasses
        raise ExportError(f"OCCT rejected the B-spline: {exc}") from None


def write_step(shape: Any, path: Path, name: str, description: str = "") -> None:
    """Write an OCP shape as AP214 STEP in millimetres, quietly, with ``name`` as file and product name
    (and ``description`` in the header's FILE_DESCRIPTION)."""
    from OCP.APIHeaderSection import APIHeaderSection_MakeHeader
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_Gravity
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
    from OCP.TCollection import TCollection_HAsciiString

    for printer in Message.DefaultMessenger_s().Printers():
        printer.SetTraceLevel(Message_Gravity.Message_Fail)
    writer = STEPControl_Writer()
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    Interface_Static.SetCVal_s("write.step.product.name", name)
    if writer.Transfer(shape, STEPControl_AsIs) != IFSelect_RetDone:
        raise ExportError("OCCT could not translate the shape to STEP")
    header = APIHeaderSection_MakeHeader(writer.Model())
    if description:
        header.SetDescriptionValue(1, TCollection_HAsciiString(description))
    header.SetName(TCollection_HAsciiString(name))
    header.SetOriginatingSystem(TCollection_HAsciiString("gsr_cad"))
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise ExportError(f"OCCT could not write {path.name}")


def patch_statement(patches: PatchSet) -> str:
    """One line stating what the patches achieve (the STEP header's description)."""
    return (f"gsr_cad Catmull-Clark limit surface: {len(patches.patches)} bicubic B-spline patches "
            f"({patches.n_exact} exact, {len(patches.patches) - patches.n_exact} fitted); deviation from the limit "
            f"max {patches.max_deviation:.6g}, mean {patches.mean_deviation:.6g} (tolerance {patches.tolerance:.6g}, "
            f"diagonal {patches.diagonal:.6g})")


def _surface(patch: Any) -> Any:
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    try:
        from OCP.collections import Array2_gp_Pnt as PointGrid
    except ImportError:  # OCP before 8
        from OCP.TColgp import TColgp_Array2OfPnt as PointGrid
    _, real_array, int_array = _arrays()
    nu, nv, _ = patch.poles.shape
    poles = PointGrid(1, nu, 1, nv)
    for i, row in enumerate(patch.poles.tolist(), start=1):
        for j, (x, y, z) in enumerate(row, start=1):
            poles.SetValue(i, j, gp_Pnt(x, y, z))
    arrays = []
    for knots, mults in (patch.breakpoints_u, patch.breakpoints_v):
        k, m = real_array(1, len(knots)), int_array(1, len(knots))
        for i, (a, b) in enumerate(zip(knots.tolist(), mults.tolist()), start=1):
            k.SetValue(i, a)
            m.SetValue(i, int(b))
        arrays += [k, m]
    return Geom_BSplineSurface(poles, arrays[0], arrays[2], arrays[1], arrays[3], patch.degree_u, patch.degree_v,
                               False, False)


def patch_shape(patches: PatchSet) -> Any:
    """One OCP face per patch, sewn into a shell, made a solid when the mesh is closed; ExportError when
    OCCT does not get a valid shape (or, for a closed mesh, one closed shell enclosing a positive volume)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeSolid, BRepBuilderAPI_Sewing
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.BRepLib import BRepLib
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopoDS import TopoDS

    sewing = BRepBuilderAPI_Sewing(SEW_TOLERANCE * patches.diagonal)
    try:
        for patch in patches.patches:
            sewing.Add(BRepBuilderAPI_MakeFace(_surface(patch), 1e-12 * patches.diagonal).Face())
        sewing.Perform()
    except Exception as exc:  # OCCT raises Standard_Failure subclasses
        raise ExportError(f"OCCT rejected the patches: {exc}") from None
    shape = sewing.SewedShape()
    if patches.closed:
        shells = [TopoDS.Shell(s) for s in _sub_shapes(shape, TopAbs_SHELL)]
        if len(shells) != 1 or sewing.NbFreeEdges() or sewing.NbMultipleEdges():
            raise ExportError(f"sewing the patches gave {len(shells)} shells, {sewing.NbFreeEdges()} free and "
                              f"{sewing.NbMultipleEdges()} multiple edges instead of one closed shell")
        shape = BRepBuilderAPI_MakeSolid(shells[0]).Solid()
        BRepLib.OrientClosedSolid_s(shape)
    if not BRepCheck_Analyzer(shape).IsValid():
        raise ExportError("OCCT finds the sewn patches invalid (BRepCheck_Analyzer)")
    return shape


def read_step_shape(path: Path) -> Any:
    """The shape in a STEP file, read with OCP; ExportError when it cannot be read."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone or reader.TransferRoots() == 0:
        raise ExportError(f"OCP cannot read {path.name} as STEP")
    return reader.OneShape()


def _sub_shapes(shape: Any, kind: Any) -> list:
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


def check_step_surface(step: Path, host: str, result: Any, path: Path | None = None,
                       stated: dict[str, Any] | None = None) -> list[Check]:
    """Compare the shape in the STEP file ``step`` with ``result``'s limit surface: one face per patch, for a
    closed mesh one valid solid of positive volume, and the distance from exact limit points (a grid one
    level finer than the fit, every patch) to the face they belong to, projected by OCCT, within the stated
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
        patches = surface_patches(result)
        shape = read_step_shape(step)
    except ExportError as exc:
        return [failed(path, host, "read", str(exc))]
    faces = [TopoDS.Face(f) for f in _sub_shapes(shape, TopAbs_FACE)]
    checks = [expect_equal(path, host, "one face per patch", len(faces), len(patches.patches)),
              expect_equal(path, host, "BRepCheck_Analyzer valid", bool(BRepCheck_Analyzer(shape).IsValid()), True)]
    if patches.closed:
        solids = _sub_shapes(shape, TopAbs_SOLID)
        shells = _sub_shapes(shape, TopAbs_SHELL)
        checks.append(expect_equal(path, host, "one closed solid", (len(solids), len(shells),
                                   all(BRep_Tool.IsClosed_s(s) for s in shells)), (1, 1, True)))
        props = GProp_GProps()
        BRepGProp.VolumeProperties_s(shape, props)
        checks.append(expect_equal(path, host, "positive volume", props.Mass() > 0, True))
    stated = stated or patches.summary()
    limit = float(stated.get("max_deviation", patches.max_deviation))
    allowed = min(limit * (1 + 1e-3), float(stated.get("tolerance", patches.tolerance))) \
        + DEVIATION_SLACK * patches.diagonal
    grids = limit_grids(result.control_mesh, patches.level + 1, (result.config or {}).get("boundary", "all"))
    m = grids.shape[1]
    tree = cKDTree(grids[:, m // 2, m // 2])
    seen, worst, total, count = set(), 0.0, 0.0, 0
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
        for x, y, z in grids[p].reshape(-1, 3).tolist():
            analysis.ValueOfUV(gp_Pnt(x, y, z), 1e-10 * patches.diagonal)
            gap = analysis.Gap()
            worst = max(worst, gap) if math.isfinite(gap) else math.inf
            total += gap
            count += 1
    detail = (f"stated max {limit:.3g}, mean {float(stated.get('mean_deviation', 0.0)):.3g}; measured mean "
              f"{total / max(count, 1):.3g} over {count} limit points")
    return checks + [measured(path, host, "deviation from the limit surface", worst if count else math.inf,
                              allowed, detail)]


class StepExporter(Exporter):
    """``*.step``: a curve as one exact B-spline edge, a surface as its sewn limit patches (AP214, mm)."""

    name = "step"
    kinds = ("curve", "surface")
    suffixes = (".step",)
    host = "OCP"

    def available(self) -> str | None:
        if importlib.util.find_spec("OCP") is None:
            return "OCP is not installed (pip install 'gsr-cad[cad]': build123d brings it)"
        return None

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        spline = curve_spline(result)
        path = out_dir / self.filename(stem)
        with atomic_path(path) as tmp:
            write_step(bspline_edge(spline), tmp, stem)
        return [path]

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        """OCP reads the file back; FreeCAD, when installed, reads it too (an independent OCCT build)."""
        spline = curve_spline(result)
        reason = self.available()
        checks = [skipped(path, self.host, "read", reason)] if reason else check_step_curve(path, self.host, spline)
        return checks + check_step_in_freecad(path, spline)

    def export_surface(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        """The STEP file and ``<name>.step.json`` stating the deviations achieved (module docstring)."""
        patches = surface_patches(result)
        shape = patch_shape(patches)
        path = out_dir / self.filename(stem)
        with atomic_path(path) as tmp:
            write_step(shape, tmp, stem, patch_statement(patches))
        report = {"file": path.name, "boundary": (result.config or {}).get("boundary", "all"),
                  "solid": patches.closed, **patches.summary()}
        sidecar = write_text(out_dir / (path.name + ".json"), json.dumps(report, indent=2) + "\n")
        return [path, sidecar]

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        if reason := self.available():
            return [skipped(path, self.host, "read", reason)]
        return check_step_surface(path, self.host, result, stated=stated_deviation(path))


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
                                 param_range=c["range"])
