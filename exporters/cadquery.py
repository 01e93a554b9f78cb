"""CadQuery export: a plain ``*_cadquery.py`` script that rebuilds the geometry exactly and writes a STEP.

Surfaces: the script holds the limit-surface patches of :func:`gsr_cad.geometry.patches.limit_patches`
(poles, knots, multiplicities), builds one ``Geom_BSplineSurface`` face per patch, sews them with
``cq.Shell.makeShell`` and, for a closed mesh, makes the solid with ``cq.Solid.makeSolid``; validation
measures its STEP like the STEP exporter's (one solid, BRepCheck, OCCT projection of limit points).

Curves:
The script builds ``Geom_BSplineCurve`` from the poles, knots, multiplicities and degree through the OCP
that comes with CadQuery (array types from ``OCP.TColgp``/``OCP.TColStd``, or ``OCP.collections`` on
OCP 8), wraps it as ``cq.Edge``, and exports STEP next to itself (or to the path given as its first
argument). In CQ-editor it shows the curve and the control polygon instead.

CadQuery and build123d ship different OCP builds that must not share a Python environment, so
validation runs the script with the interpreter of a separate venv (``GSR_CADQUERY_PYTHON``, else
``.venv-cadquery`` in the project, made by ``scripts/cadquery-venv.sh``) and reads its STEP back with
our OCP like the STEP exporter does.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gsr_cad.atomic import write_text
from gsr_cad.errors import ExportError

from . import hosts
from .base import (Check, Exporter, curve_spline, failed, num, patch_literals, scratch_dir, skipped,
                   surface_patches)
from .step import check_step_curve, check_step_surface, patch_statement

_SCRIPT = '''"""{filename}: a gsr_cad {scheme} curve ({n} control points, degree {degree}) for CadQuery.

The curve is rebuilt exactly from its poles, knots and multiplicities (not re-interpolated).
Run: python {filename} [OUT.step]   (needs CadQuery; writes {step_name} next to this file by default)
In CQ-editor, the curve and its control polygon are shown.
"""
import sys
from pathlib import Path

import cadquery as cq
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
from OCP.Geom import Geom_BSplineCurve
from OCP.gp import gp_Pnt

try:
    from OCP.TColgp import TColgp_Array1OfPnt as PointArray
    from OCP.TColStd import TColStd_Array1OfInteger as IntArray
    from OCP.TColStd import TColStd_Array1OfReal as RealArray
except ImportError:  # OCP 8 moved the array types
    from OCP.collections import Array1_double as RealArray
    from OCP.collections import Array1_gp_Pnt as PointArray
    from OCP.collections import Array1_int as IntArray

DEGREE = {degree}
POLES = [{poles}]
KNOTS = [{knots}]
MULTS = [{mults}]


def _array(kind, values, convert):
    array = kind(1, len(values))
    for i, value in enumerate(values, start=1):
        array.SetValue(i, convert(value))
    return array


def bspline_edge():
    """The exact curve as a CadQuery edge."""
    curve = Geom_BSplineCurve(_array(PointArray, POLES, lambda p: gp_Pnt(p[0], p[1], 0.0)),
                              _array(RealArray, KNOTS, float), _array(IntArray, MULTS, int), DEGREE, False)
    return cq.Edge(BRepBuilderAPI_MakeEdge(curve).Edge())


curve = cq.Workplane("XY").add(bspline_edge())
control_polygon = cq.Workplane("XY").polyline(POLES)

if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_suffix(".step")
    cq.exporters.export(curve, str(out), exportType="STEP")
    print(out)
elif "show_object" in globals():
    show_object(curve, name="curve")  # noqa: F821 (CQ-editor)
    show_object(control_polygon, name="control polygon", options={{"color": "gray"}})  # noqa: F821
'''


_SURFACE_SCRIPT = '''"""{filename}: a gsr_cad Catmull-Clark limit surface as {n} bicubic B-spline patches for CadQuery.

{statement}.
Each patch is rebuilt exactly from its poles, knots and multiplicities; the patches are sewn into a shell
({closing}).
Run: python {filename} [OUT.step]   (needs CadQuery; writes {step_name} next to this file by default)
In CQ-editor, the {kind} is shown.
"""
import sys
from pathlib import Path

import cadquery as cq
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.Geom import Geom_BSplineSurface
from OCP.gp import gp_Pnt

try:
    from OCP.TColgp import TColgp_Array2OfPnt as PointGrid
    from OCP.TColStd import TColStd_Array1OfInteger as IntArray
    from OCP.TColStd import TColStd_Array1OfReal as RealArray
except ImportError:  # OCP 8 moved the array types
    from OCP.collections import Array1_double as RealArray
    from OCP.collections import Array1_int as IntArray
    from OCP.collections import Array2_gp_Pnt as PointGrid

CLOSED = {closed}
DEGREE = 3
# per patch: poles[i][j] (i along u), u knots, u multiplicities, v knots, v multiplicities
PATCHES = [
{patches}
]


def _array(kind, values, convert):
    array = kind(1, len(values))
    for i, value in enumerate(values, start=1):
        array.SetValue(i, convert(value))
    return array


def patch_face(poles, u_knots, u_mults, v_knots, v_mults):
    """One exact patch as a CadQuery face."""
    grid = PointGrid(1, len(poles), 1, len(poles[0]))
    for i, row in enumerate(poles, start=1):
        for j, (x, y, z) in enumerate(row, start=1):
            grid.SetValue(i, j, gp_Pnt(x, y, z))
    surface = Geom_BSplineSurface(grid, _array(RealArray, u_knots, float), _array(RealArray, v_knots, float),
                                  _array(IntArray, u_mults, int), _array(IntArray, v_mults, int), DEGREE, DEGREE,
                                  False, False)
    return cq.Face(BRepBuilderAPI_MakeFace(surface, 1e-12).Face())


shell = cq.Shell.makeShell([patch_face(*patch) for patch in PATCHES])
shape = cq.Solid.makeSolid(shell) if CLOSED else shell

if __name__ == "__main__":
    if not shape.isValid():
        raise SystemExit("the sewn patches are not a valid shape")
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_suffix(".step")
    cq.exporters.export(shape, str(out), exportType="STEP")
    print(out)
elif "show_object" in globals():
    show_object(shape, name="limit surface")  # noqa: F821 (CQ-editor)
'''


def _patch_literal(patch: Any) -> str:
    poles, *lists = patch_literals(patch)
    return f"    ({poles},\n     " + ", ".join(lists) + "),"


def cadquery_python() -> Path | None:
    """The interpreter of the CadQuery venv (``GSR_CADQUERY_PYTHON`` or ``.venv-cadquery``), or None."""
    override = os.environ.get("GSR_CADQUERY_PYTHON")
    candidates = [Path(override)] if override else [
        Path(__file__).resolve().parents[1] / ".venv-cadquery" / "bin" / "python",
        Path.cwd() / ".venv-cadquery" / "bin" / "python",
    ]
    return next((p for p in candidates if p.is_file() and os.access(p, os.X_OK)), None)


_NO_ENVIRONMENT = "no CadQuery environment (run scripts/cadquery-venv.sh or set GSR_CADQUERY_PYTHON)"


def run_cadquery_script(script: Path, args: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    """Run a script with the CadQuery interpreter; ExportError when it is missing, fails or times out."""
    python = cadquery_python()
    if python is None:
        raise ExportError(_NO_ENVIRONMENT)
    return hosts.run([python, script, *args], "cadquery", timeout)


class CadqueryExporter(Exporter):
    """``*_cadquery.py``: a CadQuery script rebuilding the exact curve or limit patches and exporting STEP."""

    name = "cadquery"
    kinds = ("curve", "surface")
    suffixes = ("_cadquery.py",)
    host = "cadquery"

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        spline = curve_spline(result)
        filename = self.filename(stem)
        text = _SCRIPT.format(
            filename=filename, scheme=result.config.get("scheme", "bspline"), n=len(spline.poles),
            degree=spline.degree, step_name=Path(filename).with_suffix(".step").name,
            poles=", ".join(f"({num(x)}, {num(y)})" for x, y in spline.poles),
            knots=", ".join(num(k) for k in spline.breakpoints),
            mults=", ".join(str(int(m)) for m in spline.multiplicities))
        return [write_text(out_dir / filename, text)]

    def _validate_step(self, path: Path, check: Callable[[Path], list[Check]]) -> list[Check]:
        """Run the script to write a STEP file and judge that file with ``check``."""
        if cadquery_python() is None:
            return [skipped(path, self.host, "run script", _NO_ENVIRONMENT)]
        with scratch_dir() as tmp:
            step = tmp / "cadquery.step"
            try:
                run_cadquery_script(path, [str(step)])
            except ExportError as exc:
                return [failed(path, self.host, "run script", str(exc))]
            if not step.is_file():
                return [failed(path, self.host, "run script", "the script wrote no STEP file")]
            return check(step)

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        spline = curve_spline(result)
        return self._validate_step(path, lambda step: check_step_curve(step, self.host, spline, path))

    def export_surface(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        patches = surface_patches(result)
        filename = self.filename(stem)
        text = _SURFACE_SCRIPT.format(
            filename=filename, n=len(patches.patches), statement=patch_statement(patches),
            closing="and the shell into a solid" if patches.closed else "the control mesh is open: no solid",
            step_name=Path(filename).with_suffix(".step").name, kind="solid" if patches.closed else "shell",
            closed=patches.closed, patches="\n".join(_patch_literal(p) for p in patches.patches))
        return [write_text(out_dir / filename, text)]

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        return self._validate_step(path, lambda step: check_step_surface(step, self.host, result, path))
