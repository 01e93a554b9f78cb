"""A gsr_cad result for CadQuery: the exact curve, or the limit surface as sewn B-spline patches.

Written by gsr_cad's "cadquery" exporter; everything specific to this result is in DATA below. A curve
(DATA["kind"] == "curve") is rebuilt exactly from its poles, knots and multiplicities (not
re-interpolated). A surface is one exact face per bicubic patch (DATA["statement"] says how close the
patches are to the Catmull-Clark limit surface), sewn into a shell and, when DATA["closed"], a solid.
Run: python this_file.py [OUT.step]   (needs CadQuery; writes a STEP file next to this file by default).
In CQ-editor, the shape (and a curve's control polygon) is shown.
"""
import sys
from pathlib import Path

import cadquery as cq
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace
from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface
from OCP.gp import gp_Pnt

try:
    from OCP.TColgp import TColgp_Array1OfPnt as PointArray
    from OCP.TColgp import TColgp_Array2OfPnt as PointGrid
    from OCP.TColStd import TColStd_Array1OfInteger as IntArray
    from OCP.TColStd import TColStd_Array1OfReal as RealArray
except ImportError:  # OCP 8 moved the array types
    from OCP.collections import Array1_double as RealArray
    from OCP.collections import Array1_gp_Pnt as PointArray
    from OCP.collections import Array1_int as IntArray
    from OCP.collections import Array2_gp_Pnt as PointGrid

DATA = {}


def _array(kind, values, convert):
    array = kind(1, len(values))
    for i, value in enumerate(values, start=1):
        array.SetValue(i, convert(value))
    return array


def _point(p):
    return gp_Pnt(p[0], p[1], p[2] if len(p) > 2 else 0.0)


def bspline_edge():
    """The exact curve as a CadQuery edge."""
    curve = Geom_BSplineCurve(_array(PointArray, DATA["poles"], _point), _array(RealArray, DATA["knots"], float),
                              _array(IntArray, DATA["mults"], int), DATA["degree"], False)
    return cq.Edge(BRepBuilderAPI_MakeEdge(curve).Edge())


def control_polygon():
    """The control polygon as a polyline (repeated consecutive poles dropped: they make no edge)."""
    points = [tuple(p) for i, p in enumerate(DATA["poles"]) if i == 0 or p != DATA["poles"][i - 1]]
    return cq.Workplane("XY").polyline(points)


def patch_face(patch):
    """One exact patch as a CadQuery face."""
    poles = patch["poles"]
    grid = PointGrid(1, len(poles), 1, len(poles[0]))
    for i, row in enumerate(poles, start=1):
        for j, p in enumerate(row, start=1):
            grid.SetValue(i, j, _point(p))
    surface = Geom_BSplineSurface(grid, _array(RealArray, patch["uknots"], float),
                                  _array(RealArray, patch["vknots"], float), _array(IntArray, patch["umults"], int),
                                  _array(IntArray, patch["vmults"], int), patch["udegree"], patch["vdegree"],
                                  False, False)
    return cq.Face(BRepBuilderAPI_MakeFace(surface, 1e-12).Face())


def build():
    """The curve (as a workplane) or the sewn surface (a solid when closed)."""
    if DATA["kind"] == "curve":
        return cq.Workplane("XY").add(bspline_edge())
    shell = cq.Shell.makeShell([patch_face(patch) for patch in DATA["patches"]])
    return cq.Solid.makeSolid(shell) if DATA["closed"] else shell


shape = build()

if __name__ == "__main__":
    if DATA["kind"] == "surface" and not shape.isValid():
        raise SystemExit("the sewn patches are not a valid shape")
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_suffix(".step")
    cq.exporters.export(shape, str(out), exportType="STEP")
    print(out)
elif "show_object" in globals():
    show_object(shape, name=DATA["kind"])  # noqa: F821 (CQ-editor)
    if DATA["kind"] == "curve":
        show_object(control_polygon(), name="control polygon", options={"color": "gray"})  # noqa: F821
