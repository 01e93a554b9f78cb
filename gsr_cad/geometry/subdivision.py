"""Catmull-Clark subdivision of polygon meshes (n-gons, boundaries) as sparse matrices.

Everything here depends on connectivity (and edge sharpness) alone, so a :class:`CatmullClark` is built once per
``(topology_key, levels, boundary)`` (:attr:`PolyMesh.topology_key` includes the creases) and kept in an LRU cache (:func:`get_catmull_clark`): moving
vertices then costs one sparse product (:attr:`CatmullClark.refine_matrix` or
:attr:`CatmullClark.limit_matrix` times the ``(n, 3)`` control vertices).

Rules (those of OpenSubdiv's Catmull-Clark with the default options, hence Blender's modifier):

* face point: centroid of the face; edge point: ``(v0 + v1 + F0 + F1) / 4``, the midpoint on a
  boundary edge;
* smooth vertex of valence ``n``: ``(n - 2)/n * v + sum(neighbours)/n**2 + sum(face points)/n**2``
  (any face sizes); boundary vertex: ``(u0 + 6 v + u1) / 8`` with its two boundary neighbours;
* ``boundary="all"`` is Blender's ``boundary_smooth='ALL'``, which Blender hands to OpenSubdiv as
  ``VTX_BOUNDARY_EDGE_ONLY`` (lagrange ``VertexBoundaryInterpolation.EdgeOnly``): boundary edges are
  infinitely sharp, every boundary vertex, corners included, follows the cubic B-spline curve rule;
* ``boundary="corners"`` is Blender's ``'PRESERVE_CORNERS'`` = OpenSubdiv ``VTX_BOUNDARY_EDGE_AND_CORNER``
  (lagrange ``EdgeAndCorner``): a topological corner (a boundary vertex with one face and two
  edges) is infinitely sharp and never moves, in the refinement and in the limit;
* a vertex no face uses stays where it is (identity row); a non-manifold vertex (two fans of faces
  meeting at a point, which OpenSubdiv would sharpen) is refused with TopologyError;
* creases (:attr:`PolyMesh.edge_sharpness`, or ``sharpness`` per edge for a Topology) follow OpenSubdiv with
  its default creasing method, ``CREASE_UNIFORM``, which Blender and lagrange use: a child edge has sharpness
  ``s - 1`` (at least 0; ``s >= 10`` is infinite and stays). Edge point of a sharp edge: the midpoint (blended
  ``s : 1 - s`` with the smooth point while ``s < 1``). Vertex point by the number of sharp edges, boundary
  edges included: 0 or 1 (a dart) smooth, 2 crease ``(u0 + 6 v + u1) / 8``, 3 or more a corner ``v``; where
  the next level's rule differs, the two rules blend by the mean sharpness of the edges that decay to 0
  (OpenSubdiv's fractional weight). Blender's crease ``c`` is sharpness ``10 c**2`` (measured); Blender alone
  also sharpens a vertex with exactly two edges by the smaller sharpness of the two (not done here). Creased
  limits are exact: where semi-sharp edges remain after the last level the points are refined further (with
  these rules) until none does; then crease points take ``(u0 + 4 p + u1) / 6``, corners stay and a dart takes
  its exact stencil (the left eigenvector of its 1-ring's subdivision matrix), where OpenSubdiv's own limit
  (lagrange's) keeps the last level's rules and the smooth stencil at darts. OpenSubdiv's evaluators take that
  smooth stencil at their isolation level (lagrange: the last level; Blender's modifier: its ``quality``), so
  their dart points converge to the exact one by the subdominant eigenvalue per level; ``dart_isolation``
  reproduces them (measured: Blender 3.4 to float32 precision at every quality).

Refined order, level by level: vertex points first (in vertex order), then edge points (in
:class:`~gsr_cad.geometry.topology.Topology` edge order), then face points (in face order). Face ``f``
with corners ``c_0 .. c_{m-1}`` becomes ``m`` quads in corner order; quad ``i`` is
``(vertex point c_i, edge point c_i -> c_{i+1}, face point f, edge point c_{i-1} -> c_i)``, which keeps
the orientation of ``f``.

Limit positions (Halstead et al.) on an all-quad mesh: smooth vertex of valence ``n``:
``(n**2 v + 4 sum(neighbours) + sum(diagonal corners)) / (n (n + 5))``; boundary vertex
``(u0 + 4 v + u1) / 6``; preserved corner ``v``. Those stencils hold only where every face around a
vertex is a quad, which a level-0 mesh need not be; so the level-0 limit is taken as the limit of the
level-1 vertex points (the same surface points), ``L_1 @ S_1`` restricted to the vertex-point rows.
OpenSubdiv's level-0 limit (as lagrange returns it) applies the quad stencil beside triangles and
n-gons too and lands off the surface there; its level-1 limit points agree with ours.

Construction is a hot path (the surface GA builds one for every new connectivity), so nothing is sorted
after the input's own Topology: each level's connectivity (twins, edge order, the corners around each
vertex) follows from the previous level's in closed form; every stencil row is written straight into CSR
layout with its weights summed beforehand; the level matrices are composed right to left, one sparse
product per level. The limit stencil of level ``k`` is built from the level ``k - 1`` connectivity, so
the topology of the last level is derived only when asked for (:attr:`CatmullClark.topology`).
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, Literal, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, InputError, TopologyError
from .polymesh import SHARPNESS_INFINITE, PolyMesh
from .surface_distance import triangulate
from .topology import Topology

Boundary = Literal["all", "corners"]
BOUNDARY_MODES: tuple[str, ...] = ("all", "corners")
MAX_REFINED_FACES = 2_000_000
"""Refusing bigger results (about 450 bytes of matrices per refined face) keeps a typo in ``levels`` from
exhausting memory."""


def _check_options(levels: int, boundary: str) -> int:
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 0:
        raise ConfigError(f"subdivision levels must be a whole number >= 0, got {levels!r}")
    if boundary not in BOUNDARY_MODES:
        raise ConfigError(f"boundary must be one of {', '.join(BOUNDARY_MODES)}, got {boundary!r}")
    return int(levels)


def _indptr(counts: np.ndarray) -> np.ndarray:
    out = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=out[1:])
    return out


def _ragged(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For items with ``counts`` entries each: the item of every entry and its rank within the item."""
    owner = np.repeat(np.arange(len(counts)), counts)
    return owner, np.arange(owner.size) - np.repeat(np.cumsum(counts) - counts, counts)


class _Level(NamedTuple):
    """One level of refinement: topology, face offsets, the corners grouped by vertex
    (``vcorners[vptr[v]:vptr[v + 1]]`` are the half-edges leaving ``v``, in no particular order), and
    whether every face is a quad (always so after one step)."""

    topo: Topology
    offsets: np.ndarray
    vptr: np.ndarray
    vcorners: np.ndarray
    quads: bool

    @property
    def sizes(self) -> np.ndarray:
        return np.diff(self.offsets)

    def walk(self, he: np.ndarray, k: np.ndarray | int) -> np.ndarray:
        """The half-edge ``k`` steps after ``he`` around its face."""
        face = self.topo.he_face[he]
        start = self.offsets[face]
        return start + (he - start + k) % (self.offsets[face + 1] - start)


def _base_level(topo: Topology, offsets: np.ndarray) -> _Level:
    counts = np.bincount(topo.he_origin, minlength=topo.n_vertices)
    quads = bool(np.all(np.diff(offsets) == 4))
    return _Level(topo, offsets, _indptr(counts), np.argsort(topo.he_origin, kind="stable"), quads)


def _refined_faces(t: Topology) -> tuple[np.ndarray, np.ndarray]:
    """Corners and offsets of the next level: quad ``h`` for half-edge ``h`` (module docstring)."""
    nv, ne = t.n_vertices, t.n_edges
    corners = np.stack([t.he_origin, nv + t.he_edge, nv + ne + t.he_face, nv + t.he_edge[t.he_prev]], axis=1)
    return corners.ravel(), np.arange(0, corners.size + 1, 4, dtype=np.int64)


def _refined_twins(t: Topology) -> np.ndarray:
    """Twins of the next level in closed form (no sorting): half-edge ``4 h + j`` leaves corner ``j`` of
    quad ``h``; its twin is in the quad of ``next(h)`` or ``prev(h)``, or across the split edge."""
    nxt, prv, twin = t.he_next, t.he_prev, t.he_twin
    twin_prev = twin[prv]
    return np.stack([np.where(twin >= 0, 4 * nxt[twin] + 3, -1), 4 * nxt + 2, 4 * prv + 1,
                     np.where(twin_prev >= 0, 4 * twin_prev, -1)], axis=1).ravel()


def _refined_topology(t: Topology) -> Topology:
    """The next level's topology, derived without sorting (same arrays as Topology's constructor gives)."""
    return Topology.from_twins(*_refined_faces(t), t.n_vertices + t.n_edges + t.n_faces, _refined_twins(t))


def _refined_level(level: _Level) -> _Level:
    """The next level. Its corner groups follow from ``level``'s: at a vertex point, corner 0 of the quads
    of the vertex's corners; at the point of edge ``h0`` (twin ``t0``), corners 1 and 3 of quads ``h0`` and
    ``next(h0)``, then of ``t0`` and ``next(t0)``; at a face point, corner 2 of the face's quads."""
    t = level.topo
    topo = _refined_topology(t)
    h0 = t.edge_halfedge
    t0 = t.he_twin[h0]
    inner = t0 >= 0
    at_edge = np.stack([4 * h0 + 1, 4 * t.he_next[h0] + 3, 4 * t0 + 1, 4 * t.he_next[t0] + 3], axis=1)
    keep = np.ones((t.n_edges, 4), dtype=bool)
    keep[:, 2:] = inner[:, None]
    counts = np.concatenate([np.diff(level.vptr), 2 + 2 * inner, level.sizes])
    vcorners = np.concatenate([4 * level.vcorners, at_edge[keep], 4 * np.arange(len(t.he_origin)) + 2])
    offsets = np.arange(0, len(topo.he_origin) + 1, 4, dtype=np.int64)
    return _Level(topo, offsets, _indptr(counts), vcorners, True)


def _check_manifold(topo: Topology) -> None:
    """Refuse a vertex whose corners form more than one fan (:attr:`Topology.vertex_fans`), and a face on both
    sides of an edge (refinements of any other manifold mesh stay manifold)."""
    if not topo.is_manifold:
        raise TopologyError("Catmull-Clark needs a manifold mesh: a vertex joins separate fans of faces")
    if np.any(topo.edge_faces[:, 0] == topo.edge_faces[:, 1]):  # its refinement would repeat an edge
        raise TopologyError("Catmull-Clark needs faces that do not border themselves: a face is on both sides "
                            "of an edge")


Block = tuple[np.ndarray, Callable[[np.ndarray, np.ndarray], None]]
"""Consecutive rows of a sparse matrix: their lengths, and a function writing their column indices and
values into the slices of the matrix's arrays that hold them (CSR order, positions relative to the slice)."""


def _table(cols: list, vals: list, lengths: np.ndarray | None = None) -> Block:
    """Rows whose entry ``j`` is ``cols[j]``, ``vals[j]`` (arrays over the rows, or numbers); row ``i`` keeps
    its first ``lengths[i]`` entries (all when None)."""
    n, w = len(cols[0]), len(cols)
    if lengths is None:
        def fill(indices, data):
            indices, data = indices.reshape(n, w), data.reshape(n, w)
            for j in range(w):
                indices[:, j] = cols[j]
                data[:, j] = vals[j]
        return np.full(n, w), fill

    def fill(indices, data):
        keep = np.arange(w) < lengths[:, None]
        indices[:] = np.stack(cols, axis=1)[keep]
        data[:] = np.stack(np.broadcast_arrays(*vals), axis=1)[keep]
    return lengths, fill


def _csr(blocks: list[Block], n_cols: int) -> sp.csr_matrix:
    """The CSR matrix of row blocks stacked in order, written in place: no sorting, no summing."""
    lengths = [b[0] for b in blocks]
    sizes = [int(x.sum()) for x in lengths]
    nnz = sum(sizes)
    index = np.int32 if max(n_cols, nnz) < 2**31 else np.int64
    n_rows = sum(len(x) for x in lengths)
    indptr = np.zeros(n_rows + 1, dtype=index)
    np.cumsum(np.concatenate(lengths), out=indptr[1:])
    indices = np.empty(nnz, dtype=index)
    data = np.empty(nnz)
    start = 0
    for (_, fill), size in zip(blocks, sizes):
        fill(indices[start:start + size], data[start:start + size])
        start += size
    return sp.csr_matrix((data, indices, indptr), shape=(n_rows, n_cols))


class _VertexLayout:
    """Where the vertex rows of one level's stencils go in CSR layout; shared by the stencils with the same
    number of entries per smooth corner (on quads, the step and the limit: two each).

    Row of a fixed vertex (unused, or a preserved corner): itself. Of a boundary vertex: itself, then the
    ends of its outgoing and incoming boundary half-edges. Of a smooth vertex: itself, then ``width``
    entries for each of its corners in turn (``generic``: ``size - 2`` for the corner's face, else two).
    """

    def __init__(self, level: _Level, boundary: str, generic: bool):
        t = level.topo
        nv = t.n_vertices
        count = np.diff(level.vptr)
        bh = np.flatnonzero(t.he_twin < 0)
        out_he = np.full(nv, -1, dtype=np.int64)
        out_he[t.he_origin[bh]] = bh
        fixed = count == 0
        if boundary == "corners":  # a topological corner: one face, two boundary edges
            fixed |= (out_he >= 0) & (count == 1)
        self.fixed = fixed
        crease = (out_he >= 0) & ~fixed
        smooth = (out_he < 0) & ~fixed
        self.crease = np.flatnonzero(crease)
        self.smooth = np.flatnonzero(smooth)
        in_he = np.empty(nv, dtype=np.int64)
        in_he[t.he_dest[bh]] = bh
        self.out_he, self.in_he = out_he[self.crease], in_he[self.crease]

        owner = np.repeat(np.arange(nv), count)
        at_smooth = smooth[owner]
        self.corners = level.vcorners[at_smooth]
        self.valence = count.astype(np.float64)
        self.corner_valence = self.valence[owner[at_smooth]]
        self.width = level.sizes[t.he_face[self.corners]] - 2 if generic else 2
        widths = np.zeros(len(owner), dtype=np.int64)
        widths[at_smooth] = self.width
        before = _indptr(widths)
        self.lengths = 1 + 2 * crease + before[level.vptr[1:]] - before[level.vptr[:-1]]
        self.ptr = _indptr(self.lengths)[:-1]
        shift = self.ptr + 1 - before[level.vptr[:-1]]
        self.pos = np.arange(before[-1]) + np.repeat(shift[owner[at_smooth]], self.width)

    def rows(self, smooth_self: np.ndarray, crease: tuple[float, float], crease_cols: tuple, cols: np.ndarray,
             vals: np.ndarray) -> Block:
        """Rows with ``smooth_self`` on each smooth vertex, ``crease`` (self, neighbour) weights on the
        ``crease_cols`` (outgoing, incoming), and ``cols``/``vals`` for the smooth vertices' corners."""
        def fill(indices, data):
            indices[self.ptr] = np.arange(len(self.ptr))
            data[self.ptr] = 1.0
            data[self.ptr[self.smooth]] = smooth_self
            if self.crease.size:
                at = self.ptr[self.crease]
                data[at] = crease[0]
                indices[at + 1], indices[at + 2] = crease_cols
                data[at + 1] = data[at + 2] = crease[1]
            indices[self.pos] = cols
            data[self.pos] = vals
        return self.lengths, fill


def _pairs(a: np.ndarray, b) -> np.ndarray:
    """``a[0], b[0], a[1], b[1], ...`` (``b`` may be a number)."""
    out = np.empty((len(a), 2), dtype=np.result_type(a, b))
    out[:, 0] = a
    out[:, 1] = b
    return out.ravel()


def _step(level: _Level, layout: _VertexLayout) -> sp.csr_matrix:
    """One Catmull-Clark step as a ``(n_v + n_e + n_f, n_v)`` matrix: vertex, edge, then face points.

    Smooth vertex point ``(n - 2)/n v + sum(neighbours)/n**2 + sum(face points)/n**2``, edge point
    ``(v0 + v1 + F0 + F1) / 4``, both with the face points expanded into their corners so that no entry
    repeats (on quads: ``3/(2 n**2)`` per neighbour, ``1/(4 n**2)`` per diagonal; ``3/8`` and ``1/16``);
    boundary vertex ``(u0 + 6 v + u1) / 8``.
    """
    t = level.topo
    nv = t.n_vertices
    o, nxt, prv = t.he_origin, t.he_next, t.he_prev
    sizes = level.sizes
    he, n = layout.corners, layout.corner_valence
    crease_cols = (t.he_dest[layout.out_he], o[layout.in_he])
    if level.quads:  # he ^ 2 is next(next(he)) in a quad
        valence = layout.valence[layout.smooth]
        vertices = layout.rows((valence - 1.75) / valence, (0.75, 0.125), crease_cols,
                               _pairs(o[nxt[he]], o[he ^ 2]), _pairs(1.5 / n**2, 0.25 / n**2))
        h0 = t.edge_halfedge
        t0 = t.he_twin[h0]
        cols = [o[h0], o[nxt[h0]], o[h0 ^ 2], o[prv[h0]], o[t0 ^ 2], o[prv[t0]]]
        if np.all(t0 >= 0):
            edges = _table(cols, [0.375, 0.375, 0.0625, 0.0625, 0.0625, 0.0625])
        else:
            ends = np.where(t0 >= 0, 0.375, 0.5)
            edges = _table(cols, [ends, ends, 0.0625, 0.0625, 0.0625, 0.0625], np.where(t0 >= 0, 6, 2))
    else:  # dest(he), then the corners of face(he) up to prev(he), excluded
        m_he = sizes[t.he_face].astype(np.float64)
        item, rank = _ragged(layout.width)
        near = (1.0 + 1.0 / m_he[he] + 1.0 / m_he[t.he_twin[he]]) / n**2
        vals = np.where(rank == 0, near[item], (1.0 / (n**2 * m_he[he]))[item])
        v = layout.smooth
        inv = np.bincount(o, weights=1.0 / m_he, minlength=nv)[v]
        valence = layout.valence[v]
        vertices = layout.rows((valence - 2.0) / valence + inv / valence**2, (0.75, 0.125), crease_cols,
                               o[level.walk(he[item], rank + 1)], vals)
        edges = _polygon_edge_rows(level)

    def faces(indices, data):
        indices[:] = o
        data[:] = 0.25 if level.quads else np.repeat(1.0 / sizes, sizes)
    return _csr([vertices, edges, (sizes, faces)], nv)


def _polygon_edge_rows(level: _Level) -> Block:
    """Edge-point rows on any polygons: the ends at ``1/4 + 1/(4 m0) + 1/(4 m1)``, the other corners of the
    two faces at ``1/(4 m)``; a boundary edge's midpoint."""
    t = level.topo
    h0 = t.edge_halfedge
    t0 = t.he_twin[h0]
    inner = np.flatnonzero(t0 >= 0)
    hi, ti = h0[inner], t0[inner]
    m0, m1 = level.sizes[t.he_face[hi]], level.sizes[t.he_face[ti]]
    lengths = np.full(t.n_edges, 2, dtype=np.int64)
    lengths[inner] = m0 + m1 - 2

    def fill(indices, data):
        ptr = _indptr(lengths)[:-1]
        indices[ptr], indices[ptr + 1] = t.edges[:, 0], t.edges[:, 1]
        data[ptr] = data[ptr + 1] = 0.5
        data[ptr[inner]] = data[ptr[inner] + 1] = 0.25 + 0.25 / m0 + 0.25 / m1
        for he, m, first in ((hi, m0, 2), (ti, m1, m0)):
            item, rank = _ragged(m - 2)  # the corners of face(he) after dest(he), up to prev(he)
            pos = (ptr[inner] + first)[item] + rank
            indices[pos] = t.he_origin[level.walk(he[item], rank + 2)]
            data[pos] = 0.25 / m[item]
    return lengths, fill


def _limit(level: _Level, layout: _VertexLayout, vertex_points_only: bool = False) -> sp.csr_matrix:
    """``L_{k+1}``: the limit positions of the level-``k + 1`` points (all quads there) in terms of those
    points, built from the level-``k`` connectivity (the level-``k + 1`` topology is never needed).

    Valence-``n`` smooth point: ``(n**2 p + 4 sum(neighbours) + sum(diagonals)) / (n (n + 5))``; boundary
    point ``(u0 + 4 p + u1) / 6``; preserved corner ``p``. Around the vertex point of ``v`` the neighbours
    are the points of ``v``'s edges and the diagonals those of its faces; an edge point (valence 4, or on
    the boundary) has its end points and face points as neighbours and the points of the edges before and
    after it in both faces as diagonals; the point of an ``m``-gon (valence ``m``) has the points of the
    face's edges as neighbours and its corners as diagonals. ``layout`` must have two entries per corner.
    """
    t = level.topo
    nv, ne, nf = t.n_vertices, t.n_edges, t.n_faces
    ep = nv + t.he_edge  # per half-edge: the point of its edge, of its face
    fp = nv + ne + t.he_face
    he, n = layout.corners, layout.corner_valence
    valence = layout.valence[layout.smooth]
    d = 1.0 / (n * (n + 5.0))
    vertices = layout.rows(valence / (valence + 5.0), (4.0 / 6.0, 1.0 / 6.0), (ep[layout.out_he], ep[layout.in_he]),
                           _pairs(ep[he], fp[he]), _pairs(4.0 * d, d))
    n_points = nv + ne + nf
    if vertex_points_only:
        return _csr([vertices], n_points)

    h0 = t.edge_halfedge
    t0 = t.he_twin[h0]
    nxt, prv = t.he_next, t.he_prev
    cols = [nv + np.arange(ne), t.edges[:, 0], t.edges[:, 1], fp[h0], fp[t0], ep[prv[h0]], ep[nxt[h0]], ep[prv[t0]],
            ep[nxt[t0]]]
    if np.all(t0 >= 0):
        edges = _table(cols, [16 / 36, 4 / 36, 4 / 36, 4 / 36, 4 / 36, 1 / 36, 1 / 36, 1 / 36, 1 / 36])
    else:
        inner = t0 >= 0
        self_w, end = np.where(inner, 16 / 36, 4 / 6), np.where(inner, 4 / 36, 1 / 6)
        edges = _table(cols, [self_w, end, end, 4 / 36, 4 / 36, 1 / 36, 1 / 36, 1 / 36, 1 / 36],
                       np.where(inner, 9, 3))

    if level.quads:
        e4, o4 = ep.reshape(nf, 4), t.he_origin.reshape(nf, 4)
        faces = _table([nv + ne + np.arange(nf), e4[:, 0], o4[:, 0], e4[:, 1], o4[:, 1], e4[:, 2], o4[:, 2],
                        e4[:, 3], o4[:, 3]], [4 / 9, 4 / 36, 1 / 36, 4 / 36, 1 / 36, 4 / 36, 1 / 36, 4 / 36, 1 / 36])
    else:
        m = level.sizes
        d = 1.0 / (m * (m + 5.0))

        def fill(indices, data):
            ptr = _indptr(1 + 2 * m)[:-1]
            indices[ptr] = nv + ne + np.arange(nf)
            data[ptr] = m / (m + 5.0)
            pos = ptr[t.he_face] + 1 + 2 * (np.arange(len(t.he_face)) - level.offsets[t.he_face])
            indices[pos], indices[pos + 1] = ep, t.he_origin
            data[pos], data[pos + 1] = 4.0 * d[t.he_face], d[t.he_face]
        faces = (1 + 2 * m, fill)
    return _csr([vertices, edges, faces], n_points)


# --- creases (OpenSubdiv's rules, creasing method uniform: Blender's and lagrange's) ------------------------

def _child_sharpness(s: np.ndarray) -> np.ndarray:
    """Sharpness one level down: infinite stays, otherwise ``max(s - 1, 0)``."""
    return np.where(s >= SHARPNESS_INFINITE, s, np.maximum(s - 1.0, 0.0))


def _refined_sharpness(t: Topology, refined: Topology, s: np.ndarray) -> np.ndarray:
    """Sharpness of the next level's edges: both halves of edge ``e`` (the edges of refined half-edges
    ``4 h0`` and ``4 next(h0) + 3``) get the child sharpness of ``e``, the new inner edges are smooth."""
    out = np.zeros(refined.n_edges)
    h0 = t.edge_halfedge
    child = _child_sharpness(s)
    out[refined.he_edge[4 * h0]] = child
    out[refined.he_edge[4 * t.he_next[h0] + 3]] = child
    return out


def refined_sharpness(mesh: PolyMesh | Topology, refined: Topology, sharpness: np.ndarray | None = None) -> np.ndarray:
    """Edge sharpness of ``refined``, the topology one step of ``mesh`` makes (``CatmullClark(mesh, 1).topology``,
    half-edge ``4 h + k`` in quad ``h``): halves of a creased edge get ``s - 1`` (infinite stays), new edges 0.
    ``sharpness`` defaults to a PolyMesh's own :attr:`~PolyMesh.edge_sharpness`."""
    topo = mesh.topology if isinstance(mesh, PolyMesh) else mesh
    if sharpness is None:
        sharpness = mesh.edge_sharpness if isinstance(mesh, PolyMesh) else np.zeros(topo.n_edges)
    s = _check_sharpness(sharpness, topo)
    return np.zeros(refined.n_edges) if s is None else _refined_sharpness(topo, refined, s)


class _SharpVertices:
    """Per vertex of one level: how many of its edges are sharp (boundary edges count as infinitely sharp),
    the far ends of the first two, and whether one of them is an interior sharp edge (the only vertices
    whose rows differ from those of an uncreased mesh)."""

    def __init__(self, t: Topology, s: np.ndarray):
        sharp = (s > 0.0) | t.edge_is_boundary
        ends = t.edges[sharp]
        at = np.concatenate([ends[:, 0], ends[:, 1]])
        other = np.concatenate([ends[:, 1], ends[:, 0]])
        nv = t.n_vertices
        self.count = np.bincount(at, minlength=nv)
        order = np.argsort(at, kind="stable")
        ptr = _indptr(self.count)[:-1]
        two = self.count >= 2
        self.u0 = np.where(two, other[order[np.minimum(ptr, len(at) - 1)]] if len(at) else 0, -1)
        self.u1 = np.where(two, other[order[np.minimum(ptr + 1, len(at) - 1)]] if len(at) else 0, -1)
        inner = t.edges[(s > 0.0) & ~t.edge_is_boundary]
        self.touched = np.zeros(nv, dtype=bool)
        self.touched[inner.ravel()] = True


def _crease_rows(rows: np.ndarray, centre: np.ndarray, w_centre, u0: np.ndarray, u1: np.ndarray, w_end,
                 n_rows: int, n_cols: int) -> sp.csr_matrix:
    """Sparse rows ``w_centre * centre + w_end * (u0 + u1)`` at ``rows`` (weights may be arrays)."""
    k = len(rows)
    r = np.concatenate([rows, rows, rows])
    c = np.concatenate([centre, u0, u1])
    v = np.concatenate([np.broadcast_to(w_centre, k), np.broadcast_to(w_end, k), np.broadcast_to(w_end, k)])
    keep = v != 0.0
    return sp.csr_matrix((v[keep], (r[keep], c[keep])), shape=(n_rows, n_cols))


def _creased_step(level: _Level, layout: _VertexLayout, smooth: sp.csr_matrix, s: np.ndarray) -> sp.csr_matrix:
    """The step matrix ``smooth`` (uncreased rules) with OpenSubdiv's crease rules where edges of sharpness
    ``s > 0`` are (boundary edges count as infinitely sharp; a fixed vertex stays fixed).

    Edge point of a sharp edge: the midpoint, blended ``s : 1 - s`` with the smooth point while ``s < 1``.
    Vertex point by the number of sharp edges (the rule): 0 or 1 (dart) smooth, 2 crease
    ``(u0 + 6 v + u1) / 8`` along them, 3 or more corner ``v``. When the rule one level down differs
    (semi-sharp edges reaching 0), the point blends this level's rule with the next level's by the mean
    sharpness of the edges that reach 0 (at most 1), as OpenSubdiv's fractional weight does.
    """
    t = level.topo
    nv = t.n_vertices
    n_rows = smooth.shape[0]
    child = _child_sharpness(s)
    here, down = _SharpVertices(t, s), _SharpVertices(t, child)
    keep = np.ones(n_rows)
    extra = []

    e = np.flatnonzero((s > 0.0) & ~t.edge_is_boundary)
    w = np.where(child[e] > 0.0, 1.0, np.minimum(s[e], 1.0))
    keep[nv + e] = 1.0 - w
    extra.append(_crease_rows(nv + e, t.edges[e, 0], 0.5 * w, t.edges[e, 1], t.edges[e, 1], 0.25 * w, n_rows, nv))

    v = np.flatnonzero(here.touched & ~layout.fixed & (here.count >= 2))
    p_rule = np.minimum(here.count[v], 3)  # 2 crease, 3 corner
    c_rule = np.minimum(down.count[v], 3)
    c_rule = np.where(c_rule <= 1, 0, c_rule)  # 0: smooth (or dart)
    fading = (s > 0.0) & (child <= 0.0) & ~t.edge_is_boundary
    ends = t.edges[fading].ravel()
    total = np.bincount(ends, weights=np.repeat(s[fading], 2), minlength=nv)
    n_fading = np.bincount(ends, minlength=nv)
    frac = np.minimum(total[v] / np.maximum(n_fading[v], 1), 1.0)
    pw = np.where(p_rule == c_rule, 1.0, frac)
    # this level's rule, weight pw: crease (3/4, 1/8 on the sharp edges' ends) or corner (1)
    crease = p_rule == 2
    extra.append(_crease_rows(v, v, pw * np.where(crease, 0.75, 1.0), here.u0[v], here.u1[v],
                              pw * np.where(crease, 0.125, 0.0), n_rows, nv))
    # the next level's rule, weight 1 - pw: smooth (the uncreased row) or crease (after a corner)
    keep[v] = np.where(c_rule == 0, 1.0 - pw, 0.0)
    to_crease = np.flatnonzero((c_rule == 2) & (pw < 1.0))
    cv = v[to_crease]
    q = 1.0 - pw[to_crease]
    extra.append(_crease_rows(cv, cv, 0.75 * q, down.u0[cv], down.u1[cv], 0.125 * q, n_rows, nv))
    out = sp.diags(keep) @ smooth
    for m in extra:
        out = out + m
    return out.tocsr()


@functools.lru_cache(maxsize=64)
def _dart_step(n: int) -> np.ndarray:
    """One subdivision step of the 1-ring of a dart of valence ``n`` (all quads, one infinitely sharp edge):
    the point, its edge neighbours ``e_0 .. e_{n-1}`` in fan order from the sharp edge ``e_0``, then the
    diagonals ``f_i`` of the quads between ``e_i`` and ``e_{i+1}`` (smooth vertex rule, the midpoint on
    ``e_0``); the new 1-ring in the same layout."""
    m = 2 * n + 1
    i = np.arange(n)
    j = (i + 1) % n
    faces = np.zeros((n, m))  # the face points F_i of the current 1-ring
    np.add.at(faces, (i, 0), 0.25)
    np.add.at(faces, (i, 1 + i), 0.25)
    np.add.at(faces, (i, 1 + j), 0.25)
    np.add.at(faces, (i, 1 + n + i), 0.25)
    step = np.zeros((m, m))
    step[0, 0] = (n - 2.0) / n
    step[0, 1:1 + n] += 1.0 / n**2
    step[0] += faces.sum(axis=0) / n**2
    for k in range(n):
        if k == 0:
            step[1, 0] = step[1, 1] = 0.5
        else:
            step[1 + k, 0] += 0.25
            step[1 + k, 1 + k] += 0.25
            step[1 + k] += 0.25 * (faces[k - 1] + faces[k])
    step[1 + n:] = faces
    step.setflags(write=False)
    return step


@functools.lru_cache(maxsize=64)
def _dart_mask(n: int, isolation: int | None = None) -> np.ndarray:
    """Limit weights at a dart of valence ``n`` on its 1-ring (layout of :func:`_dart_step`). Exact (``isolation``
    None): the left eigenvector for eigenvalue 1 of the 1-ring's step. OpenSubdiv's evaluators instead take the
    smooth limit stencil at a dart, after ``isolation`` more steps: lagrange's limit with 0, Blender's modifier
    (patches isolated to its ``quality``) with ``quality`` minus the level of the 1-ring; the exact point is
    their limit, reached by the subdominant eigenvalue of the step (0.46 at valence 3, 0.6 at 7) per step."""
    step = _dart_step(n)
    if isolation is None:
        w, vecs = np.linalg.eig(step.T)
        mask = np.real(vecs[:, np.argmin(np.abs(w - 1.0))])
    else:
        smooth = np.concatenate([[float(n * n)], np.full(n, 4.0), np.ones(n)]) / (n * (n + 5))
        mask = smooth @ np.linalg.matrix_power(step, max(int(isolation), 0))
    mask = mask / mask.sum()
    mask.setflags(write=False)
    return mask


def _dart_rows(points: Topology, s: np.ndarray, darts: np.ndarray, n_rows: int,
               isolation: int | None = None) -> sp.csr_matrix:
    """Rows of :func:`_dart_mask` (``isolation`` passed on) at the ``darts`` of the all-quad topology ``points``."""
    out = sp.csr_matrix((n_rows, points.n_vertices))
    if not darts.size:
        return out
    sharp_he = np.flatnonzero(s[points.he_edge] >= SHARPNESS_INFINITE)
    start = np.full(points.n_vertices, -1, dtype=np.int64)
    start[points.he_origin[sharp_he]] = sharp_he
    valence = points.vertex_valence[darts]
    for n in np.unique(valence):
        at = darts[valence == n]
        h = start[at]
        cols = [at]
        ring_e, ring_f = [], []
        for _ in range(n):
            ring_e.append(points.he_dest[h])
            ring_f.append(points.he_origin[points.he_next[points.he_next[h]]])
            h = points.he_twin[points.he_prev[h]]
        cols = np.stack(cols + ring_e + ring_f, axis=1)
        mask = _dart_mask(int(n), isolation)
        rows = np.repeat(at, len(mask))
        out = out + sp.csr_matrix((np.tile(mask, len(at)), (rows, cols.ravel())), shape=out.shape)
    return out


def _creased_limit(limit: sp.csr_matrix, points: Topology, s: np.ndarray, boundary: str,
                   dart_isolation: int | None = None) -> sp.csr_matrix:
    """The limit rows ``limit`` (in terms of the points of the all-quad topology ``points``, whose edges have
    sharpness ``s``, 0 or infinite) where an interior edge is sharp: the crease limit ``(u0 + 4 p + u1) / 6``
    at a point with two sharp edges, the point itself at one with three or more (a preserved corner stays
    fixed), the dart limit (:func:`_dart_mask`, ``dart_isolation`` more steps) at an interior point with one."""
    sv = _SharpVertices(points, s)
    fixed = np.bincount(points.edges.ravel(), minlength=points.n_vertices) == 0
    if boundary == "corners":
        fixed |= points.vertex_is_boundary & (np.diff(points.vertex_faces_csr[0]) == 1)
    v = np.flatnonzero(sv.touched & ~fixed & (sv.count >= 2))
    darts = np.flatnonzero(sv.touched & (sv.count == 1))
    crease = sv.count[v] == 2
    keep = np.ones(limit.shape[0])
    keep[v] = 0.0
    keep[darts] = 0.0
    rows = _crease_rows(v, v, np.where(crease, 4.0 / 6.0, 1.0), sv.u0[v], sv.u1[v], np.where(crease, 1.0 / 6.0, 0.0),
                        limit.shape[0], limit.shape[1])
    return (sp.diags(keep) @ limit + rows + _dart_rows(points, s, darts, limit.shape[0], dart_isolation)).tocsr()


def _check_sharpness(sharpness: np.ndarray | None, topo: Topology) -> np.ndarray | None:
    """Edge sharpness as a float array over ``topo``'s edges (None when nothing is sharp), clipped to
    :data:`SHARPNESS_INFINITE`; InputError for a wrong length or a negative or non-finite value."""
    if sharpness is None:
        return None
    s = np.asarray(sharpness, dtype=np.float64)
    if s.shape != (topo.n_edges,):
        raise InputError(f"expected one sharpness per edge ({topo.n_edges}), got shape {s.shape}")
    if not np.all(np.isfinite(s) & (s >= 0.0)):
        raise InputError("edge sharpness must be finite numbers >= 0")
    s = np.minimum(s, SHARPNESS_INFINITE)
    return s if np.any((s > 0.0) & ~topo.edge_is_boundary) else None


def _semi_sharp(s: np.ndarray) -> bool:
    return bool(np.any((s > 0.0) & (s < SHARPNESS_INFINITE)))


def _exact_limit(level: _Level, layout: _VertexLayout, s: np.ndarray, boundary: str,
                 vertex_points_only: bool, depth: int, dart_isolation: int | None = None) -> sp.csr_matrix:
    """Creased ``L_{k+1}`` (the limit of the level-``k + 1`` points, in terms of them; only the vertex points'
    rows with ``vertex_points_only``). Where semi-sharp edges remain at level ``k + 1`` the points are
    refined further, with the crease rules, until every sharpness is 0 or infinite; there the crease and
    corner limits are exact and the smooth stencil holds elsewhere. Each point's limit is that of the
    vertex point it becomes (vertex points come first at every level). ``depth`` is the level number of
    ``k + 1``; with ``dart_isolation`` darts take OpenSubdiv's stencil at that level (:func:`_dart_mask`)."""
    t = level.topo
    n_points = t.n_vertices if vertex_points_only else t.n_vertices + t.n_edges + t.n_faces
    finer = _refined_level(level)
    s_points = _refined_sharpness(t, finer.topo, s)
    extra = None
    while _semi_sharp(s_points):
        if len(finer.topo.he_origin) * 4 > MAX_REFINED_FACES:
            raise ConfigError(f"the limit of semi-sharp creases (sharpness up to {s_points.max():g}) needs more "
                              f"than {MAX_REFINED_FACES} faces; use fewer levels' worth of sharpness")
        level, s = finer, s_points
        layout = _VertexLayout(level, boundary, generic=False)
        step = _creased_step(level, layout, _step(level, layout), s)
        extra = step if extra is None else step @ extra
        finer = _refined_level(level)
        s_points = _refined_sharpness(level.topo, finer.topo, s)
        depth += 1
    isolation = None if dart_isolation is None else dart_isolation - depth
    out = _creased_limit(_limit(level, layout), finer.topo, s_points, boundary, isolation)
    if extra is not None:
        out = out @ extra
    return out[:n_points]


class CatmullClark:
    """Catmull-Clark refinement and limit evaluation for one connectivity, as sparse matrices.

    ``refine_matrix`` (``(N, n)``, CSR) maps the ``n`` control vertices to the ``N`` vertices after
    ``levels`` steps; ``limit_matrix`` (``(N, n)``, CSR) maps them to the limit-surface positions of
    those ``N`` vertices. ``corners``/``offsets`` are the refined faces in PolyMesh layout.
    ``dart_isolation`` (None: exact) puts the limit at infinitely sharp darts where OpenSubdiv's evaluators
    put it, the smooth stencil after that many steps from the control mesh (lagrange: ``levels``; Blender's
    modifier: its ``quality``), to compare with those hosts point for point (:func:`_dart_mask`).
    """

    def __init__(self, mesh: PolyMesh | Topology, levels: int = 1, boundary: Boundary = "all",
                 sharpness: np.ndarray | None = None, dart_isolation: int | None = None):
        levels = _check_options(levels, boundary)
        if dart_isolation is not None and (isinstance(dart_isolation, bool) or not isinstance(
                dart_isolation, (int, np.integer)) or dart_isolation < 0):
            raise ConfigError(f"dart_isolation must be a whole number >= 0 or None, got {dart_isolation!r}")
        if isinstance(mesh, PolyMesh):
            topo, corners, offsets = mesh.topology, mesh.corners, mesh.offsets
            if sharpness is None and mesh.crease_values.size:
                sharpness = mesh.edge_sharpness
        elif isinstance(mesh, Topology):
            topo, corners = mesh, mesh.he_origin
            offsets = np.concatenate([[0], np.cumsum(np.bincount(mesh.he_face, minlength=mesh.n_faces))])
        else:
            raise InputError(f"CatmullClark needs a PolyMesh or Topology, got {type(mesh).__name__}")
        if topo.n_faces == 0:
            raise TopologyError("cannot subdivide a mesh without faces")
        s = _check_sharpness(sharpness, topo)
        n_out = len(corners) * 4 ** (levels - 1) if levels else topo.n_faces
        if n_out > MAX_REFINED_FACES:
            raise ConfigError(
                f"{levels} levels on {topo.n_faces} faces would make {n_out} faces (limit {MAX_REFINED_FACES})")
        base = _base_level(topo, offsets)
        _check_manifold(topo)
        self.levels = levels
        self.boundary = boundary
        self.n_control = topo.n_vertices

        level, refine = base, None  # composed right to left: one sparse product per level, then the limit
        for k in range(max(levels, 1)):
            if k:
                finer = _refined_level(level)
                if s is not None:
                    s = _refined_sharpness(level.topo, finer.topo, s)
                level = finer
            layout = _VertexLayout(level, boundary, generic=not level.quads)
            step = _step(level, layout)
            if s is not None:
                step = _creased_step(level, layout, step, s)
            refine = step if refine is None else step @ refine
        if not level.quads:
            layout = _VertexLayout(level, boundary, generic=False)
        # level 0: the limit of the level-1 vertex points (they come first), a map of the control vertices
        if s is None:
            limit = _limit(level, layout, vertex_points_only=levels == 0) @ refine
        else:
            limit = _exact_limit(level, layout, s, boundary, levels == 0, max(levels, 1), dart_isolation) @ refine
        self._coarse: Topology | None = None
        if levels == 0:
            refine = sp.identity(self.n_control, format="csr")
            self.topology = topo
            corners, offsets = np.array(corners, dtype=np.int64), np.array(offsets, dtype=np.int64)
        else:
            self._coarse = level.topo  # the refined topology follows from it, when asked for
            corners, offsets = _refined_faces(level.topo)
        corners.setflags(write=False)
        offsets.setflags(write=False)
        self.refine_matrix: sp.csr_matrix = refine
        self.limit_matrix: sp.csr_matrix = limit
        self.corners: np.ndarray = corners
        self.offsets: np.ndarray = offsets

    @functools.cached_property
    def topology(self) -> Topology:
        """Topology of the refined faces, derived in closed form on first use (the matrices never need it)."""
        return _refined_topology(self._coarse)

    @functools.cached_property
    def triangles(self) -> np.ndarray:
        """Fan triangles of the refined faces (:func:`~gsr_cad.geometry.surface_distance.triangulate`), read-only,
        built once per connectivity (the distances of every evaluation use them)."""
        tris = triangulate(self.corners, self.offsets)
        tris.setflags(write=False)
        return tris

    @functools.cached_property
    def _template(self) -> PolyMesh:
        return PolyMesh(np.zeros((self.n_vertices, 3)), self.corners, self.offsets,
                        _topology=self.__dict__.get("topology"))

    @functools.cached_property
    def topology_key(self) -> tuple:
        """:attr:`PolyMesh.topology_key` of the refined faces, shared by every output once asked for."""
        return self._template.topology_key

    @property
    def n_vertices(self) -> int:
        """Number of refined vertices."""
        return self.refine_matrix.shape[0]

    @property
    def n_faces(self) -> int:
        return len(self.offsets) - 1

    @property
    def faces(self) -> list[tuple[int, ...]]:
        """Refined faces as vertex-index tuples (same meaning as :attr:`PolyMesh.faces`)."""
        return self._template.faces

    @property
    def nbytes(self) -> int:
        """Approximate memory held by the matrices, the refined faces and the topology they derive from."""
        m = (self.refine_matrix, self.limit_matrix)
        held = vars(self._coarse).values() if self._coarse is not None else ()
        return (sum(x.data.nbytes + x.indices.nbytes + x.indptr.nbytes for x in m) + 2 * self.corners.nbytes
                + sum(a.nbytes for a in held if isinstance(a, np.ndarray)))

    def _apply(self, matrix: sp.csr_matrix, vertices: np.ndarray) -> PolyMesh:
        v = np.asarray(vertices, dtype=np.float64)
        if v.shape != (self.n_control, 3):
            raise InputError(f"expected ({self.n_control}, 3) control vertices, got shape {v.shape}")
        out = matrix @ v
        out.setflags(write=False)
        # valid faces by construction; the refined topology and key are shared once derived, before that an
        # output derives its own on demand
        return PolyMesh._trusted(out, self.corners, self.offsets, self.__dict__.get("topology"),
                                 self.__dict__.get("topology_key"))

    def refine(self, vertices: np.ndarray) -> PolyMesh:
        """The mesh after ``levels`` refinement steps of control vertices ``vertices``."""
        return self._apply(self.refine_matrix, vertices)

    def limit(self, vertices: np.ndarray) -> PolyMesh:
        """The refined faces with every vertex moved to its limit-surface position."""
        return self._apply(self.limit_matrix, vertices)

    def __repr__(self) -> str:
        return (f"CatmullClark({self.n_control} -> {self.n_vertices} vertices, {self.n_faces} faces, "
                f"levels={self.levels}, boundary={self.boundary!r})")


class _Cache:
    """Thread-safe LRU of CatmullClark objects, bounded by entry count and by bytes (each entry's size as
    measured when it was stored: the topology it holds may gain cached arrays later)."""

    def __init__(self, max_entries: int = 256, max_bytes: int = 512 * 2**20):
        self.max_entries, self.max_bytes = max_entries, max_bytes
        self._items: OrderedDict[tuple, tuple[CatmullClark, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    def get(self, mesh: PolyMesh, levels: int, boundary: str) -> CatmullClark:
        levels = _check_options(levels, boundary)
        key = (mesh.topology_key, levels, boundary)
        with self._lock:
            item = self._items.get(key)
            if item is not None:
                self._items.move_to_end(key)
                self.hits += 1
                return item[0]
            self.misses += 1
        cc = CatmullClark(mesh, levels, boundary)
        with self._lock:
            if key not in self._items:
                size = cc.nbytes
                self._items[key] = (cc, size)
                self._bytes += size
            while self._items and (len(self._items) > self.max_entries or self._bytes > self.max_bytes):
                _, (_, size) = self._items.popitem(last=False)
                self._bytes -= size
        return cc

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
            self._bytes = 0
            self.hits = self.misses = 0

    def info(self) -> dict[str, int]:
        with self._lock:
            return {"entries": len(self._items), "bytes": self._bytes, "hits": self.hits, "misses": self.misses}


_CACHE = _Cache()


class TopologyLRU:
    """Thread-safe LRU, bounded by entry count, of values that depend on a mesh's connectivity only (keys
    start with its ``topology_key``); ``get(key, build)`` builds a missing value outside the lock."""

    def __init__(self, size: int):
        self.size = size
        self._items: OrderedDict[tuple, Any] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple, build: Callable[[], Any]) -> Any:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        value = build()
        with self._lock:
            self._items[key] = value
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return value


def get_catmull_clark(mesh: PolyMesh, levels: int, boundary: Boundary = "all") -> CatmullClark:
    """The :class:`CatmullClark` of ``mesh``'s connectivity, from the LRU cache when it was built before."""
    if not isinstance(mesh, PolyMesh):
        raise InputError(f"get_catmull_clark needs a PolyMesh, got {type(mesh).__name__}")
    return _CACHE.get(mesh, levels, boundary)


def clear_cache() -> None:
    """Forget every cached CatmullClark (benchmarks, memory pressure)."""
    _CACHE.clear()


def cache_info() -> dict[str, int]:
    """``{"entries", "bytes", "hits", "misses"}`` of the subdivision cache."""
    return _CACHE.info()


def refine(mesh: PolyMesh, levels: int = 1, boundary: Boundary = "all") -> PolyMesh:
    """``mesh`` after ``levels`` Catmull-Clark steps (order: see the module docstring)."""
    return get_catmull_clark(mesh, levels, boundary).refine(mesh.vertices)


def limit_mesh(mesh: PolyMesh, levels: int = 3, boundary: Boundary = "all") -> PolyMesh:
    """The level-``levels`` refined faces with vertices on the limit surface."""
    return get_catmull_clark(mesh, levels, boundary).limit(mesh.vertices)
