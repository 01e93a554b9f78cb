"""STEP export through OCP (the OpenCascade binding build123d brings): curves and limit surfaces.

Curves: the exact B-spline as one edge, planar (in z = 0) or in space; corners are repeated knots, a closed
curve its exact clamped form (first and last pole the same point), which readers may hold as periodic.

The curve is written as a ``Geom_BSplineCurve`` built from our poles, distinct knots, multiplicities and
degree: what ``build123d.Edge.make_bspline`` builds, without importing build123d (3x slower to import
than the few OCP modules used here). Validation reads the file back with OCP's STEP reader and with FreeCAD
(when installed), takes the curve's poles, knots and degree, and evaluates it at parameters spread over
every span.

Surfaces: the Catmull-Clark limit surface as bicubic B-spline patches
(:func:`gsr_cad.geometry.patches.limit_patches`: exact where the control mesh is regular, beside straight
infinitely sharp creases included, fitted within the tolerance elsewhere; ``config["patch_tolerance"]``,
default 1e-4 of the diagonal), one face per patch, sewn (``BRepBuilderAPI_Sewing``) into a shell, and into a
solid when the control mesh is closed. Patches on either side of a crease share their edge curve, so a crease
is an exact C0 edge of the solid. The
achieved deviations go into the STEP header's description and a sidecar ``*.step.json``. Validation
reads the STEP back with OCP, checks the solid (``BRepCheck_Analyzer``, one closed shell, positive volume),
and projects exact limit points onto the faces they belong to with OCCT's own projector
(``ShapeAnalysis_Surface``): the largest distance must stay within the stated deviation.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

from gsr_cad.atomic import atomic_path, write_text
from gsr_cad.errors import ExportError
from gsr_cad.geometry.patches import PatchSet

from .base import Check, Exporter, skipped
from .checks import (sub_shapes, check_step_curve, check_step_in_freecad, check_step_surface, patch_statement,
                     stated_deviation)
from .model import CurveSpline, curve_model, surface_model, xyz

SEW_TOLERANCE = 1e-7
"""Sewing tolerance relative to the diagonal: shared patch edges are the same curve up to rounding."""


def _arrays():
    try:
        from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int
    except ImportError:  # OCP before 8 (e.g. CadQuery's)
        from OCP.TColgp import TColgp_Array1OfPnt as Array1_gp_Pnt
        from OCP.TColStd import TColStd_Array1OfInteger as Array1_int
        from OCP.TColStd import TColStd_Array1OfReal as Array1_double
    return Array1_gp_Pnt, Array1_double, Array1_int


def bspline_edge(spline: CurveSpline) -> Any:
    """The curve as an OCP ``TopoDS_Edge`` on an exact, non-rational ``Geom_BSplineCurve`` (a planar curve in
    z = 0, a space curve as it is)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt

    point_array, real_array, int_array = _arrays()
    poles = point_array(1, len(spline.poles))
    for i, (x, y, z) in enumerate(xyz(spline.poles).tolist(), start=1):
        poles.SetValue(i, gp_Pnt(x, y, z))
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
        shells = [TopoDS.Shell(s) for s in sub_shapes(shape, TopAbs_SHELL)]
        if len(shells) != 1 or sewing.NbFreeEdges() or sewing.NbMultipleEdges():
            raise ExportError(f"sewing the patches gave {len(shells)} shells, {sewing.NbFreeEdges()} free and "
                              f"{sewing.NbMultipleEdges()} multiple edges instead of one closed shell")
        shape = BRepBuilderAPI_MakeSolid(shells[0]).Solid()
        BRepLib.OrientClosedSolid_s(shape)
    if not BRepCheck_Analyzer(shape).IsValid():
        raise ExportError("OCCT finds the sewn patches invalid (BRepCheck_Analyzer)")
    return shape


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
        spline = curve_model(result).spline
        path = out_dir / self.filename(stem)
        with atomic_path(path) as tmp:
            write_step(bspline_edge(spline), tmp, stem)
        return [path]

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        """OCP reads the file back; FreeCAD, when installed, reads it too (an independent OCCT build)."""
        spline = curve_model(result).spline
        reason = self.available()
        checks = [skipped(path, self.host, "read", reason)] if reason else check_step_curve(path, self.host, spline)
        return checks + check_step_in_freecad(path, spline)

    def export_surface(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        """The STEP file and ``<name>.step.json`` stating the deviations achieved (module docstring)."""
        model = surface_model(result)
        patches = model.patches
        shape = patch_shape(patches)
        path = out_dir / self.filename(stem)
        with atomic_path(path) as tmp:
            write_step(shape, tmp, stem, patch_statement(patches))
        report = {"file": path.name, "boundary": model.boundary,
                  "solid": patches.closed, **patches.summary()}
        sidecar = write_text(out_dir / (path.name + ".json"), json.dumps(report, indent=2) + "\n")
        return [path, sidecar]

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        if reason := self.available():
            return [skipped(path, self.host, "read", reason)]
        return check_step_surface(path, self.host, result, stated=stated_deviation(path))


