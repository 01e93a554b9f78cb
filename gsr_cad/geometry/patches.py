"""The Catmull-Clark limit surface as bicubic B-spline patches, for exchange with CAD (numpy/scipy only).

Public API (other exporters build on it):

* :func:`limit_patches` ``(mesh, tolerance_rel=1e-4, boundary="all", max_level=4) -> PatchSet``;
* :class:`PatchSet` ``.patches`` (list of :class:`Patch`), ``.max_deviation``, ``.mean_deviation``
  (absolute), ``.diagonal``, ``.tolerance``, ``.within_tolerance``, ``.n_exact``, ``.spans``, ``.level``;
* :class:`Patch` ``(poles (nu, nv, 3), knots_u, knots_v, degree_u=3, degree_v=3, exact)``, knots
  flattened and clamped on [0, 1], ``.evaluate(u, v)``;
* :func:`limit_grids` ``(mesh, level, boundary)``: exact limit points of every patch on its parameter grid.

One patch per quad of the once-refined mesh (every face is a quad there), in the refined face order of
:mod:`~gsr_cad.geometry.subdivision`: quad ``h`` for half-edge ``h`` of the control mesh. A patch's
parameter ``u`` runs from its corner 0 to corner 1, ``v`` from corner 0 to corner 3, so ``dS/du x dS/dv``
points along the face normal (outwards on a closed, outward-oriented mesh).

* A quad whose four corners are interior vertices of valence 4 is an exact uniform bicubic B-spline
  patch over its 4 x 4 neighbourhood; it is written as its Bezier patch (4 x 4 poles, no interior knots).
  Creases (edge sharpness after the first step) count: a corner with a semi-sharp edge, a dart or a crease
  corner makes the quad fitted; a side on an infinitely sharp crease that runs straight through regular
  vertices keeps the quad exact, with the row across the crease replaced by its phantom ``2 p - q``
  (:func:`crease_stencils`). Either way neighbours across a crease share their edge curve: the patches
  meet as exact C0 edges at the crease's angle.
* Every other quad (an extraordinary vertex, a former n-gon's centre, the boundary) is fitted: with
  ``k`` uniform spans per direction, every edge curve is fitted to the exact limit points on that edge
  alone, ends fixed at the limit corners, so that both neighbours share the same curve and the patches
  sew into a watertight shell; then the interior poles are the least-squares fit (boundary fixed) to the
  limit points of a level-``L`` grid. Near an extraordinary corner whose limit leaves it faster than
  linearly (valence > 4, darts, crease corners: ``t**gamma``, ``gamma < 1``) the points are fitted at graded
  parameters, each side's ``(1 - t) t**g0 + t (1 - (1 - t)**g1)`` blended across the quad
  (:func:`_side_grading`), so that the leading term is linear in the patch's parameters: the fit then
  shrinks by ~0.4 per level (measured) instead of ~0.56. Both quads on a side grade it alike. ``L`` and
  ``k = 2**(L-2)`` rise until the deviation, measured at the level-``L + 1`` grid (points between the
  fitted ones), is below ``tolerance_rel`` times the limit surface's bounding-box diagonal.

Deviations are distances from exact limit points (the level-``L + 1`` grid, every patch) to the patches:
``|patch(u, v) - limit(u, v)|`` on exact patches, the distance to a Gauss-Newton foot point (started at the
point's own graded parameters and at the nearest of a finer grid of patch points, kept inside the patch, so
never an underestimate) on fitted ones. Near an
extraordinary vertex the limit's parametrization is not polynomial, so a parametric gap would mostly
measure tangential sliding (it shrinks only by the subdominant eigenvalue per level), not shape.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, InputError
from . import bspline
from .polymesh import SHARPNESS_INFINITE, PolyMesh
from .subdivision import TopologyLRU, get_catmull_clark, refined_sharpness

Boundary = Literal["all", "corners"]
DEGREE = 3
MIN_LEVEL = 3
"""Smallest fitting level: ``2**(MIN_LEVEL - 1) = 4`` sample intervals per patch side and 2 spans."""

# Uniform cubic B-spline segment -> Bezier: rows are the Bezier poles in terms of the 4 B-spline poles.
_BSPLINE_TO_BEZIER = np.array([[1, 4, 1, 0], [0, 4, 2, 0], [0, 2, 4, 0], [0, 1, 4, 1]], dtype=np.float64) / 6.0
_BEZIER_KNOTS = np.array([0.0, 0, 0, 0, 1, 1, 1, 1])


@dataclasses.dataclass(frozen=True)
class Patch:
    """A non-rational B-spline patch on [0, 1]^2: poles ``(nu, nv, 3)`` (``poles[i, j]``: ``i`` along u),
    flattened clamped knot vectors; ``exact`` when it reproduces the limit surface exactly (regular)."""

    poles: np.ndarray
    knots_u: np.ndarray
    knots_v: np.ndarray
    degree_u: int = DEGREE
    degree_v: int = DEGREE
    exact: bool = False

    def evaluate(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Points on the tensor grid ``u x v``, shape ``(len(u), len(v), 3)``."""
        bu = _basis(self.knots_u, self.degree_u, np.asarray(u, dtype=np.float64))
        bv = _basis(self.knots_v, self.degree_v, np.asarray(v, dtype=np.float64))
        return np.einsum("ia,abc,jb->ijc", bu, self.poles, bv)

    @property
    def breakpoints_u(self) -> tuple[np.ndarray, np.ndarray]:
        """Distinct u knots and their multiplicities (the form OCCT and STEP use)."""
        return np.unique(self.knots_u, return_counts=True)

    @property
    def breakpoints_v(self) -> tuple[np.ndarray, np.ndarray]:
        return np.unique(self.knots_v, return_counts=True)


@dataclasses.dataclass(frozen=True)
class PatchSet:
    """Patches of a limit surface and the deviation they achieve (absolute, parametric; module docstring).

    ``patch_deviation[p]`` is patch ``p``'s largest deviation; ``level`` the fitting level (``2**(level-1)``
    sample intervals per patch side), ``spans`` the knot spans per direction of every fitted patch;
    ``closed`` says whether the control mesh (hence the shell) is closed.
    """

    patches: list[Patch]
    max_deviation: float
    mean_deviation: float
    diagonal: float
    tolerance: float
    patch_deviation: np.ndarray
    level: int
    spans: int
    closed: bool

    @property
    def within_tolerance(self) -> bool:
        return self.max_deviation <= self.tolerance

    @property
    def n_exact(self) -> int:
        """Number of exact (regular) patches."""
        return sum(p.exact for p in self.patches)

    def summary(self) -> dict[str, float | int | bool]:
        """The figures an export states about itself (JSON-ready)."""
        return {"patches": len(self.patches), "exact_patches": self.n_exact,
                "fitted_patches": len(self.patches) - self.n_exact, "spans_per_fitted_patch": self.spans,
                "sample_level": self.level, "max_deviation": self.max_deviation,
                "mean_deviation": self.mean_deviation, "diagonal": self.diagonal,
                "max_deviation_rel": self.max_deviation / self.diagonal if self.diagonal else 0.0,
                "mean_deviation_rel": self.mean_deviation / self.diagonal if self.diagonal else 0.0,
                "tolerance": self.tolerance, "closed": self.closed}


def _basis(knots: np.ndarray, degree: int, x: np.ndarray) -> np.ndarray:
    from scipy.interpolate import BSpline

    return BSpline.design_matrix(np.clip(x, knots[0], knots[-1]), knots, degree).toarray()


_GRIDS = TopologyLRU(32)
"""Grid vertex indices by ``(topology key, level)``: they depend on connectivity only."""


def _grid_indices(corners: np.ndarray, n_quads: int, level: int) -> np.ndarray:
    """``(n_quads, n + 1, n + 1)`` refined-vertex index at parameter ``(i / n, j / n)`` of each level-1
    quad, ``n = 2**(level - 1)``, from the level-``level`` quads (children of a quad follow its corners)."""
    n = 2 ** (level - 1)
    params = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], dtype=np.float64).repeat(n_quads, axis=0)
    nxt, prv = np.array([1, 2, 3, 0]), np.array([3, 0, 1, 2])
    for _ in range(level - 1):  # child i: (p_i, (p_i + p_i+1) / 2, centre, (p_i-1 + p_i) / 2)
        centre = params.mean(axis=1, keepdims=True).repeat(4, axis=1)
        child = np.stack([params, 0.5 * (params + params[:, nxt]), centre, 0.5 * (params[:, prv] + params)], axis=2)
        params = child.reshape(-1, 4, 2)
    ij = np.rint(params * n).astype(np.int64)
    owner = np.repeat(np.arange(n_quads), 4 ** (level - 1) * 4)
    grid = np.full((n_quads, n + 1, n + 1), -1, dtype=np.int64)
    grid[owner, ij[..., 0].ravel(), ij[..., 1].ravel()] = corners.reshape(-1)
    grid.setflags(write=False)
    return grid


def limit_grids(mesh: PolyMesh, level: int, boundary: Boundary = "all") -> np.ndarray:
    """Exact limit-surface points ``(n_patches, n + 1, n + 1, 3)`` at parameters ``(i / n, j / n)`` of every
    patch (``[p, i, j]``, ``i`` along u), ``n = 2**(level - 1)``, from the level-``level`` refinement."""
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or level < 1:
        raise ConfigError(f"the sampling level must be a whole number >= 1, got {level!r}")
    cc = get_catmull_clark(mesh, int(level), boundary)
    n_quads = len(mesh.corners)
    grid = _GRIDS.get((mesh.topology_key, int(level)), lambda: _grid_indices(cc.corners, n_quads, int(level)))
    return (cc.limit_matrix @ mesh.vertices)[grid]


def bspline_stencils(topo, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The regular quads among ``faces`` of an all-quad topology (half-edges ``4 f + k``) and their uniform
    bicubic B-spline control grids ``(n_regular, 4, 4)`` of vertex indices (``[i, j]``, ``i`` along u from
    corner 0 to corner 1). A quad is regular when its four corners are interior vertices of valence 4
    (edge sharpness ignored: :func:`crease_stencils` honours it)."""
    quads, ids, _ = crease_stencils(topo, faces)
    return quads, ids


def _regular_crease_vertices(topo, sharp: np.ndarray, infinite: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Vertices where the limit is a tensor B-spline on either side of a crease: interior, valence 4, no
    sharp edge or exactly two, infinitely sharp and opposite each other (the crease runs straight through)."""
    nv = topo.n_vertices
    count = np.bincount(topo.edges[sharp].ravel(), minlength=nv)
    semi = np.zeros(nv, dtype=bool)
    semi[topo.edges[sharp & ~infinite].ravel()] = True
    ok = good & ((count == 0) | ((count == 2) & ~semi))
    org, nx, tw, edge = topo.he_origin, topo.he_next, topo.he_twin, topo.he_edge
    h = np.flatnonzero(sharp[edge] & ok[org] & (count[org] == 2))
    opposite = nx[tw[nx[tw[h]]]]  # two steps around the (interior, valence-4) origin
    ok[org[h[~sharp[edge[opposite]]]]] = False
    return ok


def crease_stencils(topo, faces: np.ndarray, sharpness: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quads among ``faces`` of an all-quad topology whose limit is one uniform bicubic B-spline patch,
    given the edge ``sharpness`` of this level (None: smooth), with their control grids ``(n, 4, 4)`` of
    vertex indices (``[i, j]``, ``i`` along u from corner 0 to corner 1) and ``(n, 4)`` phantom sides.

    Every corner must be an interior vertex of valence 4 with no sharp edge, or a regular crease vertex
    (two infinitely sharp edges, opposite). A side on an infinite crease then behaves as a boundary of the
    B-spline: the row of points across it is the phantom ``2 p_side - p_inner`` (the crease rules are the
    cubic curve rule along it, which that reflection reproduces and keeps at every level); :func:`phantom_rows`
    turns the flags into the linear map. Near a semi-sharp edge a quad is not regular at this level.
    """
    org, nx, tw = topo.he_origin, topo.he_next, topo.he_twin
    good = (topo.vertex_valence == 4) & ~topo.vertex_is_boundary
    faces = np.asarray(faces, dtype=np.int64)
    he = 4 * faces[:, None] + np.arange(4)
    if sharpness is not None and np.any(np.asarray(sharpness) > 0):
        s = np.asarray(sharpness, dtype=np.float64)
        sharp = s > 0
        good = _regular_crease_vertices(topo, sharp, s >= SHARPNESS_INFINITE, good)
        side_sharp = sharp[topo.he_edge[he]]
    else:
        side_sharp = np.zeros(he.shape, dtype=bool)
    keep = good[org[he]].all(axis=1)
    quads, phantom = faces[keep], side_sharp[keep]
    ids = np.empty((quads.size, 4, 4), dtype=np.int64)
    # corner k of the quad, the two points across its side k (next to c_k, next to c_k+1), the diagonal at c_k
    inner = [(1, 1), (2, 1), (2, 2), (1, 2)]
    across = [((1, 0), (2, 0), (0, 0)), ((3, 1), (3, 2), (3, 0)), ((2, 3), (1, 3), (3, 3)), ((0, 2), (0, 1), (0, 3))]
    for k in range(4):
        h = 4 * quads + k
        tt = tw[h]
        s_ = tw[nx[tt]]
        (xi, xj), (yi, yj), (wi, wj) = across[k]
        ids[:, inner[k][0], inner[k][1]] = org[h]
        ids[:, xi, xj] = org[nx[nx[tt]]]
        ids[:, yi, yj] = org[nx[nx[nx[tt]]]]
        ids[:, wi, wj] = org[nx[nx[nx[s_]]]]
    return quads, ids, phantom


# the grid points a phantom side k replaces, and the two (weights 2, -1) they are reflected from
_PHANTOM = []
for _k, (_row, _near, _far) in enumerate([((slice(None), 0), (slice(None), 1), (slice(None), 2)),
                                         ((3, slice(None)), (2, slice(None)), (1, slice(None))),
                                         ((slice(None), 3), (slice(None), 2), (slice(None), 1)),
                                         ((0, slice(None)), (1, slice(None)), (2, slice(None)))]):
    _flat = np.arange(16).reshape(4, 4)
    _PHANTOM.append((_flat[_row], _flat[_near], _flat[_far]))


def phantom_rows(phantom: np.ndarray) -> sp.csr_matrix:
    """``(16 n, 16 n)`` map from the gathered grid points of :func:`crease_stencils` (row ``16 p + 4 i + j``)
    to the B-spline control points: identity, except that the points across a phantom side are
    ``2 p_side - p_inner`` (at most two opposite sides per quad are phantom, so the sources are genuine)."""
    n = len(phantom)
    rows, cols, vals = [np.arange(16 * n)], [np.arange(16 * n)], [np.ones(16 * n)]
    for k, (target, near, far) in enumerate(_PHANTOM):
        p = np.flatnonzero(phantom[:, k])
        if p.size == 0:
            continue
        base = 16 * p[:, None]
        t = (base + target).ravel()
        rows += [t, t, t]
        cols += [t, (base + near).ravel(), (base + far).ravel()]
        vals += [-np.ones(t.size), np.full(t.size, 2.0), -np.ones(t.size)]
    r, c, v = (np.concatenate(x) for x in (rows, cols, vals))
    return sp.csr_matrix((v, (r, c)), shape=(16 * n, 16 * n))


def _regular_patches(mesh: PolyMesh, boundary: str) -> tuple[np.ndarray, np.ndarray]:
    """Regular level-1 quads (creases honoured) and their Bezier poles ``(n_regular, 4, 4, 3)``."""
    cc = get_catmull_clark(mesh, 1, boundary)
    sharpness = refined_sharpness(mesh, cc.topology) if mesh.crease_values.size else None
    quads, ids, phantom = crease_stencils(cc.topology, np.arange(len(mesh.corners)), sharpness)
    if quads.size == 0:
        return quads, np.zeros((0, 4, 4, 3))
    g = (phantom_rows(phantom) @ (cc.refine_matrix @ mesh.vertices)[ids.reshape(-1)]).reshape(-1, 4, 4, 3)
    return quads, np.einsum("ai,pijc,bj->pabc", _BSPLINE_TO_BEZIER, g, _BSPLINE_TO_BEZIER)


def _sides(grid: np.ndarray) -> list[np.ndarray]:
    """The four sides of ``(..., m, m, 3)`` grids, side ``k`` running from corner ``k`` to corner ``k + 1``."""
    return [grid[:, :, 0], grid[:, -1, :], grid[:, ::-1, -1], grid[:, 0, ::-1]]


def _set_sides(grid: np.ndarray, sides: list[np.ndarray]) -> None:
    grid[:, :, 0] = sides[0]
    grid[:, -1, :] = sides[1]
    grid[:, ::-1, -1] = sides[2]
    grid[:, 0, ::-1] = sides[3]


def _side_grading(mesh: PolyMesh, boundary: str, grids: np.ndarray, fitted: np.ndarray) -> np.ndarray:
    """Per side of every fitted quad (``(n_fitted, 4, 2)``: side ``k`` from corner ``k`` to ``k + 1``, its
    start and end), the exponent ``gamma`` of the limit's speed leaving that corner: along a side the limit
    moves like ``t**gamma``, ``gamma = -log2 lambda`` with lambda the subdominant eigenvalue of the corner's
    rules. Regular corners (valence 4, interior, smooth or on a straight infinite crease) get 1; interior
    corners without an infinitely sharp edge Catmull-Clark's lambda of their valence (semi-sharpness decays
    to the smooth rules; 0.74 at valence 7); the others (infinite creases, darts, the boundary) the median,
    over the sides leaving them, of ``log2(d(2 / n) / d(1 / n))`` (the distances from the corner of the limit
    points ``grids`` one and two sample steps along the side). Only a fast start (``gamma < 1``) is graded:
    a slow one (valence 3) leaves an error along the surface that the deviation does not count, so
    ``gamma`` is clipped to [0.5, 1]. A value belongs to the vertex: every quad and side there sees the same."""
    t1 = get_catmull_clark(mesh, 1, boundary).topology
    sharpness = refined_sharpness(mesh, t1) if mesh.crease_values.size else np.zeros(t1.n_edges)
    interior = ~t1.vertex_is_boundary
    regular = _regular_crease_vertices(t1, sharpness > 0, sharpness >= SHARPNESS_INFINITE,
                                       (t1.vertex_valence == 4) & interior)
    corners = t1.he_origin[4 * fitted[:, None] + np.arange(4)]
    vertex, ratio = [], []
    for k, side in enumerate(_sides(grids)):
        for end, pts in ((0, side), (1, side[:, ::-1])):
            d1 = np.linalg.norm(pts[:, 1] - pts[:, 0], axis=-1)
            d2 = np.linalg.norm(pts[:, 2] - pts[:, 0], axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio.append(np.log2(d2 / d1))
            vertex.append(corners[:, (k + end) % 4])
    vertex, ratio = np.concatenate(vertex), np.concatenate(ratio)
    ok = np.isfinite(ratio)
    vertex, ratio = vertex[ok], np.clip(ratio[ok], 0.5, 1.0)
    order = np.lexsort((ratio, vertex))
    vertex, ratio = vertex[order], ratio[order]
    first = np.flatnonzero(np.r_[True, vertex[1:] != vertex[:-1]]) if vertex.size else np.zeros(0, dtype=np.int64)
    count = np.diff(np.r_[first, vertex.size])
    gamma = np.ones(t1.n_vertices)
    gamma[vertex[first]] = 0.5 * (ratio[first + (count - 1) // 2] + ratio[first + count // 2])
    smooth = interior & (np.bincount(t1.edges[sharpness >= SHARPNESS_INFINITE].ravel(), minlength=t1.n_vertices) == 0)
    c1, c2 = np.cos(2 * np.pi / t1.vertex_valence[smooth]), np.cos(np.pi / t1.vertex_valence[smooth])
    gamma[smooth] = -np.log2((5 + c1 + c2 * np.sqrt(2 * (9 + c1))) / 16)
    gamma[regular] = 1.0
    g = np.clip(gamma[corners], 0.5, 1.0)
    return np.stack([g, np.roll(g, -1, axis=1)], axis=2)


def graded(t: np.ndarray, g0: np.ndarray, g1: np.ndarray) -> np.ndarray:
    """Side parameters at uniform ``t`` of a side whose ends have exponents ``g0``, ``g1``
    (:func:`_vertex_grading`): ``(1 - t) t**g0 + t (1 - (1 - t)**g1)``, the identity when both are 1.
    Reversing the side swaps the exponents and mirrors the parameters, so both quads on a side agree."""
    g0, g1 = np.asarray(g0)[..., None], np.asarray(g1)[..., None]
    return (1 - t) * t ** g0 + t * (1 - (1 - t) ** g1)


def _patch_params(side_gamma: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(U, V)``, each ``(n_patches, m, m)``, of the limit grid points of quads with side
    exponents ``side_gamma`` (:func:`_side_grading`): every side graded (:func:`graded`), blended linearly
    across the quad."""
    t = np.linspace(0.0, 1.0, m)
    g = side_gamma
    bottom, top = graded(t, g[:, 0, 0], g[:, 0, 1]), graded(t, g[:, 2, 1], g[:, 2, 0])  # u along v = 0, 1
    left, right = graded(t, g[:, 3, 1], g[:, 3, 0]), graded(t, g[:, 1, 0], g[:, 1, 1])  # v along u = 0, 1
    u = (1 - t)[None, None, :] * bottom[:, :, None] + t[None, None, :] * top[:, :, None]
    v = (1 - t)[None, :, None] * left[:, None, :] + t[None, :, None] * right[:, None, :]
    return u, v


def _basis_at(n_poles: int, x: np.ndarray) -> np.ndarray:
    """Dense basis ``(*x.shape, n_poles)`` at parameters ``x`` in [0, 1]."""
    return bspline.basis_matrix(n_poles, np.clip(x, 0.0, 1.0).ravel()).reshape(*x.shape, n_poles)


def _surface_at(poles: np.ndarray, bu: np.ndarray, bv: np.ndarray) -> np.ndarray:
    """Points ``(p, k, 3)`` of patches ``poles`` ``(p, n, n, 3)`` at bases ``bu``, ``bv`` ``(p, k, n)``."""
    p, n = poles.shape[0], poles.shape[1]
    rows = np.matmul(bu, poles.reshape(p, n, 3 * n)).reshape(p, -1, n, 3)
    return np.einsum("pkbc,pkb->pkc", rows, bv)


def _fit(mesh: PolyMesh, boundary: str, fit: np.ndarray, fitted: np.ndarray, spans: int,
         side_gamma: np.ndarray) -> np.ndarray:
    """Poles ``(len(fitted), spans + 3, spans + 3, 3)`` of the fitted quads from their limit grids ``fit``,
    each point at its graded parameters (:func:`_patch_params` of ``side_gamma``)."""
    n_poles = spans + DEGREE
    m = fit.shape[1]
    t = np.linspace(0.0, 1.0, m)
    # one curve per control-mesh edge of the refined mesh: fitted from the side of its first half-edge
    t1 = get_catmull_clark(mesh, 1, boundary).topology
    used = np.zeros(t1.n_edges, dtype=bool)
    quad_of = np.full(len(mesh.corners), -1)
    quad_of[fitted] = np.arange(fitted.size)
    he = (4 * fitted[:, None] + np.arange(4)).ravel()
    used[t1.he_edge[he]] = True
    edges = np.flatnonzero(used)
    curves = np.zeros((t1.n_edges, n_poles, 3))
    # a used edge's samples come from any fitted quad that has it (identical limit points either way)
    owner_he = np.full(t1.n_edges, -1)
    owner_he[t1.he_edge[he]] = he
    side_k = owner_he[edges] % 4
    q = quad_of[owner_he[edges] // 4]
    samples = np.empty((edges.size, m, 3))
    for k, side in enumerate(_sides(fit)):
        sel = side_k == k
        samples[sel] = side[q[sel]]
    forward = t1.edge_halfedge[edges] == owner_he[edges]
    samples[~forward] = samples[~forward, ::-1]
    gamma = side_gamma[q, side_k]
    gamma[~forward] = gamma[~forward, ::-1]
    basis = _basis_at(n_poles, graded(t, gamma[:, 0], gamma[:, 1]))
    fixed = samples[:, [0, -1]]
    rhs = samples - basis[..., :1] * fixed[:, None, 0] - basis[..., -1:] * fixed[:, None, 1]
    curves[edges, 0], curves[edges, -1] = fixed[:, 0], fixed[:, 1]
    curves[edges, 1:-1] = np.einsum("eam,emc->eac", np.linalg.pinv(basis[..., 1:-1]), rhs)
    poles = np.zeros((fitted.size, n_poles, n_poles, 3))
    sides = []
    for k in range(4):
        h = 4 * fitted + k
        c = curves[t1.he_edge[h]]
        rev = t1.edge_halfedge[t1.he_edge[h]] != h
        c[rev] = c[rev, ::-1]
        sides.append(c)
    _set_sides(poles, sides)
    u, v = _patch_params(side_gamma, m)
    bu, bv = _basis_at(n_poles, u), _basis_at(n_poles, v)  # (p, m, m, n)
    rest = fit - _surface_at(poles, bu.reshape(fitted.size, m * m, -1), bv.reshape(fitted.size, m * m, -1)
                             ).reshape(fit.shape)
    inner = (bu[..., 1:-1, None] * bv[..., None, 1:-1]).reshape(fitted.size, m * m, -1)
    inner_t = inner.transpose(0, 2, 1)
    normal = np.matmul(inner_t, inner)
    ridge = 1e-12 * np.trace(normal, axis1=1, axis2=2)[:, None, None] * np.eye(normal.shape[1])
    solved = np.linalg.solve(normal + ridge, np.matmul(inner_t, rest.reshape(fitted.size, m * m, 3)))
    poles[:, 1:-1, 1:-1] = solved.reshape(fitted.size, n_poles - 2, n_poles - 2, 3)
    return poles


def _foot_distances(poles: np.ndarray, x: np.ndarray, u: np.ndarray, v: np.ndarray, iterations: int) -> np.ndarray:
    """Distances ``(p, k)`` from points ``x`` ``(p, k, 3)`` to patches ``poles`` by Gauss-Newton from ``(u, v)``
    ``(p, k)``, parameters kept in [0, 1]^2: the least distance to any iterate (each a point on the patch)."""
    n_p, k = u.shape
    n = poles.shape[1]

    def basis(t: np.ndarray, order: int) -> np.ndarray:
        return bspline.derivative_basis_matrix(n, t.ravel(), DEGREE, order).reshape(n_p, k, n)

    best = np.full((n_p, k), np.inf)
    for step in range(iterations + 1):
        bu, bv = basis(u, 0), basis(v, 0)
        r = x - _surface_at(poles, bu, bv)
        best = np.minimum(best, np.linalg.norm(r, axis=-1))
        if step == iterations:
            break
        su, sv = _surface_at(poles, basis(u, 1), bv), _surface_at(poles, bu, basis(v, 1))
        a, b, c = (su * su).sum(-1), (su * sv).sum(-1), (sv * sv).sum(-1)
        ru, rv = (su * r).sum(-1), (sv * r).sum(-1)
        det = a * c - b * b
        ok = det > 1e-30 * (a * c + 1e-300)
        det = np.where(ok, det, 1.0)
        u = np.clip(u + np.where(ok, (c * ru - b * rv) / det, 0.0), 0.0, 1.0)
        v = np.clip(v + np.where(ok, (a * rv - b * ru) / det, 0.0), 0.0, 1.0)
    return best


def _project(poles: np.ndarray, points: np.ndarray, start: tuple[np.ndarray, np.ndarray],
             iterations: int = 8) -> np.ndarray:
    """Distance from every point ``points[p, i, j]`` (the limit at grid point ``(i, j)`` of patch ``p``) to
    patch ``p`` (``poles[p]``, clamped uniform knots): Gauss-Newton foot points (kept in [0, 1]^2: a foot point
    beyond the patch's edge would lie on its neighbour, so clamping can only overestimate) from the parameters
    ``start`` (``(U, V)``, each shaped like ``points[..., 0]``) and from the nearest of a twice as fine grid of
    patch points (a strongly distorted patch leads Gauss-Newton astray from ``start``); the lesser distance."""
    from scipy.spatial import cKDTree

    n_p, m = points.shape[0], points.shape[1]
    x = points.reshape(n_p, m * m, 3)
    shape = (n_p, m * m)
    dist = _foot_distances(poles, x, start[0].reshape(shape).copy(), start[1].reshape(shape).copy(), iterations)
    g = np.linspace(0.0, 1.0, 2 * m - 1)
    b = bspline.basis_matrix(poles.shape[1], g)
    dense = np.einsum("ia,pabc,jb->pijc", b, poles, b, optimize=True).reshape(n_p, -1, 3)
    near = np.stack([cKDTree(dense[p]).query(x[p])[1] for p in range(n_p)])
    u, v = g[near // g.size], g[near % g.size]
    dist = np.minimum(dist, _foot_distances(poles, x, u, v, iterations))
    return dist.reshape(n_p, m, m)


def limit_patches(mesh: PolyMesh, tolerance_rel: float = 1e-4, boundary: Boundary = "all",
                  max_level: int = 4) -> PatchSet:
    """Bicubic B-spline patches of ``mesh``'s Catmull-Clark limit surface (module docstring).

    ``tolerance_rel`` is relative to the limit surface's bounding-box diagonal; the fitting level rises
    from 3 to ``max_level`` until every fitted patch is within it. When even ``max_level`` does not reach
    it, the best patches are returned with ``within_tolerance`` False (callers decide whether to refuse).
    """
    if not isinstance(mesh, PolyMesh):
        raise InputError(f"limit_patches needs a PolyMesh, got {type(mesh).__name__}")
    if not (isinstance(tolerance_rel, (float, int)) and np.isfinite(tolerance_rel) and tolerance_rel > 0):
        raise ConfigError(f"the patch tolerance must be a positive number, got {tolerance_rel!r}")
    if isinstance(max_level, bool) or not isinstance(max_level, (int, np.integer)) or not 3 <= max_level <= 7:
        raise ConfigError(f"max_level must be a whole number from 3 to 7, got {max_level!r}")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("the control mesh has non-finite vertex coordinates")
    regular, bezier = _regular_patches(mesh, boundary)
    n_quads = len(mesh.corners)
    fitted = np.setdiff1d(np.arange(n_quads), regular)
    best = None
    for level in range(MIN_LEVEL, int(max_level) + 1):
        check = limit_grids(mesh, level + 1, boundary)
        if best is None:
            lo, hi = check.reshape(-1, 3).min(axis=0), check.reshape(-1, 3).max(axis=0)
            diagonal = float(np.linalg.norm(hi - lo))
            tolerance = float(tolerance_rel) * diagonal
        spans = 2 ** (level - 2)
        m = check.shape[1]
        dev = np.empty((n_quads, m, m))
        poles = None
        if fitted.size:
            side_gamma = _side_grading(mesh, boundary, check[fitted], fitted)
            poles = _fit(mesh, boundary, check[fitted][:, ::2, ::2], fitted, spans, side_gamma)
            dev[fitted] = _project(poles, check[fitted], _patch_params(side_gamma, m))
        if regular.size:
            b = bspline.uniform_basis(4, m, DEGREE)
            dev[regular] = np.linalg.norm(np.einsum("ia,pabc,jb->pijc", b, bezier, b) - check[regular], axis=-1)
        best = (level, spans, poles, dev)
        if dev.max() <= tolerance or not fitted.size:
            break
    level, spans, poles, dev = best
    knots = bspline.clamped_uniform_knots(spans + DEGREE, DEGREE)
    out: list[Patch | None] = [None] * n_quads
    for p, q in enumerate(regular.tolist()):
        out[q] = Patch(_readonly(bezier[p]), _BEZIER_KNOTS, _BEZIER_KNOTS, exact=True)
    for p, q in enumerate(fitted.tolist()):
        out[q] = Patch(_readonly(poles[p]), knots, knots)
    per_patch = dev.reshape(n_quads, -1).max(axis=1)
    return PatchSet(out, float(dev.max()), float(dev.mean()), diagonal, tolerance, _readonly(per_patch),
                    level, spans, bool(mesh.topology.is_closed))


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a


_BEZIER_KNOTS.setflags(write=False)
