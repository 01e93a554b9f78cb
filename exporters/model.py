"""What every exporter sees of a result: one model per result, built from its single replay.

A :class:`~gsr_cad.reconstruct.result.Result` already holds the genome's replay (``result.states``: the
template and the geometry after every op). :func:`curve_model` and :func:`surface_model` label those
states, derive the B-spline, the limit mesh and (lazily, once) the limit-surface patches, and keep the
model on the result, so an export run and a validation run each build it once for all exporters.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from gsr_cad.errors import ExportError, GsrError
from gsr_cad.geometry import bspline
from gsr_cad.geometry.patches import PatchSet, limit_patches
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import limit_mesh

PATCH_TOLERANCE = 1e-4
"""Default largest deviation of the limit-surface patches from the limit surface, relative to its diagonal."""
_CACHE = "_gsr_export_model"


@dataclasses.dataclass(frozen=True)
class CurveSpline:
    """A curve result as CAD sees it: poles (2-D or 3-D), degree and the clamped knot vector on [0, 1]
    (uniform, or with repeated knots at corners and where a closed curve was cut open; see
    ``bspline.clamped_form``). ``control``, ``closed`` and ``corners`` keep the form it came from, so a host
    that holds periodic curves gets :meth:`periodic_form` (the control points themselves)."""

    poles: np.ndarray
    degree: int
    knots: np.ndarray
    closed: bool = False
    corners: tuple[int, ...] = ()
    control: np.ndarray | None = None

    @property
    def dim(self) -> int:
        """2 for a planar (x, y) curve, 3 for a space curve."""
        return int(self.poles.shape[1])

    @property
    def breakpoints(self) -> np.ndarray:
        """Distinct knot values."""
        return np.unique(self.knots)

    @property
    def multiplicities(self) -> np.ndarray:
        """Multiplicity of each distinct knot."""
        return np.unique(self.knots, return_counts=True)[1]

    @property
    def n_spans(self) -> int:
        return len(self.breakpoints) - 1

    @property
    def scale(self) -> float:
        """``max(1, largest absolute coordinate)``: the unit of every tolerance."""
        return max(1.0, float(np.max(np.abs(self.poles))))

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the control polygon (1 when it is a point)."""
        d = float(np.linalg.norm(np.ptp(self.poles, axis=0)))
        return d if d > 0 else 1.0

    def points(self, params: np.ndarray) -> np.ndarray:
        """Our curve at ``params`` in [0, 1]."""
        return np.asarray(BSpline(self.knots, self.poles, self.degree)(np.asarray(params, dtype=float)))

    def bezier(self) -> np.ndarray:
        """Exact Bezier pieces ``(n_spans, degree + 1, dim)``, one per knot span, in order."""
        return bspline.bezier_pieces(self.knots, self.poles, self.degree)

    def params(self, per_span: int) -> np.ndarray:
        """``per_span`` parameters per knot span, both ends included."""
        return np.linspace(0.0, 1.0, self.n_spans * per_span + 1)

    def dense(self, per_span: int = 64) -> np.ndarray:
        """A polyline close to the curve (for stroke widths, not for exact comparisons)."""
        return self.points(self.params(per_span))

    def periodic_forms(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The exact periodic representations ``(poles, distinct knots, multiplicities)`` of a closed curve on
        [0, 1] (OCCT's convention: first and last multiplicity equal, poles = their sum minus the last): the
        control points with the form's knots of one period (what a host given the periodic curve holds), and
        the clamped form with its repeated end pole dropped (what a STEP reader makes of our clamped closed
        curve). Empty for an open curve."""
        if not self.closed or self.control is None:
            return []
        k, n = self.degree, len(self.control)
        t = bspline.form_knots(n, k, True, self.corners)
        zeros = np.flatnonzero(t == 0.0)
        values, mults = np.unique(t[k:k + n + 1], return_counts=True)
        mults[0] = mults[-1] = len(zeros)
        # a knot of multiplicity m at 0 with j of its copies after t[k] shifts the first pole by j
        own = (np.roll(self.control, -(int(zeros[-1]) - k), axis=0), values, mults)
        ends = self.multiplicities.copy()
        ends[0] = ends[-1] = k
        return [own, (self.poles[:-1], self.breakpoints, ends)]


def xyz(points: Any) -> np.ndarray:
    """Points as (x, y, z) rows: planar rows get z = 0, space rows are kept."""
    a = np.asarray(points, dtype=float)
    return np.column_stack([a, np.zeros(len(a))]) if a.ndim == 2 and a.shape[1] == 2 else a


def curve_spline(result: Any) -> CurveSpline:
    """The B-spline of a curve result; ExportError when it has too few or non-finite control points."""
    if result.kind != "curve" or result.control_points is None:
        raise ExportError(f"expected a curve result, got a {result.kind} result")
    poles = np.asarray(result.control_points, dtype=float)
    degree = int(result.degree)
    if poles.ndim != 2 or poles.shape[1] not in (2, 3) or not np.all(np.isfinite(poles)):
        raise ExportError("curve control points must be finite [x, y] or [x, y, z] rows")
    if len(poles) < degree + 1:
        raise ExportError(f"a degree-{degree} curve needs at least {degree + 1} control points, got {len(poles)}")
    cfg = result.config or {}
    closed, corners = bool(cfg.get("closed", False)), tuple(cfg.get("corners") or ())
    if not closed and not corners:
        return CurveSpline(poles, degree, bspline.clamped_uniform_knots(len(poles), degree), control=poles)
    try:  # closed (periodic) or cornered: its exact clamped form, corners as repeated knots
        knots, clamped = bspline.clamped_form(poles, degree, closed, corners)
    except GsrError as exc:
        raise ExportError(f"the curve's closed/corner form is invalid: {exc}") from None
    return CurveSpline(clamped, degree, knots, closed, tuple(int(c) for c in corners), poles)


@dataclasses.dataclass(frozen=True)
class HistoryStep:
    """The control polygon and its corners after one op (``op`` None for the template), with a readable label."""

    label: str
    op: dict[str, Any] | None
    points: np.ndarray
    corners: tuple[int, ...] = ()


def _fmt_pair(v: Sequence[float]) -> str:
    return "(" + ", ".join(f"{float(x):.4g}" for x in v) + ")"


def op_label(number: int, op: dict[str, Any] | None, width: int = 2) -> str:
    """``"03 add point 2 at (0.41, 0.77)"``: the step number, then the op in words."""
    head = f"{number:0{width}d}"
    if op is None:
        return f"{head} template"
    name = str(op.get("op", "op"))
    if name == "add_point":
        return f"{head} add point {op['index']} at {_fmt_pair(op['position'])}"
    if name == "move_point":
        return f"{head} move point {op['index']} by {_fmt_pair(op['delta'])}"
    if name == "corner":
        return f"{head} corner at point {op['index']}"
    fields = ", ".join(f"{k}={v}" for k, v in op.items() if k != "op")
    return f"{head} {name.replace('_', ' ')} {fields}".rstrip()


def require_ops(genome: Sequence[Any], known: Sequence[str], writer: str) -> None:
    """ExportError when ``genome`` (ops) holds an op kind the host script of ``writer`` cannot replay (a kind
    added to gsr_cad.ops after that script was written)."""
    unknown = sorted({op.name for op in genome} - set(known))
    if unknown:
        raise ExportError(f"the {writer} replays {', '.join(known)}, not {', '.join(unknown)}")


def _replayed(result: Any) -> tuple:
    if not result.states:
        raise ExportError("the result has no config.template: the modelling history cannot be replayed")
    return result.states


def curve_history(result: Any) -> list[HistoryStep]:
    """The template and the control polygon after every op of the result's replay, labelled."""
    states = _replayed(result)
    width = max(2, len(str(len(result.genome))))
    ops: list[dict[str, Any] | None] = [None, *(op.to_json() for op in result.genome)]
    return [HistoryStep(op_label(i, op, width), op, np.asarray(s.points), tuple(int(c) for c in s.corners))
            for i, (op, s) in enumerate(zip(ops, states))]


@dataclasses.dataclass(frozen=True)
class CurveModel:
    """A curve result for the exporters: its B-spline, its labelled history and its genome."""

    spline: CurveSpline
    history: tuple[HistoryStep, ...]
    genome: tuple = ()


def curve_model(result: Any) -> CurveModel:
    """The curve model of ``result`` (built once per result)."""
    cached = result.__dict__.get(_CACHE)
    if isinstance(cached, CurveModel):
        return cached
    model = CurveModel(curve_spline(result), tuple(curve_history(result)), tuple(result.genome))
    result.__dict__[_CACHE] = model
    return model


def surface_labels(genome: Sequence[Any]) -> list[str]:
    """``"00 template"``, then ``"03 extrude face 5 by 0.42"`` for every op (numbers padded to the genome)."""
    width = max(2, len(str(len(genome))))
    return [f"{0:0{width}d} template"] + [f"{i + 1:0{width}d} {op.describe()}" for i, op in enumerate(genome)]


@dataclasses.dataclass(frozen=True, eq=False)
class SurfaceModel:
    """A surface result as the exporters see it: the template, the control mesh after every op (labelled),
    the subdivision settings, the limit mesh and (on first use) the limit-surface patches."""

    labels: tuple[str, ...]
    ops: tuple[dict[str, Any] | None, ...]
    genome: tuple
    states: tuple[PolyMesh, ...]
    levels: int
    boundary: str
    limit: PolyMesh
    patch_options: tuple[float, str, int]

    @property
    def control(self) -> PolyMesh:
        return self.states[-1]

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the limit mesh: the unit of every surface tolerance."""
        d = self.limit.diagonal
        return d if d > 0 else 1.0

    @functools.cached_property
    def patches(self) -> PatchSet:
        """The limit patches (fitted once); ExportError when they miss the tolerance."""
        tol, boundary, level = self.patch_options
        try:
            patches = limit_patches(self.control, tol, boundary, level)
        except GsrError as exc:
            raise ExportError(f"cannot build the limit-surface patches: {str(exc).splitlines()[0]}") from None
        if not patches.within_tolerance:
            raise ExportError(f"the limit-surface patches deviate by {patches.max_deviation / patches.diagonal:.3g} "
                              f"of the diagonal, above the tolerance {tol:.3g} (raise config patch_tolerance or "
                              f"patch_max_level)")
        return patches


def surface_model(result: Any) -> SurfaceModel:
    """The surface model of ``result`` (built once per result); ExportError when it has no history."""
    cached = result.__dict__.get(_CACHE)
    if isinstance(cached, SurfaceModel):
        return cached
    if result.kind != "surface" or result.control_mesh is None:
        raise ExportError(f"expected a surface result, got a {result.kind} result")
    states = _replayed(result)
    cfg = result.config
    options = (float(cfg.get("patch_tolerance", PATCH_TOLERANCE)), result.boundary, int(cfg.get("patch_max_level", 5)))
    model = SurfaceModel(tuple(surface_labels(result.genome)), (None, *(op.to_json() for op in result.genome)),
                         tuple(result.genome), tuple(states), result.levels, result.boundary,
                         limit_mesh(states[-1], result.levels, result.boundary), options)
    result.__dict__[_CACHE] = model
    return model


def surface_patches(result: Any) -> PatchSet:
    """The limit patches of a surface result (see :attr:`SurfaceModel.patches`)."""
    return surface_model(result).patches


def patch_data(patch: Any) -> dict[str, Any]:
    """A B-spline patch as plain data for host scripts: poles[u][v], distinct knots and multiplicities, degrees."""
    (uk, um), (vk, vm) = patch.breakpoints_u, patch.breakpoints_v
    return {"poles": patch.poles.tolist(), "uknots": uk.tolist(), "umults": [int(m) for m in um],
            "vknots": vk.tolist(), "vmults": [int(m) for m in vm], "udegree": int(patch.degree_u),
            "vdegree": int(patch.degree_v)}


def triangle_faces(mesh: PolyMesh) -> list[tuple[int, int, int]]:
    """Fan triangles of every face, counter-clockwise seen from outside like the faces."""
    return [(f[0], f[i], f[i + 1]) for f in mesh.faces for i in range(1, len(f) - 1)]


def _canonical(cycle: Sequence[int]) -> tuple[int, ...]:
    i = int(np.argmin(cycle))
    return tuple(cycle[i:]) + tuple(cycle[:i])


def same_mesh(ours: PolyMesh, theirs_vertices: np.ndarray, theirs_faces: Sequence[Sequence[int]]) -> tuple[float, str]:
    """``(largest vertex distance, problem)`` between our mesh and one read back in any element order:
    every vertex is matched to its nearest, the match must be one-to-one and map faces onto faces (as
    oriented cycles). ``problem`` is "" when the structure agrees (the distance is then meaningful)."""
    tv = np.asarray(theirs_vertices, dtype=float).reshape(-1, 3)
    if len(tv) != ours.n_vertices or len(theirs_faces) != ours.n_faces:
        return math.inf, (f"{len(tv)} vertices and {len(theirs_faces)} faces, "
                          f"expected {ours.n_vertices} and {ours.n_faces}")
    dist, match = cKDTree(tv).query(ours.vertices)
    if len(np.unique(match)) != ours.n_vertices:
        return float(dist.max()), "two vertices match the same vertex"
    mapped = sorted(_canonical([int(match[i]) for i in f]) for f in ours.faces)
    if mapped != sorted(_canonical([int(i) for i in f]) for f in theirs_faces):
        return float(dist.max()), "the faces differ"
    return float(dist.max()), ""


def read_obj(path: Path) -> tuple[np.ndarray, list[list[int]]]:
    """Vertices and 0-based faces of a plain OBJ file written by a host script."""
    verts, faces = [], []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:]])
    return np.array(verts, dtype=float).reshape(-1, 3), faces
