"""SVG export: the curve as its exact Bezier pieces in one path, plus the dashed control polygon.

A clamped cubic B-spline is a chain of cubic Beziers (``C``) and the Chaikin limit a chain of quadratic ones
(``Q``), one per knot span, corners included, so the path *is* the curve, not an approximation; a closed
curve's path ends with ``Z``. SVG is planar: 3D curves are refused (``curve_dims``). Coordinates are written as our
numbers (shortest exact text) inside a ``scale(1 -1)`` group, so y points up as in the data; the viewBox
fits the control polygon with a 5 % margin. Validation parses the file with svgelements (an independent
SVG reader that applies viewBox and transforms), maps its page coordinates back through the view we
meant to write, and compares Bezier points and control points with ours.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from gsr_cad.atomic import write_text
from gsr_cad.errors import ExportError

from .base import (EXACT_TOL, SAMPLE_TOL, Check, Exporter, expect_equal, failed,
                   measured, num, point_deviation, skipped)
from .model import CurveSpline, curve_model

PAGE_PX = 800.0
MARGIN = 0.05
SAMPLES_PER_SPAN = 16
_COMMANDS = {2: "Q", 3: "C"}


@dataclasses.dataclass(frozen=True)
class View:
    """The drawing window in our coordinates and its size on the page (pixels, y down)."""

    x0: float
    y1: float
    width: float
    height: float
    px: float

    @property
    def page(self) -> tuple[float, float]:
        return self.width * self.px, self.height * self.px

    def to_user(self, page_xy: np.ndarray) -> np.ndarray:
        """Page pixels back to our coordinates (undoing the viewBox scale and the y flip)."""
        p = np.asarray(page_xy, dtype=float)
        return np.column_stack([self.x0 + p[:, 0] / self.px, self.y1 - p[:, 1] / self.px])


def view_of(spline: CurveSpline) -> View:
    """The viewBox: the control polygon's box (which holds the curve) grown by 5 % of its diagonal."""
    lo, hi = spline.poles.min(axis=0), spline.poles.max(axis=0)
    m = MARGIN * spline.diagonal
    w, h = float(hi[0] - lo[0] + 2 * m), float(hi[1] - lo[1] + 2 * m)
    return View(float(lo[0] - m), float(hi[1] + m), w, h, PAGE_PX / max(w, h))


def path_data(spline: CurveSpline) -> str:
    """The SVG path ``d`` of the curve: ``M`` then one ``C`` (cubic) or ``Q`` (quadratic) per knot span, and
    ``Z`` when the curve is closed (its last piece already ends on the first point: the close is a join)."""
    if spline.degree not in _COMMANDS:
        raise ExportError(f"SVG paths hold quadratic or cubic Beziers only, not degree {spline.degree}")
    pieces = spline.bezier()
    parts = [f"M {num(pieces[0, 0, 0])} {num(pieces[0, 0, 1])}"]
    cmd = _COMMANDS[spline.degree]
    for piece in pieces:
        parts.append(cmd + " " + " ".join(f"{num(x)} {num(y)}" for x, y in piece[1:]))
    return " ".join(parts + (["Z"] if spline.closed else []))


class SvgExporter(Exporter):
    """``*.svg``: exact Bezier path of the curve and the dashed control polygon, y up."""

    name = "svg"
    kinds = ("curve",)
    suffixes = (".svg",)
    host = "svgelements"
    curve_dims = (2,)

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        spline = curve_model(result).spline
        view = view_of(spline)
        d = spline.diagonal
        page_w, page_h = view.page
        points = " ".join(f"{num(x)},{num(y)}" for x, y in spline.poles)
        dots = "\n".join(f'    <circle cx="{num(x)}" cy="{num(y)}" r="{num(0.004 * d)}"/>' for x, y in spline.poles)
        scheme = escape(result.scheme)
        svg = f"""<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{num(page_w)}" height="{num(page_h)}"
     viewBox="{num(view.x0)} {num(-view.y1)} {num(view.width)} {num(view.height)}">
  <title>{escape(stem)}: {scheme} curve of degree {spline.degree}, {len(spline.poles)} control points</title>
  <g transform="scale(1 -1)" fill="none" stroke-linecap="round" stroke-linejoin="round">
    <polyline id="control_polygon" points="{points}" stroke="#888888" stroke-width="{num(0.002 * d)}"
              stroke-dasharray="{num(0.012 * d)} {num(0.008 * d)}"/>
    <g id="control_points" fill="#888888" stroke="none">
{dots}
    </g>
    <path id="curve" d="{path_data(spline)}" stroke="#d62728" stroke-width="{num(0.004 * d)}"/>
  </g>
</svg>
"""
        return [write_text(out_dir / self.filename(stem), svg)]

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if importlib.util.find_spec("svgelements") is None:
            return [skipped(path, self.host, "read", "svgelements is not installed (it comes with build123d)")]
        import svgelements as se

        spline = curve_model(result).spline
        view = view_of(spline)
        try:
            svg = se.SVG.parse(str(path), reify=False)
        except Exception as exc:  # svgelements raises whatever its XML/number parsing raises
            return [failed(path, self.host, "read", f"svgelements cannot parse it: {exc}")]
        curve = svg.get_element_by_id("curve")
        polygon = svg.get_element_by_id("control_polygon")
        checks = [expect_equal(path, self.host, "path #curve", type(curve).__name__, "Path"),
                  expect_equal(path, self.host, "polyline #control_polygon", type(polygon).__name__, "Polyline")]
        if isinstance(curve, se.Path):
            checks += self._check_path(path, curve, spline, view, se)
        if isinstance(polygon, se.Polyline):
            page = [polygon.transform.point_in_matrix_space(p) for p in polygon.points]
            got = view.to_user(np.array([[p.x, p.y] for p in page])) if page else np.empty((0, 2))
            checks.append(measured(path, self.host, "control polygon", point_deviation(got, spline.poles),
                                   EXACT_TOL * spline.scale))
        return checks

    def _check_path(self, path: Path, curve: Any, spline: CurveSpline, view: View, se: Any) -> list[Check]:
        kind = se.CubicBezier if spline.degree == 3 else se.QuadraticBezier
        segments = [s for s in curve if not isinstance(s, (se.Move, se.Close))]
        closes = [i for i, s in enumerate(curve) if isinstance(s, se.Close)]
        checks = [expect_equal(path, self.host, f"{kind.__name__} segments",
                               (len(segments), all(isinstance(s, kind) for s in segments)), (spline.n_spans, True)),
                  expect_equal(path, self.host, "closed path (Z at the end)" if spline.closed else "open path",
                               closes, [len(curve) - 1] if spline.closed else [])]
        if not checks[0].passed:
            return checks
        t = np.linspace(0.0, 1.0, SAMPLES_PER_SPAN + 1)
        page = [curve.transform.point_in_matrix_space(s.point(float(u))) for s in segments for u in t]
        got = view.to_user(np.array([[p.x, p.y] for p in page]))
        params = ((np.arange(spline.n_spans)[:, None] + t[None, :]) / spline.n_spans).ravel()
        checks.append(measured(path, self.host, f"{len(params)} Bezier samples",
                               point_deviation(got, spline.points(params)), SAMPLE_TOL * spline.scale))
        return checks
