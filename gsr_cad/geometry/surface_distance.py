"""Distances between a subdivision surface and a target (mesh or point cloud); numpy/scipy only.

Two measures, both reported for every surface result:

* :func:`mixed_mean_distance`, the paper's fitness (section 4) exactly: for every vertex ``v`` of mesh
  A, its nearest target vertex ``t`` and the A-vertex ``a`` nearest to ``t``; the term is ``|v - t|``
  when ``a`` is ``v`` and the bounding-box diagonal otherwise. The mean of these terms over A -> T and
  over T -> A, the larger of the two, is the distance (fitness = its inverse). Ties (several A-vertices
  exactly as near to ``t``) count as "``a`` is ``v``", so the value does not depend on vertex order.
  It compares vertex *sets*: it reaches 0 only when the two sets coincide, and every target vertex
  without a partner at the same sampling density costs a full diagonal.
* :func:`point_to_surface`, symmetric and density independent: every target point to its exact closest
  point on the limit mesh's triangles, and every limit-mesh vertex back to the target: to its triangles
  when it has faces; for a point cloud, to the nearest sample less that sample's sampling radius
  (:func:`cloud_distance`), so a surface lying on the sampled surface costs nothing however sparse the
  samples are (the distance to the nearest sample alone would keep a floor set by the spacing). This
  direction only has to catch surface far from any data; the exact first direction gives the precision.

:class:`TriangleSet` answers exact closest-point queries on a triangle soup: a KD-tree on dense
samples (centroids of sub-triangles no larger than the typical triangle) finds an upper bound, and every
triangle that can beat it is projected exactly, so the answer equals brute force.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError

_MAX_SPLIT = 8  # sub-triangles per edge of one triangle in the sample tree; longer ones go to a nested set
_SPLIT = 2  # pieces per median triangle edge: finer pieces mean fewer candidate triangles per query
_K_CANDIDATES = 32  # pieces fetched per point by the first KD-tree query (4x more per later round, if needed)


def triangulate(corners: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Fan triangles ``(m, 3)`` of a PolyMesh layout, each face from its first corner.

    Quads become ``(c0, c1, c2), (c0, c2, c3)``; the triangles of face ``f`` are consecutive.
    """
    corners = np.asarray(corners, dtype=np.int64)
    offsets = np.asarray(offsets, dtype=np.int64)
    sizes = np.diff(offsets)
    n_tri = sizes - 2
    first = np.repeat(offsets[:-1], n_tri)
    local = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    return np.stack([corners[first], corners[first + local + 1], corners[first + local + 2]], axis=1)


class _Triangles:
    """Per-triangle quantities of the closest-point computation, computed once per triangle set."""

    def __init__(self, a: np.ndarray, b: np.ndarray, c: np.ndarray):
        self.a, self.b = a, b
        self.ab, self.ac, self.bc = b - a, c - a, c - b
        self.d00 = np.einsum("ij,ij->i", self.ab, self.ab)
        self.d01 = np.einsum("ij,ij->i", self.ab, self.ac)
        self.d11 = np.einsum("ij,ij->i", self.ac, self.ac)
        self.l_bc = np.einsum("ij,ij->i", self.bc, self.bc)
        normal = np.cross(self.ab, self.ac)
        det = np.einsum("ij,ij->i", normal, normal)  # = d00 d11 - d01^2, without the cancellation
        # slivers (an angle under ~1e-7 rad) and specks are taken as their edges
        ok = (det > 1e-14 * self.d00 * self.d11) & (det > 1e-200)
        self.inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
        self.ok = ok

    def closest(self, p: np.ndarray, t: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(distance, point, barycentric)`` of ``p[i]`` on triangle ``t[i]`` (or triangle ``i``)."""
        pick = (lambda x: x) if t is None else (lambda x: x[t])
        a, ab, ac = pick(self.a), pick(self.ab), pick(self.ac)
        ap = p - a
        d20 = np.einsum("ij,ij->i", ap, ab)
        d21 = np.einsum("ij,ij->i", ap, ac)
        d00, d01, d11, inv = pick(self.d00), pick(self.d01), pick(self.d11), pick(self.inv_det)
        v = (d11 * d20 - d01 * d21) * inv
        w = (d00 * d21 - d01 * d20) * inv
        inside = pick(self.ok) & (v >= 0.0) & (w >= 0.0) & (v + w <= 1.0)
        bary = np.stack([1.0 - v - w, v, w], axis=1)
        out = np.flatnonzero(~inside)
        if out.size:
            # Outside (or degenerate): the nearest point of the three edges.
            po, ao, abo, aco = p[out], a[out], ab[out], ac[out]
            bco = aco - abo
            l_ab, l_ac, l_bc = d00[out], d11[out], pick(self.l_bc)[out]
            s_ab = np.clip(np.divide(d20[out], l_ab, out=np.zeros(out.size), where=l_ab > 0), 0.0, 1.0)
            s_ac = np.clip(np.divide(d21[out], l_ac, out=np.zeros(out.size), where=l_ac > 0), 0.0, 1.0)
            bp = po - ao - abo
            s_bc = np.clip(np.divide(np.einsum("ij,ij->i", bp, bco), l_bc, out=np.zeros(out.size),
                                     where=l_bc > 0), 0.0, 1.0)
            r_ab = po - ao - s_ab[:, None] * abo
            r_ac = po - ao - s_ac[:, None] * aco
            r_bc = bp - s_bc[:, None] * bco
            e = np.argmin(np.stack([np.einsum("ij,ij->i", r, r) for r in (r_ab, r_ac, r_bc)]), axis=0)
            zero = np.zeros(out.size)
            cand = np.stack([np.stack([1 - s_ab, s_ab, zero], axis=1), np.stack([1 - s_ac, zero, s_ac], axis=1),
                             np.stack([zero, 1 - s_bc, s_bc], axis=1)])
            bary[out] = cand[e, np.arange(out.size)]
        point = a + bary[:, 1:2] * ab + bary[:, 2:3] * ac
        return np.linalg.norm(p - point, axis=1), point, bary


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest point of triangle ``(a[i], b[i], c[i])`` to ``p[i]`` for every row ``i``.

    Returns ``(distance (n,), point (n, 3), barycentric (n, 3))``. The interior projection is used where it
    falls inside a non-degenerate triangle, else the nearest of the three edges, so slivers and collapsed
    triangles are handled as segments or points.
    """
    arrays = [np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p, a, b, c)]
    return _Triangles(*arrays[1:]).closest(arrays[0])


@dataclasses.dataclass(frozen=True)
class Closest:
    """Closest points on a triangle set: per query point its distance, triangle, point and barycentrics."""

    distance: np.ndarray
    triangle: np.ndarray
    point: np.ndarray
    barycentric: np.ndarray


@functools.lru_cache(maxsize=_MAX_SPLIT)
def _piece_centroids(k: int) -> np.ndarray:
    """Barycentric centroids ``(k*k, 3)`` of the sub-triangles of a k-by-k barycentric grid."""
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    i, j = i.ravel(), j.ravel()
    up = i + j <= k - 1
    down = i + j <= k - 2
    u = np.concatenate([(i[up] + 1 / 3) / k, (i[down] + 2 / 3) / k])
    v = np.concatenate([(j[up] + 1 / 3) / k, (j[down] + 2 / 3) / k])
    return np.stack([1 - u - v, u, v], axis=1)


class TriangleSet:
    """Exact closest-point queries on a fixed set of triangles (build once, query many times).

    ``vertices`` ``(n, 3)``, ``triangles`` ``(m, 3)`` vertex indices. Each triangle is cut into ``k**2``
    similar pieces (``k`` = its longest edge over half the median longest edge, rounded up) whose
    centroids go into a KD-tree; every point of a piece lies within ``radius`` of its centroid, so the
    nearest triangle to a query has a piece centroid within ``upper bound + radius`` of it. Queries fetch
    the nearest pieces, project onto their triangles, and fetch more only for points whose last fetched
    piece still lies within that bound. Triangles that would need more than ``_MAX_SPLIT`` pieces per edge
    (long slivers) form a nested set with its own median, queried too: the memory and the query cost do
    not depend on the triangles' shapes.
    """

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray):
        v = np.asarray(vertices, dtype=np.float64)
        t = np.asarray(triangles, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or t.ndim != 2 or t.shape[1] != 3 or len(t) == 0:
            raise InputError(f"a triangle set needs (n, 3) vertices and (m >= 1, 3) triangles, "
                             f"got {v.shape} and {t.shape}")
        if t.min() < 0 or t.max() >= len(v):
            raise InputError("a triangle refers to a vertex that does not exist")
        self.vertices, self.triangles = v, t
        a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        self._data = _Triangles(a, b, c)
        edges = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                          np.linalg.norm(a - c, axis=1)], axis=1).max(axis=1)
        size = float(np.median(edges)) / _SPLIT
        k = (np.ones(len(t), dtype=np.int64) if size <= 0
             else np.maximum(np.ceil(edges / size), 1).astype(np.int64))
        # triangles far longer than the median (slivers of a CAD export) get a nested set of their own, with
        # its own median, so that neither the piece count nor the covering radius depends on their shapes
        long = k > _MAX_SPLIT
        self._long: TriangleSet | None = None
        if long.any():
            self._long_ids = np.flatnonzero(long)
            self._long = TriangleSet(v, t[long])
        k = np.minimum(k, _MAX_SPLIT)
        centroid = (a + b + c) / 3.0
        own_radius = np.stack([np.linalg.norm(a - centroid, axis=1), np.linalg.norm(b - centroid, axis=1),
                               np.linalg.norm(c - centroid, axis=1)], axis=1).max(axis=1)
        own_radius[long] = 0.0
        pieces, owners = [], []
        for kk in np.unique(k[~long]):
            sel = np.flatnonzero((k == kk) & ~long)
            bary = _piece_centroids(int(kk))
            pts = (bary[None, :, 0:1] * a[sel, None] + bary[None, :, 1:2] * b[sel, None]
                   + bary[None, :, 2:3] * c[sel, None])
            pieces.append(pts.reshape(-1, 3))
            owners.append(np.repeat(sel, len(bary)))
        self._owner = np.concatenate(owners)
        self._tree = cKDTree(np.concatenate(pieces))
        # A piece is the triangle scaled by 1/k about a point, so its covering radius is own_radius / k.
        self.radius = float((own_radius / k).max()) * (1.0 + 1e-9) + 1e-300

    def __len__(self) -> int:
        return len(self.triangles)

    def closest(self, points: np.ndarray) -> Closest:
        """The exact closest point on the set for every row of ``points`` ``(q, 3)``."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n_p, n_pieces = len(p), self._tree.n
        k = min(_K_CANDIDATES, n_pieces)
        dk, ik = self._tree.query(p, k=k)
        dk, ik = dk.reshape(n_p, k), ik.reshape(n_p, k)
        tri = self._owner[ik[:, 0]]
        dist, point, bary = self._data.closest(p, tri)
        rows = np.arange(n_p)
        done = 1  # columns already evaluated
        while True:
            # Triangles that may beat the current best: a piece within best + radius (each triangle once per row).
            cand = np.where(dk[:, done:] <= (dist[rows] + self.radius)[:, None], self._owner[ik[:, done:]], -1)
            cand = np.where(cand == tri[rows, None], -1, cand)
            cand.sort(axis=1)
            cand[:, 1:][cand[:, 1:] == cand[:, :-1]] = -1
            r, c = np.nonzero(cand >= 0)
            if r.size:
                q, t = rows[r], cand[r, c]
                d, pt, bc = self._data.closest(p[q], t)
                table = np.full(cand.shape, np.inf)
                table[r, c] = d
                pick = np.argmin(table, axis=1)
                better = table[np.arange(len(rows)), pick] < dist[rows]
                sel = np.flatnonzero(better)
                slot = np.full(cand.shape, -1, dtype=np.int64)
                slot[r, c] = np.arange(r.size)
                j = slot[sel, pick[sel]]
                q = rows[sel]
                dist[q], tri[q], point[q], bary[q] = d[j], t[j], pt[j], bc[j]
            if k >= n_pieces:
                break
            # Rows whose last fetched piece still lies inside the bound may have candidates beyond it.
            more = dk[:, -1] <= dist[rows] + self.radius
            if not more.any():
                break
            rows = rows[more]
            done = k
            k = min(4 * k, n_pieces)
            dk, ik = self._tree.query(p[rows], k=k)
            dk, ik = dk.reshape(len(rows), k), ik.reshape(len(rows), k)
        if self._long is not None:
            other = self._long.closest(p)
            nearer = other.distance < dist
            dist[nearer], tri[nearer] = other.distance[nearer], self._long_ids[other.triangle[nearer]]
            point[nearer], bary[nearer] = other.point[nearer], other.barycentric[nearer]
        return Closest(dist, tri, point, bary)


LARGE_TRIANGLE = 3.0
"""A triangle whose longest edge exceeds this many times the median is sampled inside (see
:func:`area_samples`); smaller ones are represented by their corners."""

FLAT_DEGREES = 0.5
"""Dihedral angle (degrees) below which two triangles are coplanar parts of one flat face."""

SHARP_DEGREES = 30.0
"""Dihedral angle (degrees) above which an edge is a feature edge (a CAD part's sharp edge)."""


def _edge_angles(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                          np.ndarray, np.ndarray]:
    """Per distinct edge of a triangle mesh: the cosine of the angle between its two faces' normals (1 unless
    exactly two faces share it), its face count and length; then each triangle corner's edge index ``(m, 3)``
    and whether each triangle has area."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(length > 0, length, 1.0)[:, None]
    edges = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(t)), 3)
    unique, key, count = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    key = key.ravel()
    order = np.argsort(key, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(key[order]) != 0])
    pair = count[key[order[starts]]] == 2
    cos = np.ones(len(count))
    a, b = owner[order[starts[pair]]], owner[order[starts[pair] + 1]]
    cos[key[order[starts[pair]]]] = np.einsum("ij,ij->i", normal[a], normal[b])
    edge_length = np.linalg.norm(v[unique[:, 1]] - v[unique[:, 0]], axis=1)
    return cos, count, edge_length, key.reshape(-1, 3), length > 0


def facet_triangles(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Which triangles lie on a planar face of a part: each of their edges is shared with a coplanar
    neighbour (``FLAT_DEGREES``), is a feature edge (``SHARP_DEGREES``) or is a boundary. Their interiors are
    the surface itself, unlike the chords of a smooth surface's tessellation, whose edges bend by a few
    degrees."""
    cos, count, _, corner_edges, has_area = _edge_angles(vertices, triangles)
    flat = cos > np.cos(np.radians(FLAT_DEGREES))
    sharp = (cos < np.cos(np.radians(SHARP_DEGREES))) | (count != 2)
    return (flat | sharp)[corner_edges].all(axis=1) & has_area


def chord_sag(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per triangle, how far the smooth surface a tessellation approximates may lie from it.

    Each smooth edge gives the normal curvature across it: the angle between its two faces' normals over the
    distance between their centroids *across the edge* (a third of the sum of the faces' heights over it). A
    triangle's curvature tensor is ``S = 2/3 * sum(k_e d_e d_e^T)`` over its edges (``d_e``: in its plane,
    perpendicular to edge ``e``; the 2/3 makes three equal curvatures of a near-equilateral triangle ``k I``),
    and its sag is half the squared radius of the smallest circle enclosing the triangle mapped by ``S^(1/2)``:
    ``k r^2 / 2`` on a sphere, ``k w^2 / 8`` across a cylinder's strip of width ``w`` however long it is (an
    enclosing circle of the strip itself would charge its length). Feature edges (``SHARP_DEGREES``: the chord
    is the part's edge), boundaries and flat edges bend nothing. A coarse tessellation's chords are this far
    inside a curved surface, so a fit may leave a surface within it unpulled; a fine one's sag is negligible."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    cos, count, _, corner_edges, has_area = _edge_angles(v, t)
    corners = v[t]  # (m, 3, 3)
    along = np.roll(corners, -1, axis=1) - corners  # edge j runs from corner j to corner j + 1
    length = np.linalg.norm(along, axis=2)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    double_area = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(double_area > 0, double_area, 1.0)[:, None]
    height = np.divide(double_area[:, None], length, out=np.zeros_like(length), where=length > 0)
    gap = np.zeros(len(count))  # the two faces' centroid distance across each edge: a third of their heights
    np.add.at(gap, corner_edges.ravel(), height.ravel() / 3.0)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    smooth = (count == 2) & (angle < np.radians(SHARP_DEGREES)) & (gap > 0)
    curvature = np.where(smooth, angle / np.where(gap > 0, gap, 1.0), 0.0)[corner_edges]  # (m, 3)
    across = np.cross(normal[:, None, :], along)
    across /= np.where(length > 0, length, 1.0)[:, :, None]
    tensor = (2.0 / 3.0) * np.einsum("mj,mja,mjb->mab", curvature, across, across)
    value, vector = np.linalg.eigh(tensor)
    root = np.einsum("mab,mb,mcb->mac", vector, np.sqrt(np.maximum(value, 0.0)), vector)
    mapped = np.einsum("mab,mjb->mja", root, corners - corners[:, :1])
    sides = np.sort(np.linalg.norm(np.roll(mapped, -1, axis=1) - mapped, axis=2), axis=1)
    mapped_area = 0.5 * np.linalg.norm(np.cross(mapped[:, 1], mapped[:, 2]), axis=1)
    obtuse = sides[:, 2] ** 2 >= (sides[:, 0] ** 2 + sides[:, 1] ** 2) * (1.0 - 1e-9)
    circum = np.divide(sides.prod(axis=1), 4.0 * mapped_area, out=np.zeros(len(t)), where=mapped_area > 0)
    radius = np.where(obtuse | (mapped_area <= 0), 0.5 * sides[:, 2], circum)
    return np.where(has_area, radius ** 2 / 2.0, 0.0)


def area_samples(vertices: np.ndarray, triangles: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """``n`` points ``(n, 3)`` drawn by area from a triangle mesh (seeded), so that a plain mean over them
    is a mean over the surface whatever the triangles' sizes.

    Each triangle's area goes to its three corners (a third each), except for triangles much larger than
    the median (``LARGE_TRIANGLE``: long slivers of a CAD export) and facets (:func:`facet_triangles`: the
    planar faces of a CAD part), which are sampled uniformly inside: a tessellation's vertices lie on the
    surface it samples while its chords do not, so the same smooth surface tessellated at any density gives
    the same distances, and a mean over the vertices alone would miss the interior of a long triangle or of
    a flat face."""
    v, t, a, b, c, area = _with_areas(vertices, triangles)
    longest = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                        np.linalg.norm(a - c, axis=1)], axis=1).max(axis=1)
    large = (longest > LARGE_TRIANGLE * float(np.median(longest))) | facet_triangles(v, t)
    corner_area = np.bincount(t[~large].ravel(), np.repeat(area[~large] / 3.0, 3), minlength=len(v))
    weight = np.concatenate([corner_area, np.where(large, area, 0.0)])
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(weight), size=int(n), p=weight / weight.sum())
    out = v[np.minimum(pick, len(v) - 1)].copy()
    inside = np.flatnonzero(pick >= len(v))
    if inside.size:
        out[inside] = _inside(a, b, c, pick[inside] - len(v), rng)
    return out


def _with_areas(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(vertices, triangles, corners a, b, c, areas)`` of a mesh to sample by area; InputError without area."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if not float(area.sum()) > 0:
        raise InputError("cannot sample a mesh by area: its triangles have no area")
    return v, t, a, b, c, area


def _inside(a: np.ndarray, b: np.ndarray, c: np.ndarray, f: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform random point inside triangle ``(a[i], b[i], c[i])`` for every ``i`` in ``f``."""
    r1, r2 = rng.random(f.size), rng.random(f.size)
    flip = r1 + r2 > 1.0
    r1, r2 = np.where(flip, 1.0 - r1, r1), np.where(flip, 1.0 - r2, r2)
    return a[f] + r1[:, None] * (b[f] - a[f]) + r2[:, None] * (c[f] - a[f])


def mixed_mean_distance(a: np.ndarray, t: np.ndarray, diagonal: float, t_tree: cKDTree | None = None,
                        a_tree: cKDTree | None = None) -> float:
    """The paper's mixed mean distance between vertex sets ``a`` (result) and ``t`` (target).

    ``diagonal`` is the penalty of an unmatched vertex (the paper: the bounding-box diagonal). Pass the
    target's KD-tree as ``t_tree`` to build it only once per target.
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t, dtype=np.float64).reshape(-1, 3)
    if len(a) == 0 or len(t) == 0:
        raise InputError("the mixed mean distance needs two non-empty vertex sets")
    t_tree = cKDTree(t) if t_tree is None else t_tree
    a_tree = cKDTree(a) if a_tree is None else a_tree
    d_a, near_t = t_tree.query(a)  # A -> nearest T
    d_t, near_a = a_tree.query(t)  # T -> nearest A
    tol = 1e-12 * max(float(diagonal), 1e-300)
    # v's nearest target t sends back to v exactly when v is (one of) t's nearest A-vertices.
    a_ok = d_a <= d_t[near_t] + tol
    t_ok = d_t <= d_a[near_a] + tol
    mean_a = float(np.where(a_ok, d_a, diagonal).mean())
    mean_t = float(np.where(t_ok, d_t, diagonal).mean())
    return max(mean_a, mean_t)


def sampling_radius(points: np.ndarray, tree: cKDTree | None = None, k: int = 6) -> np.ndarray:
    """Per point, the distance to its ``k``-th nearest other point: the radius of the patch of surface a
    sample stands for (the slack of :func:`cloud_distance`)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    tree = cKDTree(p) if tree is None else tree
    k = min(k, len(p) - 1)
    if k < 1:
        return np.zeros(len(p))
    d, _ = tree.query(p, k=k + 1)
    return d[:, -1]


def cloud_distance(x: np.ndarray, points: np.ndarray, radius: np.ndarray, tree: cKDTree | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each row of ``x`` to a point cloud whose samples each stand for the surface within
    ``radius`` of them: the distance to the nearest sample less its radius, floored at 0. Returns
    ``(distance, nearest sample index)``."""
    tree = cKDTree(points) if tree is None else tree
    d, idx = tree.query(x)
    return np.maximum(d - np.asarray(radius)[idx], 0.0), idx


@dataclasses.dataclass(frozen=True)
class SurfaceDistances:
    """Both directions of the point-to-surface distance (absolute units).

    ``to_surface``: every target point to the limit mesh's triangles (with the closest points for a
    least-squares fit); ``to_target``: every limit vertex back to the target.
    """

    to_surface: np.ndarray
    to_target: np.ndarray
    closest: Closest

    @property
    def symmetric(self) -> float:
        """Mean of the two directions' mean distances."""
        return 0.5 * (float(self.to_surface.mean()) + float(self.to_target.mean()))


def point_to_surface(limit_vertices: np.ndarray, limit_triangles: np.ndarray, target_points: np.ndarray, *,
                     target_surface: TriangleSet | None = None, target_tree: cKDTree | None = None,
                     target_radius: np.ndarray | None = None) -> SurfaceDistances:
    """Symmetric point-to-surface distances between a limit mesh and a target.

    Target -> surface is exact (closest points on the limit triangles). Surface -> target uses the
    target's triangles when ``target_surface`` is given (a mesh target), else (a point cloud)
    :func:`cloud_distance` with ``target_radius`` (default :func:`sampling_radius`).
    """
    lv = np.asarray(limit_vertices, dtype=np.float64)
    tp = np.asarray(target_points, dtype=np.float64)
    closest = TriangleSet(lv, limit_triangles).closest(tp)
    if target_surface is not None:
        back = target_surface.closest(lv).distance
    else:
        tree = cKDTree(tp) if target_tree is None else target_tree
        radius = sampling_radius(tp, tree) if target_radius is None else target_radius
        back, _ = cloud_distance(lv, tp, radius, tree)
    return SurfaceDistances(closest.distance, back, closest)


class NearTriangles:
    """Fast, nearly exact closest points on a fixed triangle mesh (a refinement's many fits): a KD-tree of
    every triangle's centroid and ``count`` area samples drawn inside the triangles (large ones get several),
    each remembering its triangle; a query projects exactly onto the triangles of its ``k`` nearest samples
    and keeps the nearest. The answer is a point of the mesh, so its distance is never below the exact one,
    and it is exact whenever the nearest triangle owns one of those samples (nearly always; otherwise the
    triangle found is a neighbour of it). Unlike :class:`TriangleSet`, no bound is certified, so a query is
    one KD-tree search and ``k`` projections."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, count: int = 20_000, k: int = 8,
                 seed: int = 0):
        _, t, a, b, c, area = _with_areas(vertices, triangles)
        rng = np.random.default_rng(seed)
        owner = rng.choice(len(t), size=int(count), p=area / area.sum())
        points = _inside(a, b, c, owner, rng)
        owner = np.concatenate([owner, np.arange(len(t))])
        points = np.concatenate([points, (a + b + c) / 3.0])
        self._owner = owner
        self._tree = cKDTree(points)
        self._data = _Triangles(a, b, c)
        self.k = min(int(k), len(owner))

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(distance, closest point)`` of every row of ``points`` ``(q, 3)`` (class docstring)."""
        d, point, _ = self.closest_triangles(points)
        return d, point

    def closest_triangles(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(distance, closest point, triangle index)`` of every row of ``points`` ``(q, 3)``."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(p) == 0:
            return np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
        _, idx = self._tree.query(p, k=self.k)
        tri = np.sort(self._owner[np.asarray(idx).reshape(len(p), self.k)], axis=1)
        # each distinct triangle once per query (a query's nearest samples mostly share a few triangles)
        fresh = np.ones(tri.shape, dtype=bool)
        fresh[:, 1:] = tri[:, 1:] != tri[:, :-1]
        query, slot = np.nonzero(fresh)
        tri = tri[query, slot]
        d, point, _ = self._data.closest(p[query], tri)
        starts = np.flatnonzero(np.r_[True, query[1:] != query[:-1]])
        nearest = np.minimum.reduceat(d, starts)
        # the first of each query's nearest (lowest triangle index on a tie): same as a full argmin
        pick = np.flatnonzero(d == nearest[query])
        pick = pick[np.r_[True, query[pick[1:]] != query[pick[:-1]]]]
        return d[pick], point[pick], tri[pick]
