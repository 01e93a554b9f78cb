"""STEP export through OCP (the OpenCascade binding build123d brings): the exact B-spline as one edge.

The curve is written as a ``Geom_BSplineCurve`` built from our poles, distinct knots, multiplicities and
degree: what ``build123d.Edge.make_bspline`` builds, without importing build123d (3x slower to import
than the few OCP modules used here). Validation reads the file back with OCP's STEP reader and with FreeCAD
(when installed), takes the curve's poles, knots and degree, and evaluates it at parameters spread over
every span.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad.atomic import atomic_path
from gsr_cad.errors import ExportError

from . import hosts
from .base import Check, CurveSpline, Exporter, curve_checks, curve_spline, expect_equal, failed, skipped
from .freecad import freecad_read

SAMPLES_PER_SPAN = 16


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
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    reader = STEPControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise ExportError(f"OCP cannot read {path.name} as STEP")
    reader.TransferRoots()
    shape = reader.OneShape()
    curves = []
    explorer = TopExp_Explorer(shape, TopAbs_EDGE)
    while explorer.More():
        adaptor = BRepAdaptor_Curve(TopoDS.Edge(explorer.Current()))
        explorer.Next()
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


def write_step(shape: Any, path: Path, name: str) -> None:
    """Write an OCP shape as AP214 STEP in millimetres, quietly, with ``name`` as file and product name."""
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
        raise ExportError("OCCT could not translate the curve to STEP")
    header = APIHeaderSection_MakeHeader(writer.Model())
    header.SetName(TCollection_HAsciiString(name))
    header.SetOriginatingSystem(TCollection_HAsciiString("gsr_cad"))
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise ExportError(f"OCCT could not write {path.name}")


class StepExporter(Exporter):
    """``*.step``: the curve as one exact B-spline edge (AP214, millimetres)."""

    name = "step"
    kinds = ("curve",)
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
        if importlib.util.find_spec("OCP") is None:
            checks = [skipped(path, self.host, "read", "OCP is not installed (pip install 'gsr-cad[cad]')")]
        else:
            checks = check_step_curve(path, self.host, spline)
        return checks + check_step_in_freecad(path, spline)


def check_step_in_freecad(path: Path, spline: CurveSpline) -> list[Check]:
    """Read a STEP file with ``freecadcmd`` and compare its one B-spline edge with ``spline``."""
    if hosts.find_host("freecad") is None:
        return [skipped(path, "freecad", "read", "FreeCAD is not installed (apt-get install freecad)")]
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
