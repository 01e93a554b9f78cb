"""Curve export benchmark: real curves (open, closed, cornered, 3D) through every export format and its host.

Each case is reconstructed with ``max_distance`` (default 1e-3 of the diagonal), exported in every installed
format (``gsr_cad.export``: SVG and OpenSCAD skip 3D curves with a warning) and validated
(``gsr_cad.validate``: OCP, FreeCAD, ezdxf, Blender, CadQuery, svgelements and OpenSCAD re-read the files).
The table gives, per case and format, the largest deviation of the host's own evaluation of the curve from
ours (relative to ``max(1, largest coordinate)``), or the stroke's for OpenSCAD (relative to its half width,
which it must stay within), and the number of failed checks; ``-`` where a format does not carry the case.

    python benchmarks/curve_exports.py            # -> benchmarks/results/curve_exports.md
    python benchmarks/curve_exports.py --cases glyph_L helix
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import gsr_cad
from gsr_cad.atomic import write_text
from gsr_cad.errors import GsrWarning
from gsr_cad.exporters.model import curve_spline
from gsr_cad.exporters.openscad import stroke_width

sys.path.insert(0, str(Path(__file__).resolve().parent))  # _common, real_curves
from _common import command, environment, load_average, markdown_table  # noqa: E402
from real_curves import CASES as REAL  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "curve_exports.md"
FILES = {"step": "curve.step", "dxf": "curve.dxf", "svg": "curve.svg", "scad": "curve.scad",
         "fcmacro": "curve.FCMacro", "blender": "curve_blender.py", "cadquery": "curve_cadquery.py"}
SAMPLE_CHECKS = ("curve samples", "Bezier samples", "evaluated points")


def helix() -> np.ndarray:
    """An open space curve: two turns of a helix, 300 points."""
    t = np.linspace(0.0, 4.0 * np.pi, 300)
    return np.c_[np.cos(t), np.sin(t), 0.2 * t]


def open_e() -> np.ndarray:
    """An open curve with corners: the first 70 % of the outline of the glyph E."""
    points = REAL["glyph_E"]()
    return points[: int(0.7 * len(points))]


CASES = {"glyph_L": REAL["glyph_L"], "glyph_S": REAL["glyph_S"], "glyph_E_open": open_e,
         "dem_circle_3d": REAL["dem_circle_3d"], "helix": helix}


def _cell(checks: list, file: str, spline) -> str:
    mine = [c for c in checks if c.file == file]
    if not mine:
        return "-"
    fails = sum(c.status == "FAIL" for c in mine)
    if file.endswith(".scad"):
        dev = [c.deviation for c in mine if "within half width of our curve" in c.check and c.deviation is not None]
        value = f"{max(dev) / (stroke_width(spline) / 2):.3f} hw" if dev else "?"
    else:
        dev = [c.deviation for c in mine if c.check.endswith(SAMPLE_CHECKS) and c.deviation is not None]
        value = f"{max(dev) / spline.scale:.1e}" if dev else "?"
    return value + ("" if not fails else f" ({fails} FAIL)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES))
    parser.add_argument("--max-distance", type=float, default=1e-3)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    load = load_average()
    rows = []
    for name in args.cases:
        t0 = time.perf_counter()
        result = gsr_cad.reconstruct_curve(CASES[name](), seed=1, max_distance=args.max_distance)
        fit = time.perf_counter() - t0
        spline = curve_spline(result)
        with tempfile.TemporaryDirectory() as tmp:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", GsrWarning)
                gsr_cad.export(result, tmp)
            result.save(tmp)
            t1 = time.perf_counter()
            checks = gsr_cad.validate(tmp)
            seconds = time.perf_counter() - t1
        form = ", ".join(w for w, on in (("closed", spline.closed), ("corners", bool(spline.corners)),
                                          ("3D", spline.dim == 3)) if on) or "open"
        rows.append([name, form, str(len(result.control_points)), *(_cell(checks, f, spline) for f in FILES.values()),
                     f"{sum(c.status == 'pass' for c in checks)}/{len(checks)}", f"{fit:.0f}", f"{seconds:.0f}"])
        print(" | ".join(rows[-1]), flush=True)
    header = ["case", "form", "poles", *FILES, "checks passed", "fit s", "validate s"]
    lines = [f"# Curve exports on real curves ({command('curve_exports.py', argv or [])})", "",
             f"{environment(load)}; times are wall-clock on a shared machine.", "",
             "Host evaluation of the exported curve against ours, largest deviation relative to max(1, largest "
             "coordinate) (Blender: single precision); scad: the rendered stroke's farthest vertex from our curve "
             "in half widths (at most 1 + chord sag); `-`: the format does not carry the case (3D in SVG/SCAD).",
             "", *markdown_table(header, rows, right={"poles", "fit s", "validate s"}), ""]
    write_text(args.out, "\n".join(lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
