"""Real curves for the curve benchmark, built only from data shipped in installed packages (no downloads).

* glyph outlines: matplotlib's DejaVu Sans through :class:`matplotlib.textpath.TextPath` (straight edges,
  corners, closed contours; the outer contour of each letter, its Bezier pieces sampled by arc length);
* airfoils: coordinate files of the UIUC database shipped by ``aerosandbox`` (read as text, the package is
  not imported);
* image contours: ``skimage.data.horse()`` through ``skimage.measure.find_contours``;
* a map contour: matplotlib's sample DEM ``jacksboro_fault_dem.npz``;
* a 3D curve: a circle draped over that DEM (z = elevation);
* long inputs: the horse contour resampled on its Catmull-Rom model to 10^5 points.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from pathlib import Path

import numpy as np

from gsr_cad.geometry.distance import data_model

GLYPH_SPACING = 1.0 / 1500  # glyph samples: this fraction of the outline's length apart (vertices kept)


def _resample_pieces(pieces: list[np.ndarray], spacing: float) -> np.ndarray:
    out = []
    for piece in pieces:
        length = float(np.linalg.norm(np.diff(piece, axis=0), axis=1).sum())
        k = max(1, int(np.ceil(length / spacing)))
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(piece, axis=0), axis=1))])
        u = np.linspace(0.0, s[-1], k, endpoint=False)
        out.append(np.column_stack([np.interp(u, s, piece[:, d]) for d in range(2)]))
    return np.vstack(out)


def glyph(char: str) -> np.ndarray:
    """The outer contour of a DejaVu Sans glyph, closed, about 1500 points (first point not repeated)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.path import Path as MplPath
    from matplotlib.textpath import TextPath

    path = TextPath((0, 0), char, size=100, prop=FontProperties(family="DejaVu Sans"))
    contours: list[list[np.ndarray]] = []
    for segment, code in path.iter_bezier():
        if code == MplPath.MOVETO:
            contours.append([])
            continue
        if code == MplPath.CLOSEPOLY or not contours:
            continue
        t = np.linspace(0.0, 1.0, 2 if code == MplPath.LINETO else 65)
        contours[-1].append(segment(t))
    lengths = [sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in c) for c in contours]
    outer = contours[int(np.argmax(lengths))]
    pts = _resample_pieces(outer, max(lengths) * GLYPH_SPACING)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9])
    pts = pts[keep]
    return pts[:-1] if np.linalg.norm(pts[-1] - pts[0]) < 1e-9 else pts


def airfoil(name: str) -> np.ndarray:
    """Coordinates of a UIUC airfoil file shipped by aerosandbox (Selig order: TE, upper, LE, lower, TE)."""
    spec = importlib.util.find_spec("aerosandbox")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("aerosandbox is not installed (pip install -e .[bench])")
    path = Path(spec.submodule_search_locations[0]) / "geometry" / "airfoil" / "airfoil_database" / f"{name}.dat"
    rows = []
    for line in path.read_text().splitlines():
        cells = line.split()
        try:
            rows.append([float(cells[0]), float(cells[1])])
        except (ValueError, IndexError):
            continue
    pts = np.asarray(rows)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12])
    return pts[keep]


def horse() -> np.ndarray:
    """The longest iso-contour (level 0.5) of scikit-image's horse silhouette, closed."""
    from skimage import data, measure

    contour = max(measure.find_contours(data.horse().astype(float), 0.5), key=len)
    return contour[:-1, ::-1] * [1.0, -1.0]


def _dem() -> np.ndarray:
    from matplotlib import cbook

    with cbook.get_sample_data("jacksboro_fault_dem.npz") as dem:
        return np.asarray(dem["elevation"], dtype=float)


def dem_contour() -> np.ndarray:
    """The longest 700 m contour of matplotlib's Jacksboro fault DEM (grid units)."""
    from skimage import measure

    contour = max(measure.find_contours(_dem(), 700.0), key=len)
    if np.linalg.norm(contour[0] - contour[-1]) < 1e-12:
        contour = contour[:-1]
    return contour[:, ::-1]


def dem_circle_3d(n: int = 2000) -> np.ndarray:
    """A circle of radius 120 grid cells draped over the DEM: (x, y, elevation / 10), closed."""
    from scipy.ndimage import map_coordinates

    z = _dem()
    th = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    x, y = 200.0 + 120.0 * np.cos(th), 172.0 + 120.0 * np.sin(th)
    return np.column_stack([x, y, map_coordinates(z, [y, x], order=3) / 10.0])


def horse_long(n: int = 100_000) -> np.ndarray:
    """The horse contour resampled by arc length on its Catmull-Rom model to ``n`` points."""
    base = horse()
    model = data_model(base, closed=True, per_segment=16)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(model, axis=0), axis=1))])
    u = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.column_stack([np.interp(u, s, model[:, d]) for d in range(2)])


CASES: dict[str, Callable[[], np.ndarray]] = {
    "glyph_L": lambda: glyph("L"),
    "glyph_E": lambda: glyph("E"),
    "glyph_V": lambda: glyph("V"),
    "glyph_S": lambda: glyph("S"),
    "glyph_8": lambda: glyph("8"),
    "glyph_O": lambda: glyph("O"),
    "airfoil_e387": lambda: airfoil("e387"),
    "airfoil_naca4412": lambda: airfoil("naca4412"),
    "horse": horse,
    "dem_contour": dem_contour,
    "dem_circle_3d": dem_circle_3d,
    "horse_1e5": horse_long,
}
