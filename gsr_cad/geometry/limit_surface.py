"""The Catmull-Clark limit surface itself (not a tessellation of it): patches, foot points, area samples.

After one Catmull-Clark step every face is a quad. A quad whose four corners are interior vertices of
valence 4 is exactly a uniform bicubic B-spline patch of the 16 vertices of its 1-ring
(:func:`~gsr_cad.geometry.patches.bspline_stencils`). The other quads (next to an extraordinary or a
boundary vertex) are refined again, locally: the faces within two rings of them are cut out and
subdivided one more step, three of the four children of a quad at an extraordinary vertex become
regular patches, and the fourth stays pending. After ``depth`` such steps the pending quads (an area
``4**-depth`` of the first ones) are kept as flat pairs of triangles on their limit corners. Two rings of
margin keep every vertex used exactly as the global refinement computes it (the artificial boundary of a
cut-out only perturbs vertices within a quarter of a ring of it). Creases are carried level by level
(:func:`~gsr_cad.geometry.patches.crease_stencils`: a quad beside an infinitely sharp straight crease is
regular with phantom points across it; one touching any other sharp edge is refined again).

Everything is a fixed sparse map of the control vertices (:class:`LimitLayout`, built once per
connectivity), so a point at fixed ``(patch, u, v)`` is a linear combination of control vertices and a
least-squares fit stays linear. :class:`LimitSurface` evaluates one placement: foot points of query
points (nearest samples, then clamped Newton on a few candidate patches), area-weighted samples
(Gauss-Legendre per patch) and the sparse rows of any evaluated point. numpy/scipy only.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import InputError
from .patches import crease_stencils, phantom_rows
from .polymesh import PolyMesh
from .subdivision import CatmullClark, TopologyLRU, get_catmull_clark, refined_sharpness
from .surface_distance import TriangleSet

DEPTH = 5
"""Local refinement steps at extraordinary vertices: the pending quads left are ``4**-DEPTH`` of the
area next to them, so their chord error is about ``1e-3 / 4**(DEPTH - 1)`` of a cube's diagonal."""
_CANDIDATE_SAMPLES = 8  # nearest samples fetched per query point and patch depth
_CANDIDATE_PATCHES = 4  # distinct patches per query point and patch depth (four meet at a regular vertex)
_NEWTON = 12  # clamped Newton iterations per foot point (converged pairs stop earlier)
_SEARCH_GRID = {0: 8, 1: 4, 2: 2}  # samples per patch side for the candidate search, by depth (else 1)
_QUADRATURE = {0: 4, 1: 3, 2: 2}  # Gauss-Legendre points per patch side, by local depth (else 1)


@dataclasses.dataclass(frozen=True)
class LimitLayout:
    """The limit surface of one connectivity as maps of the control vertices.

    ``poles`` ``(16 P, n)``: row ``16 p + 4 i + j`` is control point ``(i, j)`` (``i`` along u) of patch
    ``p``; ``depth[p]`` its local refinement depth (0: a quad of the first refinement); ``corners``
    ``(R, n)`` the limit corners of the pending quads, ``triangles`` ``(2 R', 3)`` rows of ``corners``.
    """

    poles: sp.csr_matrix
    depth: np.ndarray
    corners: sp.csr_matrix
    triangles: np.ndarray
    n_control: int
    maps: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)
    """Per patch depth, the search grid's and the area samples' patches, parameters and weights (fixed by the
    connectivity), built on first use: every fit round of a cage reuses them."""

    @property
    def n_patches(self) -> int:
        return len(self.depth)


def _ring_faces(topo, faces: np.ndarray, rings: int) -> np.ndarray:
    """Faces within ``rings`` vertex-rings of ``faces`` (a boolean mask over the topology's faces)."""
    n_f = topo.n_faces
    inc = sp.csr_matrix((np.ones(len(topo.he_origin)), (topo.he_face, topo.he_origin)),
                        shape=(n_f, topo.n_vertices))
    mask = np.zeros(n_f, dtype=bool)
    mask[faces] = True
    for _ in range(rings):
        verts = np.asarray(inc[mask].sum(axis=0)).ravel() > 0
        mask = np.asarray(inc[:, verts].sum(axis=1)).ravel() > 0
    return mask


def build_layout(mesh: PolyMesh, boundary: str = "all", depth: int = DEPTH) -> LimitLayout:
    """The :class:`LimitLayout` of ``mesh``'s connectivity (module docstring)."""
    cc = get_catmull_clark(mesh, 1, boundary)
    topo = cc.topology
    sharp = refined_sharpness(mesh, topo) if mesh.crease_values.size else None  # creases, level by level
    P = sp.csr_matrix(cc.refine_matrix)
    faces = cc.corners.reshape(-1, 4)
    pending = np.arange(len(faces))
    blocks, depths = [], []
    for step in range(depth + 1):
        regular, ids, phantom = crease_stencils(topo, pending, sharp)
        if regular.size:
            rows = P[ids.reshape(-1)]
            blocks.append(phantom_rows(phantom) @ rows if phantom.any() else rows)
            depths.append(np.full(regular.size, step))
        pending = np.setdiff1d(pending, regular)
        if pending.size == 0 or step == depth:
            break
        keep, used, sub = _cut_out(topo, faces, _ring_faces(topo, pending, 2))
        sub_sharp = None if sharp is None else _carried(topo, sharp, sub.topology, used)
        step_cc = CatmullClark(sub, 1, boundary, sharpness=sub_sharp)
        P = sp.csr_matrix(step_cc.refine_matrix @ P[used])
        if sharp is not None:
            sharp = refined_sharpness(sub.topology, step_cc.topology, sub_sharp)
        topo = step_cc.topology
        faces = step_cc.corners.reshape(-1, 4)
        where = np.searchsorted(keep, pending)  # pending faces' positions in the cut-out
        pending = (4 * where[:, None] + np.arange(4)).ravel()  # their children
    if pending.size:
        last = PolyMesh(np.zeros((P.shape[0], 3)), faces.ravel(), np.arange(0, faces.size + 1, 4))
        lim = CatmullClark(last, 0, boundary, sharpness=None if sharp is None else
                           _carried(topo, sharp, last.topology, np.arange(P.shape[0]))).limit_matrix
        quads = faces[pending]
        used, local = np.unique(quads, return_inverse=True)
        local = local.reshape(-1, 4)
        corners = sp.csr_matrix(lim[used] @ P)
        tris = np.concatenate([local[:, [0, 1, 2]], local[:, [0, 2, 3]]])
    else:
        corners = sp.csr_matrix((0, mesh.n_vertices))
        tris = np.zeros((0, 3), dtype=np.int64)
    poles = sp.vstack(blocks, format="csr") if blocks else sp.csr_matrix((0, mesh.n_vertices))
    dep = np.concatenate(depths) if depths else np.zeros(0, dtype=np.int64)
    return LimitLayout(poles, dep, corners, tris, mesh.n_vertices)


def _cut_out(topo, faces: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, PolyMesh]:
    """The faces ``mask`` selects as a mesh of their own (indices kept, vertices used, the mesh), grown by
    the whole fan of any vertex where the selection would pinch (two fans meeting at a point)."""
    while True:
        keep = np.flatnonzero(mask)
        used, local = np.unique(faces[keep], return_inverse=True)
        sub = PolyMesh(np.zeros((used.size, 3)), local.ravel(), np.arange(0, local.size + 1, 4))
        pinched = used[sub.topology.vertex_fans > 1]
        if pinched.size == 0:
            return keep, used, sub
        mask = mask.copy()
        mask[topo.he_face[np.isin(topo.he_origin, pinched)]] = True


def _carried(topo, sharpness: np.ndarray, sub_topo, used: np.ndarray) -> np.ndarray:
    """Sharpness of ``sub_topo``'s edges (vertex ``i`` there is ``used[i]`` of ``topo``) from ``topo``'s."""
    n = topo.n_vertices
    keys = np.sort(topo.edges, axis=1) @ np.array([n, 1])
    order = np.argsort(keys)
    sub_keys = np.sort(used[sub_topo.edges], axis=1) @ np.array([n, 1])
    return sharpness[order[np.searchsorted(keys, sub_keys, sorter=order)]]


_LAYOUTS = TopologyLRU(256)
"""Layouts by ``(topology key, boundary, depth)``."""


def get_layout(mesh: PolyMesh, boundary: str = "all", depth: int = DEPTH) -> LimitLayout:
    """The cached :class:`LimitLayout` of ``mesh``'s connectivity."""
    return _LAYOUTS.get((mesh.topology_key, boundary, depth), lambda: build_layout(mesh, boundary, depth))


def bspline_basis(t: np.ndarray, order: int = 0) -> np.ndarray:
    """Uniform cubic B-spline basis ``(len(t), 4)`` on [0, 1] (``order`` 0, 1 or 2: value or derivative)."""
    t = np.asarray(t, dtype=np.float64)
    out = np.empty(t.shape + (4,))
    s = 1.0 - t
    if order == 0:
        t2 = t * t
        t3 = t2 * t
        out[..., 0] = s * s * s / 6.0
        out[..., 1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0
        out[..., 2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0
        out[..., 3] = t3 / 6.0
    elif order == 1:
        t2 = t * t
        out[..., 0] = -0.5 * s * s
        out[..., 1] = 1.5 * t2 - 2.0 * t
        out[..., 2] = -1.5 * t2 + t + 0.5
        out[..., 3] = 0.5 * t2
    else:
        out[..., 0] = s
        out[..., 1] = 3.0 * t - 2.0
        out[..., 2] = 1.0 - 3.0 * t
        out[..., 3] = t
    return out


def _bases(t: np.ndarray) -> np.ndarray:
    """``(len(t), 3, 4)``: :func:`bspline_basis` of orders 0, 1 and 2 at once (a Newton step needs all three)."""
    s = 1.0 - t
    t2 = t * t
    t3 = t2 * t
    out = np.empty((len(t), 3, 4))
    out[:, 0, 0] = s * s * s / 6.0
    out[:, 0, 1] = (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0
    out[:, 0, 2] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0
    out[:, 0, 3] = t3 / 6.0
    out[:, 1, 0] = -0.5 * s * s
    out[:, 1, 1] = 1.5 * t2 - 2.0 * t
    out[:, 1, 2] = -1.5 * t2 + t + 0.5
    out[:, 1, 3] = 0.5 * t2
    out[:, 2, 0] = s
    out[:, 2, 1] = 3.0 * t - 2.0
    out[:, 2, 2] = 1.0 - 3.0 * t
    out[:, 2, 3] = t
    return out


@dataclasses.dataclass(frozen=True)
class Hits:
    """Points on a limit surface: on patch ``patch`` at ``(u, v)``, or (``patch == -1``) on pending
    triangle ``triangle`` at ``barycentric``; ``point``, unit ``normal`` and ``distance`` to the query."""

    patch: np.ndarray
    u: np.ndarray
    v: np.ndarray
    triangle: np.ndarray
    barycentric: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    distance: np.ndarray


def _unit(a: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    return np.divide(a, n, out=np.zeros_like(a), where=n > 0)


def _tensor(rows: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``out[q, m, c, k] = sum_ij a[q, m, i] b[q, j, k] P[q, i, j, c]`` for bicubic patches with poles ``P``
    given as ``rows`` ``(q, 12, 4)`` (``rows[q, 3 i + c, j] = P[q, i, j, c]``, as ``LimitSurface._pole_rows``): the
    patches contracted with ``m`` bases along u and ``k`` along v, as two stacked matrix products (four times
    faster than an einsum per pair of bases, of which the foot points' Newton steps need six)."""
    q, k = len(rows), b.shape[2]
    return (a @ (rows @ b).reshape(q, 4, 3 * k)).reshape(q, a.shape[1], 3, k)


def _evaluate(rows: np.ndarray, u: np.ndarray, v: np.ndarray, derivatives: bool):
    """Points of patches with poles ``rows`` (as :func:`_tensor` takes them) at ``(u[i], v[i])`` (and the
    first derivatives)."""
    if not derivatives:
        return _tensor(rows, bspline_basis(u)[:, None, :], bspline_basis(v)[:, :, None])[:, 0, :, 0]
    out = _tensor(rows, np.stack([bspline_basis(u), bspline_basis(u, 1)], axis=1),
                  np.stack([bspline_basis(v), bspline_basis(v, 1)], axis=2))
    return out[:, 0, :, 0], out[:, 1, :, 0], out[:, 0, :, 1]


def _grid_params(m: int) -> tuple[np.ndarray, np.ndarray]:
    g = np.linspace(0.0, 1.0, m)
    return np.repeat(g, m), np.tile(g, m)


class LimitSurface:
    """The limit surface of control vertices ``vertices`` on ``layout``'s connectivity."""

    def __init__(self, layout: LimitLayout, vertices: np.ndarray):
        v = np.asarray(vertices, dtype=np.float64)
        if v.shape != (layout.n_control, 3):
            raise InputError(f"expected ({layout.n_control}, 3) control vertices, got shape {v.shape}")
        self.layout = layout
        self.control = v
        self.poles = (layout.poles @ v).reshape(-1, 4, 4, 3)
        self._pole_rows = np.ascontiguousarray(self.poles.transpose(0, 1, 3, 2)).reshape(-1, 12, 4)
        self._poles16 = self.poles.reshape(-1, 16, 3)
        self.corner_points = layout.corners @ v
        self._groups: list | None = None
        self._pending: TriangleSet | None = None  # the pending triangles, once a query may end on them
        self._sampled: tuple[Hits, tuple] | None = None  # the last samples() and the layout's maps they came from

    @classmethod
    def of(cls, mesh: PolyMesh, boundary: str = "all", depth: int = DEPTH) -> LimitSurface:
        return cls(get_layout(mesh, boundary, depth), mesh.vertices)

    # --- evaluation --------------------------------------------------------------------------------------
    def evaluate(self, patch: np.ndarray, u: np.ndarray, v: np.ndarray, derivatives: bool = False):
        """Points ``(q, 3)`` at ``(patch[i], u[i], v[i])``; with ``derivatives`` also ``S_u`` and ``S_v``."""
        return _evaluate(self._pole_rows[patch], u, v, derivatives)

    def _search(self) -> list[tuple[cKDTree, np.ndarray, np.ndarray, np.ndarray]]:
        """Per patch depth: a KD-tree of grid samples of its patches (spaced alike at every depth), their
        patch, parameters ``(s, 2)`` and covering radius ``(s,)`` (every point of a patch lies within its
        radius of a sample of its own)."""
        if self._groups is None:
            dep = self.layout.depth
            # a uniform bicubic's derivative along u (v) is at most its largest pole step along u (v), and
            # a cell's points are within 1 / (2 m) of its centre along each
            steps = (np.linalg.norm(np.diff(self.poles, axis=1), axis=3).max(axis=(1, 2))
                     + np.linalg.norm(np.diff(self.poles, axis=2), axis=3).max(axis=(1, 2)))
            self._groups = []
            for d in np.unique(dep):
                sel = np.flatnonzero(dep == d)
                m = _SEARCH_GRID.get(int(d), 1)
                owner, params, basis = self.layout.maps.get(("grid", int(d))) or _grid_maps(self.layout, sel, m)
                self._groups.append((cKDTree((basis @ self._poles16[sel]).reshape(-1, 3)), owner, params,
                                     np.repeat(steps[sel] / (2 * m), m * m)))
            if len(self.layout.triangles):
                corners = self.corner_points[self.layout.triangles]
                centroid = corners.mean(axis=1)
                reach = float(np.linalg.norm(corners - centroid[:, None], axis=2).max()) * (1 + 1e-9)
                self._pending_index = (cKDTree(centroid), reach)
        return self._groups

    def foot_points(self, patch: np.ndarray, u: np.ndarray, v: np.ndarray, x: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Clamped Newton foot points of ``x[i]`` on patch ``patch[i]`` from ``(u[i], v[i])`` (pairs stop
        once their step is below 1e-12 in parameter)."""
        u, v = u.astype(np.float64).copy(), v.astype(np.float64).copy()
        active = np.arange(len(u))
        poles = self._pole_rows[patch]
        for _ in range(_NEWTON):
            if not active.size:
                break
            ua, va = u[active], v[active]
            g = poles[active]
            d = _tensor(g, _bases(ua), _bases(va).transpose(0, 2, 1))
            s, su, sv = d[:, 0, :, 0], d[:, 1, :, 0], d[:, 0, :, 1]
            suu, suv, svv = d[:, 2, :, 0], d[:, 1, :, 1], d[:, 0, :, 2]
            r = x[active] - s
            a = (su * su).sum(-1) - (r * suu).sum(-1)
            b = (su * sv).sum(-1) - (r * suv).sum(-1)
            c = (sv * sv).sum(-1) - (r * svv).sum(-1)
            ru, rv = (su * r).sum(-1), (sv * r).sum(-1)
            det = a * c - b * b
            newton = (det > 0) & (a > 0)
            # where the Hessian is not positive definite (far from the surface): Gauss-Newton
            a = np.where(newton, a, (su * su).sum(-1))
            b = np.where(newton, b, (su * sv).sum(-1))
            c = np.where(newton, c, (sv * sv).sum(-1))
            det = a * c - b * b
            ok = det > 1e-14 * (a * c + 1e-300)
            det = np.where(ok, det, 1.0)
            # a degenerate Jacobian falls back to a gradient step along each direction
            alone_u = np.divide(ru, a, out=np.zeros_like(a), where=a > 0)
            alone_v = np.divide(rv, c, out=np.zeros_like(c), where=c > 0)
            du = np.where(ok, (c * ru - b * rv) / det, alone_u)
            dv = np.where(ok, (a * rv - b * ru) / det, alone_v)
            # a parameter on its bound whose step leaves the patch stays there and the other takes its own
            # Newton step along the border (projected Newton): the joint step, clipped, would zigzag
            out_u = ((ua <= 0.0) & (du < 0.0)) | ((ua >= 1.0) & (du > 0.0))
            out_v = ((va <= 0.0) & (dv < 0.0)) | ((va >= 1.0) & (dv > 0.0))
            du = np.where(out_u, 0.0, np.where(out_v, alone_u, du))
            dv = np.where(out_v, 0.0, np.where(out_u, alone_v, dv))
            nu, nv = np.clip(ua + du, 0.0, 1.0), np.clip(va + dv, 0.0, 1.0)
            u[active], v[active] = nu, nv
            active = active[np.maximum(np.abs(nu - ua), np.abs(nv - va)) > 1e-12]
        return u, v

    def closest(self, points: np.ndarray, hint: Hits | None = None) -> Hits:
        """The closest point on the limit surface of every row of ``points`` ``(q, 3)``.

        Candidates: per patch depth, the patches of the nearest grid samples (up to
        ``_CANDIDATE_PATCHES`` distinct ones: a foot point beyond a patch's edge lies on a neighbour), kept
        when their sample is within their patch's covering radius of the nearest sample of any depth. The
        nearest sample's patch is refined first by clamped Newton; the others where that foot point lies on
        the patch's border or where they may hold a nearer point (their sample's distance less their covering
        radius below that foot point's); the nearest foot point wins, or the nearest point of the pending
        triangles where that is nearer. ``hint`` (the same points' hits on this layout at nearby control
        vertices, e.g. the previous polish round's) is refined first, and searched from scratch only where
        its foot point leaves the interior of its patch."""
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        q = len(x)
        best = np.full(q, np.inf)
        patch = np.full(q, -1, dtype=np.int64)
        uu, vv = np.zeros(q), np.zeros(q)
        tri = np.full(q, -1, dtype=np.int64)
        bary = np.zeros((q, 3))
        todo = np.arange(q)
        self._search()  # the sample trees and the pending triangles' index, built once per placement
        if hint is not None and len(hint.patch) == q:
            on = np.flatnonzero(hint.patch >= 0)
            u, v = self.foot_points(hint.patch[on], hint.u[on], hint.v[on], x[on])
            ok = (u > 0) & (u < 1) & (v > 0) & (v < 1)
            rows = on[ok]
            patch[rows], uu[rows], vv[rows] = hint.patch[rows], u[ok], v[ok]
            best[rows] = np.linalg.norm(x[rows] - self.evaluate(patch[rows], uu[rows], vv[rows]), axis=1)
            todo = np.setdiff1d(todo, rows)
        self._search_patches(x, todo, best, patch, uu, vv)
        if len(self.layout.triangles):
            # only points that a pending triangle can be nearer to (bound from the triangles' centroids)
            tree, reach = self._pending_index
            near = np.flatnonzero(tree.query(x)[0] - reach < best)
            if near.size:
                if self._pending is None:
                    self._pending = TriangleSet(self.corner_points, self.layout.triangles)
                hit = self._pending.closest(x[near])
                nearer = hit.distance < best[near]
                sel = near[nearer]
                best[sel], patch[sel], tri[sel] = hit.distance[nearer], -1, hit.triangle[nearer]
                bary[sel] = hit.barycentric[nearer]
        return self._hits(patch, uu, vv, tri, bary, x)

    def _search_patches(self, points: np.ndarray, todo: np.ndarray, best: np.ndarray, patch: np.ndarray,
                        uu: np.ndarray, vv: np.ndarray) -> None:
        """The candidate search of :meth:`closest` for rows ``todo``, written into the other arrays."""
        if not todo.size:
            return
        x = points[todo]
        q = len(x)
        found = []
        for tree, owner, params, radius in self._search():
            k = min(_CANDIDATE_SAMPLES, tree.n)
            dist, idx = tree.query(x, k=k)
            dist, idx = dist.reshape(q, k), idx.reshape(q, k)
            own = owner[idx]
            first = np.ones((q, k), dtype=bool)
            seen = (own[:, 1:, None] == own[:, None, :-1]) & np.tri(k - 1, k - 1, 0, dtype=bool)[None]
            first[:, 1:] = ~seen.any(axis=2)
            first &= np.cumsum(first, axis=1) <= _CANDIDATE_PATCHES
            r, c = np.nonzero(first)
            found.append((r, own[r, c], params[idx[r, c]], dist[r, c], dist[r, c] - radius[idx[r, c]]))
        if found:
            r, cand, start, dist, reach = (np.concatenate(a) for a in zip(*found))
            nearest = np.full(q, np.inf)
            np.minimum.at(nearest, r, dist)
            keep = reach <= nearest[r]
            r, cand, start, dist, reach = r[keep], cand[keep], start[keep], dist[keep], reach[keep]
            # the nearest sample's patch first; the others where its foot point is on the patch's border or
            # where they may hold a nearer point (an interior foot point may be a local minimum only: a point
            # inside a sharp edge has one on each side)
            order = np.lexsort((dist, r))
            primary = np.zeros(r.size, dtype=bool)
            primary[order[np.r_[True, r[order][1:] != r[order][:-1]]]] = True
            u, v = np.zeros(r.size), np.zeros(r.size)
            u[primary], v[primary] = self.foot_points(cand[primary], start[primary, 0], start[primary, 1],
                                                      x[r[primary]])
            inside = np.zeros(q, dtype=bool)
            inside[r[primary]] = (u[primary] > 0) & (u[primary] < 1) & (v[primary] > 0) & (v[primary] < 1)
            first = np.full(q, np.inf)
            first[r[primary]] = np.linalg.norm(
                x[r[primary]] - self.evaluate(cand[primary], u[primary], v[primary]), axis=1)
            rest = ~primary & (~inside[r] | (reach < first[r]))
            u[rest], v[rest] = self.foot_points(cand[rest], start[rest, 0], start[rest, 1], x[r[rest]])
            done = primary | rest
            r, cand, u, v = r[done], cand[done], u[done], v[done]
            d = np.linalg.norm(x[r] - self.evaluate(cand, u, v), axis=1)
            order = np.lexsort((d, r))
            lead = order[np.r_[True, r[order][1:] != r[order][:-1]]]
            rows = todo[r[lead]]
            best[rows], patch[rows], uu[rows], vv[rows] = d[lead], cand[lead], u[lead], v[lead]

    def _hits(self, patch, u, v, tri, bary, x: np.ndarray | None) -> Hits:
        point = np.zeros((len(patch), 3))
        normal = np.zeros((len(patch), 3))
        on = patch >= 0
        if on.any():
            s, du, dv = self.evaluate(patch[on], u[on], v[on], derivatives=True)
            point[on], normal[on] = s, _unit(np.cross(du, dv))
        if (~on).any():
            t = self.layout.triangles[tri[~on]]
            a, b, c = (self.corner_points[t[:, i]] for i in range(3))
            point[~on] = bary[~on, 0:1] * a + bary[~on, 1:2] * b + bary[~on, 2:3] * c
            normal[~on] = _unit(np.cross(b - a, c - a))
        dist = np.zeros(len(patch)) if x is None else np.linalg.norm(x - point, axis=1)
        return Hits(patch, u, v, tri, bary, point, normal, dist)

    # --- area samples ------------------------------------------------------------------------------------
    def samples(self, density: int = 0) -> tuple[Hits, np.ndarray]:
        """Area samples of the whole surface and their weights (areas, summing to the surface's area):
        Gauss-Legendre points on every patch (more on larger patches; ``density`` adds points per side) and
        the centroid of every pending triangle. Their parameters are the layout's (built once per connectivity),
        and so are their :meth:`rows` (kept for the few latest connectivities)."""
        maps = self.layout.maps.get(("samples", int(density))) or _sample_maps(self.layout, int(density))
        patch, u, v, w, tri, bary, groups = maps
        on = patch >= 0
        point = np.zeros((len(patch), 3))
        su, sv = np.zeros((int(on.sum()), 3)), np.zeros((int(on.sum()), 3))
        at = 0
        for sel, basis in groups:  # per patch depth: (its patches, basis (3, k, 16): value, d/du, d/dv)
            k = basis.shape[1]
            out = basis[:, None] @ self._poles16[sel][None]  # (3, patches, k, 3)
            span = slice(at, at + sel.size * k)
            point[span], su[span], sv[span] = (out[i].reshape(-1, 3) for i in range(3))
            at += sel.size * k
        normal = np.zeros_like(point)
        area = np.zeros(len(patch))
        if on.any():
            cross = np.cross(su, sv)
            norm = np.linalg.norm(cross, axis=1)
            normal[on] = np.divide(cross, norm[:, None], out=np.zeros_like(cross), where=norm[:, None] > 0)
            area[on] = w * norm
        if (~on).any():
            t = self.layout.triangles
            a, b, c = (self.corner_points[t[:, i]] for i in range(3))
            cross = np.cross(b - a, c - a)
            point[~on] = (a + b + c) / 3.0
            normal[~on], area[~on] = _unit(cross), 0.5 * np.linalg.norm(cross, axis=1)
        hits = Hits(patch, u, v, tri, bary, point, normal, np.zeros(len(patch)))
        self._sampled = (hits, maps)
        return hits, area

    def random_points(self, count: int, seed: int = 0) -> np.ndarray:
        """``count`` points ``(count, 3)`` on the surface, drawn uniformly by area (seeded): pieces by area,
        parameters uniformly, then resampled by the area element (sampling-importance resampling)."""
        hits, area = self.samples()
        piece = np.where(hits.patch >= 0, hits.patch, self.layout.n_patches + hits.triangle)
        n_pieces = self.layout.n_patches + len(self.layout.triangles)
        piece_area = np.bincount(piece, area, minlength=n_pieces)
        rng = np.random.default_rng(seed)
        m = 4 * int(count)
        pick = rng.choice(n_pieces, size=m, p=piece_area / piece_area.sum())
        u, v = rng.random(m), rng.random(m)
        on = pick < self.layout.n_patches
        points = np.zeros((m, 3))
        weight = np.ones(m)
        if on.any():
            p, su, sv = self.evaluate(pick[on], u[on], v[on], derivatives=True)
            points[on] = p
            weight[on] = np.linalg.norm(np.cross(su, sv), axis=1) / piece_area[pick[on]]
        if (~on).any():
            flip = u + v > 1.0
            u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
            t = self.layout.triangles[pick[~on] - self.layout.n_patches]
            a, b, c = (self.corner_points[t[:, i]] for i in range(3))
            points[~on] = a + u[~on, None] * (b - a) + v[~on, None] * (c - a)
        keep = rng.choice(m, size=int(count), replace=False, p=weight / weight.sum())
        return points[keep]

    # --- linear maps -------------------------------------------------------------------------------------
    def rows(self, hits: Hits) -> sp.csr_matrix:
        """``(q, n)`` sparse rows: ``rows @ V`` is the hit points for control vertices ``V`` (same hits)."""
        if self._sampled is not None and hits is self._sampled[0]:  # the area samples: their rows are kept
            key = id(self._sampled[1])
            kept = _SAMPLE_ROWS.pop(key, None)
            if kept is None or kept[0] is not self._sampled[1]:
                kept = (self._sampled[1], _rows(self.layout, hits.patch, hits.u, hits.v, hits.triangle,
                                                hits.barycentric))
            _SAMPLE_ROWS[key] = kept
            while len(_SAMPLE_ROWS) > _SAMPLE_ROWS_KEPT:
                _SAMPLE_ROWS.popitem(last=False)
            return kept[1]
        return _rows(self.layout, hits.patch, hits.u, hits.v, hits.triangle, hits.barycentric)


def _basis16(u: np.ndarray, v: np.ndarray, order_u: int = 0, order_v: int = 0) -> np.ndarray:
    """``(k, 16)``: column ``4 i + j`` weighs pole ``(i, j)`` of a patch at ``(u[k], v[k])`` (or its derivative of
    orders ``order_u``, ``order_v``)."""
    return np.einsum("ka,kb->kab", bspline_basis(u, order_u), bspline_basis(v, order_v)).reshape(-1, 16)


def _grid_maps(layout: LimitLayout, sel: np.ndarray, m: int) -> tuple:
    """The search grid of the patches ``sel`` (one depth): ``m x m`` cell centres per patch (no sample on a
    border shared by several patches), their owners and parameters, and the basis ``(m m, 16)``; kept."""
    g = (np.arange(m) + 0.5) / m
    u, v = np.repeat(g, m), np.tile(g, m)
    maps = (np.repeat(sel, u.size), np.tile(np.stack([u, v], 1), (sel.size, 1)), _basis16(u, v))
    layout.maps[("grid", int(layout.depth[sel[0]]))] = maps
    return maps


def _sample_maps(layout: LimitLayout, density: int) -> tuple:
    """The area samples of :meth:`LimitSurface.samples`: their patches, parameters, quadrature weights, pending
    triangles and barycentric coordinates, and per patch depth its patches and bases (value, d/du, d/dv); kept
    on the layout (read-only)."""
    dep = layout.depth
    parts, groups = [], []
    for d in np.unique(dep):
        sel = np.flatnonzero(dep == d)
        n = _QUADRATURE.get(int(d), 1) + density
        g, w = np.polynomial.legendre.leggauss(n)
        g, w = 0.5 * (g + 1.0), 0.5 * w
        u, v = np.repeat(g, n), np.tile(g, n)
        parts.append((np.repeat(sel, n * n), np.tile(u, sel.size), np.tile(v, sel.size),
                      np.tile(np.outer(w, w).ravel(), sel.size)))
        groups.append((sel, np.stack([_basis16(u, v), _basis16(u, v, 1, 0), _basis16(u, v, 0, 1)])))
    patch = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, dtype=np.int64)
    u = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0)
    v = np.concatenate([p[2] for p in parts]) if parts else np.zeros(0)
    w = np.concatenate([p[3] for p in parts]) if parts else np.zeros(0)
    n_t = len(layout.triangles)
    patch = np.concatenate([patch, np.full(n_t, -1)])
    u, v = np.concatenate([u, np.zeros(n_t)]), np.concatenate([v, np.zeros(n_t)])
    tri = np.concatenate([np.full(len(w), -1), np.arange(n_t)])
    bary = np.concatenate([np.zeros((len(w), 3)), np.full((n_t, 3), 1.0 / 3.0)])
    for a in (patch, u, v, w, tri, bary):
        a.flags.writeable = False  # shared by every surface of this connectivity
    maps = (patch, u, v, w, tri, bary, tuple(groups))
    layout.maps[("samples", density)] = maps
    return maps


_SAMPLE_ROWS: OrderedDict = OrderedDict()
"""The area samples' :meth:`LimitSurface.rows` of the latest connectivities (by their maps' identity): the same
every fit round of a cage, and as large as its layout's poles several times over, so only a few are kept."""
_SAMPLE_ROWS_KEPT = 3


def _canonical(m) -> sp.csr_matrix:
    """``m`` as CSR with sorted, summed indices: a cached map that scipy would otherwise sort in place on some
    first use must sum in the same order at every use (bit-identical runs)."""
    m = sp.csr_matrix(m)
    m.sum_duplicates()
    m.sort_indices()
    return m


def _rows(layout: LimitLayout, patch: np.ndarray, u: np.ndarray, v: np.ndarray, triangle: np.ndarray,
          barycentric: np.ndarray) -> sp.csr_matrix:
    """:meth:`LimitSurface.rows` of points on patches (``patch >= 0``) or pending triangles."""
    q = len(patch)
    on = np.flatnonzero(patch >= 0)
    off = np.flatnonzero(patch < 0)
    parts = []
    if on.size:
        w = np.einsum("qa,qb->qab", bspline_basis(u[on]), bspline_basis(v[on])).reshape(-1)
        cols = (16 * patch[on][:, None] + np.arange(16)).ravel()
        pick = sp.csr_matrix((w, (np.repeat(on, 16), cols)), shape=(q, layout.poles.shape[0]))
        parts.append(pick @ layout.poles)
    if off.size:
        t = layout.triangles[triangle[off]]
        pick = sp.csr_matrix((barycentric[off].ravel(), (np.repeat(off, 3), t.ravel())),
                             shape=(q, layout.corners.shape[0]))
        parts.append(pick @ layout.corners)
    if not parts:
        return sp.csr_matrix((q, layout.n_control))
    return _canonical(sum(parts[1:], parts[0]))
