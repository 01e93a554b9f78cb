"""OpenSCAD export (format "scad"): a curve as a 2-D stroke, a surface as a polyhedron of its limit mesh.

The ``.scad`` files are :mod:`~gsr_cad.exporters.hostside` ``curve.scad`` and ``surface.scad`` with their
data lines filled by the literal encoder (numbers and vectors of numbers only; comment lines reduced to a
safe character set, so nothing can leave a comment). By default each renders the part: the curve's stroke
or the limit surface; the control polygon or cage is a module drawn only when asked
(``-D 'part="both"'``, ``"control_polygon"``, ``"cage"``, ``"cage_solid"``).

Curves: OpenSCAD has no spline primitive, so the file carries the curve sampled finely enough that the
chords stay within 1 % of the default stroke width of it; module ``gsr_curve(width)`` offsets every chord
by ``width / 2`` to both sides and joins neighbours with bevels, a union that stays right where the curve
crosses itself (one offset outline would not). ``height`` > 0 extrudes the drawing for STL. OpenSCAD snaps
2-D geometry to a 1/65536 grid, so the modules draw at ``gsr_unit`` (a power of ten making the diagonal
>= 1000) times the size and scale the result back; it still writes 6 significant digits, so coordinates far
from the origin relative to the curve's size lose precision in its STL/DXF/SVG output.

Validation renders ``part="curve"`` and ``part="control_polygon"`` extruded to STL with ``openscad`` and
checks that the solids are non-empty, that every vertex lies within half the stroke width of our exact
curve (or control polygon), that our curve (control points) lies inside the rendered footprint and, for a
closed curve, that the stroke is joined at its seam (no notch there); for surfaces, the limit mesh and the
cage solid.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from gsr_cad.errors import ExportError
from gsr_cad.geometry import distance
from gsr_cad.geometry.polymesh import PolyMesh

from . import hosts
from .base import Check, Exporter, expect_equal, failed, measured, num, scratch_dir, skipped
from .encode import fill_scad
from .model import CurveSpline, SurfaceModel, curve_model, same_mesh, surface_model, triangle_faces

WIDTH_FRACTION = 0.01
SAG_FRACTION = 0.01
MAX_PER_SPAN = 1024
_HEIGHT = 1.0
_DIGITS_TOL = 1e-5  # OpenSCAD writes 6 significant digits
_GRID = 2.0 ** -16  # and snaps 2-D geometry to this grid (in drawing units)


def stroke_width(spline: CurveSpline) -> float:
    """Default stroke width: 1 % of the control polygon's diagonal."""
    return WIDTH_FRACTION * spline.diagonal


def stroke_samples(spline: CurveSpline, width: float) -> np.ndarray:
    """Curve samples whose chords deviate from the curve by at most ``SAG_FRACTION * width`` (per-span
    count doubled from 16 until the midpoint sag is small enough, at most ``MAX_PER_SPAN``)."""
    per = 16
    while True:
        u = spline.params(per)
        pts = spline.points(u)
        mid = spline.points(0.5 * (u[:-1] + u[1:]))
        chord = pts[1:] - pts[:-1]
        len2 = np.einsum("ij,ij->i", chord, chord)
        s = np.clip(np.divide(np.einsum("ij,ij->i", mid - pts[:-1], chord), len2, out=np.zeros(len(len2)),
                              where=len2 > 0), 0.0, 1.0)
        sag = np.linalg.norm(mid - pts[:-1] - s[:, None] * chord, axis=1).max()
        if sag <= SAG_FRACTION * width or per >= MAX_PER_SPAN:
            return pts
        per *= 2


def drawing_unit(spline: CurveSpline) -> int:
    """A power of ten that makes the drawing's diagonal at least 1000 (OpenSCAD's grid is 1/65536)."""
    return 10 ** max(0, math.ceil(math.log10(1000.0 / spline.diagonal)))


def distinct(points: np.ndarray) -> np.ndarray:
    """Drop consecutive repeats (zero-length segments have no normal); ExportError when no length is left."""
    p = np.asarray(points, dtype=float)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    p = p[np.concatenate([[True], step > 1e-12 * max(1.0, float(np.abs(p).max()))])]
    if len(p) < 2:
        raise ExportError("the curve has no length: nothing to stroke")
    return p


def seam_joins(spline: CurveSpline, width: float) -> np.ndarray:
    """The centroids of the two bevel triangles that join a closed stroke at its seam (the ``gsr_closed`` join
    of curve.scad), on the samples the file carries: a stroke joined there covers both, one left open has a
    notch on the outer side of the seam's turn."""
    p = distinct(stroke_samples(spline, width))
    ends = np.array([p[-1] - p[-2], p[1] - p[0]])
    normals = np.c_[-ends[:, 1], ends[:, 0]] / np.linalg.norm(ends, axis=1)[:, None]
    offset = (width / 2) * normals.sum(axis=0) / 3
    return np.array([p[0] + offset, p[0] - offset])


def footprint_distance(points: np.ndarray, tri: np.ndarray, chunk: int = 256) -> np.ndarray:
    """Distance of each 2-D point to the union of triangles ``(t, 3, 2)``: 0 inside, else to the nearest edge."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1 = b - a, c - a
    den = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    ok = np.abs(den) > 0
    den = np.where(ok, den, 1.0)
    inside = np.zeros(len(points), dtype=bool)
    for start in range(0, len(points), chunk):
        w = points[start:start + chunk, None, :] - a[None]
        s = (w[..., 0] * v1[:, 1] - w[..., 1] * v1[:, 0]) / den
        t = (v0[:, 0] * w[..., 1] - v0[:, 1] * w[..., 0]) / den
        inside[start:start + chunk] = ((s >= 0) & (t >= 0) & (s + t <= 1) & ok).any(axis=1)
    out = np.zeros(len(points))
    if not inside.all():
        ea = np.concatenate([a, b, c])
        ab = np.concatenate([b, c, a]) - ea
        len2 = np.maximum(np.einsum("ij,ij->i", ab, ab), np.finfo(float).tiny)
        q = points[~inside]
        d = np.empty(len(q))
        for start in range(0, len(q), chunk):
            w = q[start:start + chunk, None, :] - ea[None]
            s = np.clip(np.einsum("qed,ed->qe", w, ab) / len2, 0.0, 1.0)
            d[start:start + chunk] = np.linalg.norm(w - s[..., None] * ab[None], axis=2).min(axis=1)
        out[~inside] = d
    return out


class OpenscadExporter(Exporter):
    """``*.scad``: a curve as a stroke of configurable width plus the control polygon; a surface as a
    polyhedron of its limit mesh plus the control cage; each as modules."""

    name = "scad"
    kinds = ("curve", "surface")
    suffixes = (".scad",)
    host = "openscad"
    curve_dims = (2,)

    def render_curve(self, result: Any, stem: str) -> dict[str, str]:
        spline = curve_model(result).spline
        width = stroke_width(spline)
        points = distinct(stroke_samples(spline, width))
        title = (f"{len(spline.poles)} control points, {result.scheme} curve of degree {spline.degree}, "
                 f"{len(points)} samples")
        text = fill_scad("curve.scad", {"width": float(width), "gsr_curve_points": points.tolist(),
                                        "gsr_control_points": spline.poles.tolist(), "gsr_closed": spline.closed,
                                        "gsr_unit": int(drawing_unit(spline))}, {"title": [title]})
        return {self.filename(stem): text}

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("openscad"):
            return [skipped(path, self.host, "render", reason)]
        spline = curve_model(result).spline
        width = stroke_width(spline)
        checks: list[Check] = []
        with scratch_dir() as tmp:
            for part, half, sag, ours, inner in (
                    ("curve", width / 2, 2 * SAG_FRACTION * width, "curve", spline.points(spline.params(32))),
                    ("control_polygon", width / 6, 0.0, "control polygon", spline.poles)):
                stl = tmp / f"{part}.stl"
                try:
                    hosts.run_openscad(path, stl, timeout=120, defines={"part": f'"{part}"', "width": num(width),
                                                                        "height": num(_HEIGHT)})
                    mesh = _load_stl(stl, allow_empty=True)
                except ExportError as exc:
                    checks.append(failed(path, self.host, f"render {part}", str(exc)))
                    continue
                checks += self._compare(path, part, ours, half, sag, np.asarray(mesh.vertices, dtype=float),
                                        np.asarray(mesh.faces, dtype=np.int64), inner, spline,
                                        seam_joins(spline, width) if part == "curve" and spline.closed else None)
        return checks

    def _compare(self, path: Path, part: str, ours: str, half: float, sag: float, vertices: np.ndarray,
                 triangles: np.ndarray, inner: np.ndarray, spline: CurveSpline,
                 seam: np.ndarray | None = None) -> list[Check]:
        """The rendered solid against our curve or polygon; with ``seam`` (:func:`seam_joins`), also that the
        closed stroke is joined at its seam (both join points inside the footprint)."""
        if len(triangles) == 0:
            return [failed(path, self.host, f"{part} solid", "OpenSCAD rendered nothing")]
        rounding = _DIGITS_TOL * float(np.abs(spline.poles).max()) + _GRID / drawing_unit(spline)
        xy = vertices[:, :2]
        dist = distance.point_to_polyline(xy, spline.dense(256) if part == "curve" else spline.poles)
        z = vertices[:, 2]
        bottom = triangles[np.all(np.abs(z[triangles]) <= rounding, axis=1)]

        def outside(points: np.ndarray) -> float:
            return float(footprint_distance(points, xy[bottom]).max()) if len(bottom) else math.inf

        checks = [
            measured(path, self.host, f"{part}: extrusion height", float(abs(np.ptp(z) - _HEIGHT)), rounding),
            measured(path, self.host, f"{part}: vertices within half width of our {ours}", float(dist.max()),
                     half + sag + rounding, f"half width {half:.3g} + chord sag {sag:.2g}"),
            measured(path, self.host, f"{part}: our {ours} inside the footprint", outside(inner), rounding,
                     f"{len(inner)} points; deviation = farthest outside"),
        ]
        if seam is not None:
            checks.append(measured(path, self.host, f"{part}: joined at the seam", outside(seam), rounding,
                                   "the seam's bevel join inside the footprint; deviation = farthest outside"))
        return checks

    def render_surface(self, result: Any, stem: str) -> dict[str, str]:
        return {self.filename(stem): surface_scad(surface_model(result))}

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("openscad"):
            return [skipped(path, self.host, "render", reason)]
        try:
            model = surface_model(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        centre = scad_centre(model)
        checks: list[Check] = []
        with scratch_dir() as tmp:
            meshes = {}
            for part in ("surface", "cage_solid"):
                stl = tmp / f"{part}.stl"
                try:
                    hosts.run_openscad(path, stl, timeout=300, defines={"part": f'"{part}"', "place": "false"},
                                       options=("--export-format", "binstl"))
                    meshes[part] = _load_stl(stl)
                except ExportError as exc:
                    checks.append(failed(path, self.host, f"render {part}", str(exc)))
        if "surface" in meshes:
            checks += self._compare_surface(path, model, centre, meshes["surface"])
        if "cage_solid" in meshes:
            got = np.asarray(meshes["cage_solid"].vertices, dtype=float)
            ours = model.control.vertices - centre
            dev = max(float(cKDTree(ours).query(got)[0].max()), float(cKDTree(got).query(ours)[0].max())) \
                if len(got) else math.inf
            checks.append(measured(path, self.host, "control cage vertices", dev / model.diagonal, SURFACE_TOL,
                                   f"{model.control.n_vertices} vertices, both ways, relative to the diagonal"))
        return checks

    def _compare_surface(self, path: Path, model: SurfaceModel, centre: np.ndarray, mesh: Any) -> list[Check]:
        host, diag = self.host, model.diagonal
        ours = model.limit
        tri = PolyMesh.from_faces(ours.vertices - centre, triangle_faces(ours))
        want_volume = _signed_volume(tri.vertices, np.asarray(tri.faces))
        checks = [
            expect_equal(path, host, "watertight", bool(mesh.is_watertight), True),
            expect_equal(path, host, "volume sign", bool(mesh.volume > 0), True),
            measured(path, host, "volume", abs(float(mesh.volume) - want_volume) / max(abs(want_volume), 1e-300),
                     SURFACE_TOL, f"relative to ours ({want_volume:.6g}); tolerance {SURFACE_TOL:.3g}"),
        ]
        dev, problem = same_mesh(tri, np.asarray(mesh.vertices), np.asarray(mesh.faces).tolist())
        label = f"limit mesh (level {model.levels}) vertices and triangles"
        if problem:
            return checks + [failed(path, host, label, problem)]
        return checks + [measured(path, host, label, dev / diag, SURFACE_TOL,
                                  f"{ours.n_vertices} vertices, relative to the diagonal; tolerance {SURFACE_TOL:.3g}")]


SURFACE_TOL = 1e-6
"""Surface vertices read back from OpenSCAD's binary STL (single precision), relative to the diagonal."""
CAGE_WIDTH_FRACTION = 0.005


def scad_centre(model: SurfaceModel) -> np.ndarray:
    """The point the ``.scad`` stores coordinates relative to: the limit mesh's bounding-box centre."""
    return model.limit.bbox.mean(axis=0)


def _signed_volume(v: np.ndarray, tri: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", v[tri[:, 0]], np.cross(v[tri[:, 1]], v[tri[:, 2]])).sum() / 6.0)


def surface_scad(model: SurfaceModel) -> str:
    """The ``.scad`` text of a surface: limit-mesh polyhedron, control cage and history listing."""
    centre = scad_centre(model)
    limit, cage = model.limit, model.control
    tris = [list(t[::-1]) for t in triangle_faces(limit)]
    edges = sorted({(min(u, v), max(u, v)) for f in cage.faces for u, v in zip(f, f[1:] + f[:1])})
    title = (f"{cage.n_faces} control faces, {model.levels} subdivision levels, {limit.n_vertices} limit points, "
             f"{len(tris)} triangles, {len(model.labels) - 1} ops")
    return fill_scad("surface.scad", {
        "width": float(CAGE_WIDTH_FRACTION * model.diagonal), "gsr_centre": centre.tolist(),
        "gsr_limit_points": (limit.vertices - centre).tolist(), "gsr_limit_faces": tris,
        "gsr_cage_points": (cage.vertices - centre).tolist(), "gsr_cage_faces": [list(f[::-1]) for f in cage.faces],
        "gsr_cage_edges": [list(e) for e in edges]},
        {"title": [title], "history": [f"  {label}" for label in model.labels]})


def _load_stl(path: Path, allow_empty: bool = False) -> Any:
    """OpenSCAD's STL as a trimesh (vertices merged); ExportError when unreadable or (unless
    ``allow_empty``) empty."""
    import trimesh

    try:
        mesh = trimesh.load(str(path), file_type="stl", force="mesh", process=True)
    except Exception as exc:  # trimesh raises assorted errors on broken files
        raise ExportError(f"cannot read OpenSCAD's STL: {exc}") from None
    if len(mesh.faces) == 0 and not allow_empty:
        raise ExportError("OpenSCAD rendered nothing")
    return mesh
