"""CadQuery export: a plain ``*_cadquery.py`` script that rebuilds the geometry exactly and writes a STEP.

The script is :mod:`~gsr_cad.exporters.hostside` ``cadquery_script.py`` with its
``DATA`` line filled by the literal encoder.

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

from collections.abc import Callable
from pathlib import Path
from typing import Any

from gsr_cad.errors import ExportError

from . import hosts
from .base import Check, Exporter, failed, scratch_dir, skipped
from .checks import check_step_curve, check_step_surface, patch_statement
from .encode import fill_python
from .model import curve_model, patch_data, surface_model


class CadqueryExporter(Exporter):
    """``*_cadquery.py``: a CadQuery script rebuilding the exact curve or limit patches and exporting STEP."""

    name = "cadquery"
    kinds = ("curve", "surface")
    suffixes = ("_cadquery.py",)
    host = "cadquery"

    def render_curve(self, result: Any, stem: str) -> dict[str, str]:
        spline = curve_model(result).spline
        text = fill_python("cadquery_script.py", {"kind": "curve", "degree": int(spline.degree),
                                                  "poles": spline.poles.tolist(), "knots": spline.breakpoints.tolist(),
                                                  "mults": [int(m) for m in spline.multiplicities]})
        return {self.filename(stem): text}

    def _validate_step(self, path: Path, check: Callable[[Path], list[Check]]) -> list[Check]:
        """Run the script to write a STEP file and judge that file with ``check``."""
        if hosts.cadquery_python() is None:
            return [skipped(path, self.host, "run script", hosts.NO_CADQUERY)]
        with scratch_dir() as tmp:
            step = tmp / "cadquery.step"
            try:
                hosts.run_cadquery(path, [str(step)])
            except ExportError as exc:
                return [failed(path, self.host, "run script", str(exc))]
            if not step.is_file():
                return [failed(path, self.host, "run script", "the script wrote no STEP file")]
            return check(step)

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        spline = curve_model(result).spline
        return self._validate_step(path, lambda step: check_step_curve(step, self.host, spline, path))

    def render_surface(self, result: Any, stem: str) -> dict[str, str]:
        patches = surface_model(result).patches
        text = fill_python("cadquery_script.py", {"kind": "surface", "statement": patch_statement(patches),
                                                  "closed": bool(patches.closed),
                                                  "patches": [patch_data(p) for p in patches.patches]})
        return {self.filename(stem): text}

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        return self._validate_step(path, lambda step: check_step_surface(step, self.host, result, path))
