"""Where the template starts: the default cube on the target's oriented box, a user template fitted to it.

* :func:`oriented_box`: the target's principal axes (PCA of its area samples) give an oriented box; it
  is used when its volume is clearly (``AXIS_PREFERENCE``) smaller than the axis-aligned box's, so a
  target already aligned with the axes (whose principal axes may be ill-defined, e.g. a cube) keeps
  them.
* :func:`place_cube`: the unit cube on that box, scaled so that its limit surface spans it.
* :func:`fit_template`: a similarity (scale, rotation, translation) taking a user template's limit surface
  onto the target: principal axes matched (every proper sign choice tried), then ICP-like rounds
  (closest points both ways, the best similarity of the pairs in closed form), the closest start kept.

Each returns a :class:`Placement` saying what was done (``result.json`` metrics ``template_placement``).
"""

from __future__ import annotations

import dataclasses
import itertools
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..geometry.limit_surface import LimitSurface
from ..geometry.polymesh import PolyMesh, unit_cube

CUBE_LIMIT_HALF = 34.0 / 81.0
"""Half-extent of the limit surface of a unit cube (its face centres): a cube of side ``s`` has a limit
surface ``s * 68/81`` across, so a template meant to fill a box of extent ``e`` has side ``e * 81/68``."""
AXIS_PREFERENCE = 0.9
"""The principal-axes box is used when its volume is below this fraction of the axis-aligned box's."""
ICP_ROUNDS = 25


@dataclasses.dataclass(frozen=True)
class Placement:
    """A placed template and how: ``method``, and the similarity ``x -> scale * rotation @ x + translation``
    applied to the template as given (for the cube: to the unit cube), with the distance it reached."""

    mesh: PolyMesh
    method: str
    rotation: np.ndarray
    scale: np.ndarray
    translation: np.ndarray
    mean_distance: float | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"method": self.method, "rotation": self.rotation.tolist(), "scale": np.atleast_1d(self.scale).tolist(),
               "translation": self.translation.tolist()}
        if self.mean_distance is not None:
            out["mean_distance"] = self.mean_distance
        return out


def principal_axes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and principal axes (columns, largest spread first, right-handed) of ``points``."""
    p = np.asarray(points, dtype=np.float64)
    centre = p.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((p - centre).T))
    axes = vectors[:, ::-1].copy()
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    return centre, axes


def oriented_box(points: np.ndarray, samples: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """``(centre, axes (columns), extent along each axis, method)`` of the box of ``points`` the cube is
    placed on; the principal axes come from ``samples`` (area samples: density independent), default
    ``points``."""
    p = np.asarray(points, dtype=np.float64)
    _, axes = principal_axes(p if samples is None else samples)
    local = p @ axes
    lo_r, hi_r = local.min(axis=0), local.max(axis=0)
    lo_a, hi_a = p.min(axis=0), p.max(axis=0)
    if np.prod(hi_r - lo_r) < AXIS_PREFERENCE * np.prod(hi_a - lo_a):
        return axes @ ((lo_r + hi_r) / 2.0), axes, hi_r - lo_r, "oriented box (principal axes)"
    return (lo_a + hi_a) / 2.0, np.eye(3), hi_a - lo_a, "axis-aligned box"


def place_cube(points: np.ndarray, fit: str = "box", samples: np.ndarray | None = None) -> Placement:
    """The unit cube on the :func:`oriented_box` of ``points`` (axes from ``samples``), its limit surface
    spanning the box (``fit`` "box": per axis; "cube": uniformly, by the largest extent)."""
    centre, axes, extent, method = oriented_box(points, samples)
    if fit == "cube":
        extent = np.full(3, extent.max())
    extent = np.maximum(extent, 1e-6 * float(extent.max()))
    scale = extent / (2.0 * CUBE_LIMIT_HALF)
    cube = unit_cube()
    vertices = (cube.vertices * scale) @ axes.T + centre
    return Placement(cube.with_vertices(vertices), method, axes, scale, centre)


def _similarity(src: np.ndarray, dst: np.ndarray, weight: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The weighted least-squares similarity ``dst ~ s R src + t`` (closed form, proper rotation)."""
    w = weight / weight.sum()
    mu_s, mu_d = w @ src, w @ dst
    a, b = src - mu_s, dst - mu_d
    cov = (b * w[:, None]).T @ a
    u, sig, vt = np.linalg.svd(cov)
    d = np.ones(3)
    d[2] = np.sign(np.linalg.det(u @ vt)) or 1.0
    rot = u @ np.diag(d) @ vt
    var = float(w @ (a * a).sum(axis=1))
    s = float((sig * d).sum() / var) if var > 0 else 1.0
    return s, rot, mu_d - s * rot @ mu_s


def fit_template(template: PolyMesh, points: np.ndarray, rounds: int = ICP_ROUNDS) -> Placement:
    """``template`` moved by the similarity that best takes its limit surface onto ``points`` (module
    docstring); a template whose own pose is within 10 % of the best score stays as given."""
    target = np.asarray(points, dtype=np.float64)
    if len(target) < 4:
        raise InputError("fitting a template needs at least 4 target points")
    tree = cKDTree(target)
    diag = float(np.linalg.norm(target.max(axis=0) - target.min(axis=0)))
    surface = LimitSurface.of(template)
    base = surface.random_points(min(2000, 4 * len(target)), seed=0)
    c_t, axes_t = principal_axes(target)
    c_s, axes_s = principal_axes(base)
    spread = np.sqrt(np.mean(np.sum((target - c_t) ** 2, axis=1)) / np.mean(np.sum((base - c_s) ** 2, axis=1)))
    starts = [(1.0, np.eye(3), np.zeros(3))]
    for signs in itertools.product((1.0, -1.0), repeat=2):
        flip = np.diag([signs[0], signs[1], signs[0] * signs[1]])
        rot = axes_t @ flip @ axes_s.T
        starts.append((float(spread), rot, c_t - spread * rot @ c_s))
    def score_of(moved: np.ndarray) -> float:
        return 0.5 * (tree.query(moved)[0].mean() + cKDTree(moved).query(target)[0].mean()) / max(diag, 1e-300)

    as_is = score_of(base)
    best = None
    for s, rot, t in starts:
        for _ in range(rounds):
            moved = s * base @ rot.T + t
            d_fwd, near = tree.query(moved)
            # target -> template: the nearest moved sample of each target point
            d_back, back = cKDTree(moved).query(target)
            src = np.concatenate([base, base[back]])
            dst = np.concatenate([target[near], target])
            weight = np.concatenate([np.full(len(base), 1.0 / len(base)), np.full(len(target), 1.0 / len(target))])
            s_new, rot_new, t_new = _similarity(src, dst, weight)
            change = abs(s_new - s) + np.abs(rot_new - rot).max() + np.abs(t_new - t).max() / max(diag, 1e-300)
            s, rot, t = s_new, rot_new, t_new
            if change < 1e-9:
                break
        score = score_of(s * base @ rot.T + t)
        if best is None or score < best[0]:
            best = (score, s, rot, t)
    score, s, rot, t = best
    if as_is <= score / 0.9:
        return Placement(template, "as given (a similarity fit was not closer)", np.eye(3), np.ones(1), np.zeros(3),
                         float(as_is))
    mesh = template.with_vertices(s * template.vertices @ rot.T + t)
    return Placement(mesh, "similarity fit (principal axes + ICP)", rot, np.full(1, s), t, float(score))
