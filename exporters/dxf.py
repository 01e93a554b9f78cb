"""DXF export through ezdxf: the exact SPLINE (poles, knots, degree) plus the control polygon.

A planar curve is a planar SPLINE (flag 8, normal +z) in z = 0, a space curve a non-planar SPLINE (no normal) with
its z; corners are repeated knots; a closed curve is its exact clamped form (first and last control point the
same) with the SPLINE's closed flag (1) set. The control polygon is an LWPOLYLINE (planar) or a 3D POLYLINE.

Layers: ``GSR_CURVE`` holds the SPLINE, ``GSR_CONTROL_POLYGON`` a dashed LWPOLYLINE through the control
points. Numbers are written at full double precision, so validation re-reads the file with ezdxf and
expects the very same poles and knots, then evaluates the SPLINE with ezdxf's own B-spline code.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from gsr_cad.atomic import atomic_path
from gsr_cad.errors import ExportError

from .base import (EXACT_TOL, Check, Exporter, curve_checks, expect_equal, failed, measured,
                   point_deviation, skipped)
from .model import curve_model, xyz

CURVE_LAYER = "GSR_CURVE"
POLYGON_LAYER = "GSR_CONTROL_POLYGON"
SAMPLES_PER_SPAN = 16
_CLOSED, _PLANAR = 1, 8  # SPLINE flag bits: closed; the curve lies in a plane


class DxfExporter(Exporter):
    """``*.dxf`` (R2010, millimetres): SPLINE + control polygon on their own layers."""

    name = "dxf"
    kinds = ("curve",)
    suffixes = (".dxf",)
    host = "ezdxf"

    def available(self) -> str | None:
        if importlib.util.find_spec("ezdxf") is None:
            return "ezdxf is not installed (pip install 'gsr-cad[cad]')"
        return None

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        import ezdxf

        spline = curve_model(result).spline
        doc = ezdxf.new("R2010", setup=["linetypes"])
        doc.units = ezdxf.units.MM
        doc.layers.add(CURVE_LAYER, color=1)
        doc.layers.add(POLYGON_LAYER, color=8, linetype="DASHED")
        msp = doc.modelspace()
        poles3 = [tuple(p) for p in xyz(spline.poles).tolist()]
        entity = msp.add_open_spline(poles3, degree=spline.degree, knots=spline.knots.tolist(),
                                     dxfattribs={"layer": CURVE_LAYER})
        if spline.closed:
            entity.dxf.flags = entity.dxf.flags | _CLOSED
        if spline.dim == 2:
            entity.dxf.flags = entity.dxf.flags | _PLANAR
            entity.dxf.extrusion = (0.0, 0.0, 1.0)
            msp.add_lwpolyline(spline.poles.tolist(), dxfattribs={"layer": POLYGON_LAYER})
        else:
            msp.add_polyline3d(poles3, dxfattribs={"layer": POLYGON_LAYER})
        path = out_dir / self.filename(stem)
        try:
            with atomic_path(path) as tmp:
                doc.saveas(tmp)
        except OSError as exc:
            raise ExportError(f"cannot write {path}: {exc.strerror or exc}") from None
        return [path]

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if reason := self.available():
            return [skipped(path, self.host, "read", reason)]
        import ezdxf

        spline = curve_model(result).spline
        try:
            doc = ezdxf.readfile(path)
        except (OSError, ezdxf.DXFError) as exc:
            return [failed(path, self.host, "read", f"ezdxf cannot read it: {str(exc).splitlines()[0]}")]
        msp = doc.modelspace()
        splines = msp.query(f'SPLINE[layer=="{CURVE_LAYER}"]')
        kind = "LWPOLYLINE" if spline.dim == 2 else "POLYLINE"
        polylines = msp.query(f'{kind}[layer=="{POLYGON_LAYER}"]')
        checks = [expect_equal(path, self.host, f"one SPLINE on {CURVE_LAYER}", len(splines), 1),
                  expect_equal(path, self.host, f"one {kind} on {POLYGON_LAYER}", len(polylines), 1)]
        if len(splines) == 1:
            s = splines[0]
            params = spline.params(SAMPLES_PER_SPAN)
            try:
                tool = s.construction_tool()
                samples = np.array([tool.point(float(u)) for u in params])
            except (ValueError, IndexError, ZeroDivisionError, ezdxf.DXFError) as exc:
                checks.append(failed(path, self.host, "curve samples", f"ezdxf cannot evaluate it: {exc}"))
                samples = None
            checks.append(expect_equal(path, self.host, "planar flag", bool(s.dxf.flags & _PLANAR), spline.dim == 2))
            checks += curve_checks(path, self.host, spline, params, degree=s.dxf.degree, rational=len(s.weights) > 0,
                                   poles=np.array(s.control_points), knots=np.array(s.knots), samples=samples,
                                   closed=bool(s.dxf.flags & _CLOSED))
        if len(polylines) == 1:
            line = polylines[0]
            pts = (np.array([(x, y) for x, y, *_ in line.get_points()]) if spline.dim == 2
                   else np.array([tuple(v.dxf.location) for v in line.vertices]))
            checks.append(measured(path, self.host, "control polygon", point_deviation(pts, spline.poles),
                                   EXACT_TOL * spline.scale))
        return checks
