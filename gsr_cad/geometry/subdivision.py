"""Catmull-Clark subdivision of polygon meshes (n-gons, boundaries) as sparse matrices.

Everything here depends on connectivity alone, so a :class:`CatmullClark` is built once per
``(topology_key, levels, boundary)`` and kept in an LRU cache (:func:`get_catmull_clark`): moving
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
  meeting at a point, which OpenSubdiv would sharpen) is refused with TopologyError.

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
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Literal

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, InputError, TopologyError
from .polymesh import PolyMesh
from .topology import Topology

Boundary = Literal["all", "corners"]
BOUNDARY_MODES: tuple[str, ...] = ("all", "corners")
MAX_REFINED_FACES = 2_000_000
"""Refusing bigger results (about 450 bytes of matrices per refined face) keeps a typo in ``levels`` from
exhausting memory."""


def _ragged_face_corners(offsets: np.ndarray, sizes: np.ndarray, owner_face: np.ndarray):
    """For every item ``i`` owning face ``owner_face[i]``: ``(item index, corner index)`` over that face."""
    counts = sizes[owner_face]
    item = np.repeat(np.arange(len(owner_face)), counts)
    starts = np.cumsum(counts) - counts
    local = np.arange(int(counts.sum())) - np.repeat(starts, counts)
    return item, offsets[owner_face][item] + local


def _fixed_vertices(topo: Topology, boundary: str) -> np.ndarray:
    """Vertices that never move: unused ones, and topological corners in "corners" mode."""
    faces_at = np.bincount(topo.he_origin, minlength=topo.n_vertices)
    fixed = faces_at == 0
    if boundary == "corners":
        fixed |= topo.vertex_is_boundary & (faces_at == 1) & (topo.vertex_valence == 2)
    return fixed


def _check_options(levels: int, boundary: str) -> int:
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 0:
        raise ConfigError(f"subdivision levels must be a whole number >= 0, got {levels!r}")
    if boundary not in BOUNDARY_MODES:
        raise ConfigError(f"boundary must be one of {', '.join(BOUNDARY_MODES)}, got {boundary!r}")
    return int(levels)


def _check_manifold(topo: Topology) -> None:
    from .validation import vertex_fans

    if np.any(vertex_fans(topo) > 1):
        raise TopologyError("Catmull-Clark needs a manifold mesh: a vertex joins separate fans of faces")


def _step(topo: Topology, offsets: np.ndarray, boundary: str) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """One Catmull-Clark step: the ``(n_v + n_e + n_f, n_v)`` matrix and the refined corners/offsets."""
    nv, ne, nf = topo.n_vertices, topo.n_edges, topo.n_faces
    corners = topo.he_origin
    sizes = np.diff(offsets)
    n_he = len(corners)
    he_face = topo.he_face
    he_edge = topo.he_edge
    e_boundary = topo.edge_is_boundary
    v_boundary = topo.vertex_is_boundary
    valence = topo.vertex_valence.astype(np.float64)
    fixed = _fixed_vertices(topo, boundary)
    smooth = ~v_boundary & ~fixed
    crease = v_boundary & ~fixed
    inv_n2 = np.divide(1.0, valence**2, out=np.zeros(nv), where=valence > 0)
    a, b = topo.edges[:, 0], topo.edges[:, 1]
    inv_size = 1.0 / sizes

    rows, cols, vals = [], [], []

    # face points
    rows.append(nv + ne + he_face)
    cols.append(corners)
    vals.append(inv_size[he_face])

    # edge points: the two end points, plus the face points on an interior edge
    ew = np.where(e_boundary, 0.5, 0.25)
    rows += [nv + np.arange(ne)] * 2
    cols += [a, b]
    vals += [ew, ew]
    interior_he = np.flatnonzero(~e_boundary[he_edge])
    item, corner = _ragged_face_corners(offsets, sizes, he_face[interior_he])
    rows.append(nv + he_edge[interior_he][item])
    cols.append(corners[corner])
    vals.append(0.25 * inv_size[he_face[interior_he]][item])

    # vertex points: self weight
    smooth_w = np.divide(valence - 2.0, valence, out=np.zeros(nv), where=valence > 0)
    self_w = np.where(fixed, 1.0, np.where(crease, 0.75, smooth_w))
    rows.append(np.arange(nv))
    cols.append(np.arange(nv))
    vals.append(self_w)
    # smooth vertices: every edge neighbour and every face point at 1 / n**2
    for p, q in ((a, b), (b, a)):
        m = smooth[p]
        rows.append(p[m])
        cols.append(q[m])
        vals.append(inv_n2[p[m]])
    smooth_he = np.flatnonzero(smooth[corners])
    item, corner = _ragged_face_corners(offsets, sizes, he_face[smooth_he])
    v_of = corners[smooth_he][item]
    rows.append(v_of)
    cols.append(corners[corner])
    vals.append(inv_n2[v_of] * inv_size[he_face[smooth_he]][item])
    # boundary vertices: the two boundary neighbours at 1/8
    for p, q in ((a, b), (b, a)):
        m = e_boundary & crease[p]
        rows.append(p[m])
        cols.append(q[m])
        vals.append(np.full(int(m.sum()), 0.125))

    matrix = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nv + ne + nf, nv))
    matrix.sum_duplicates()

    quads = np.stack([corners, nv + he_edge, nv + ne + he_face, nv + he_edge[topo.he_prev]], axis=1)
    return matrix, quads.ravel(), np.arange(0, 4 * n_he + 1, 4, dtype=np.int64)


def _limit_stencil(topo: Topology, boundary: str) -> sp.csr_matrix:
    """Limit positions of the vertices of an all-quad mesh, ``(n_v, n_v)``."""
    nv = topo.n_vertices
    fixed = _fixed_vertices(topo, boundary)
    smooth = ~topo.vertex_is_boundary & ~fixed
    crease = topo.vertex_is_boundary & ~fixed
    n = topo.vertex_valence.astype(np.float64)
    denom = np.where(smooth, n * (n + 5.0), 1.0)
    a, b = topo.edges[:, 0], topo.edges[:, 1]
    e_boundary = topo.edge_is_boundary

    rows = [np.arange(nv)]
    cols = [np.arange(nv)]
    vals = [np.where(fixed, 1.0, np.where(crease, 4.0 / 6.0, n * n / denom))]
    for p, q in ((a, b), (b, a)):
        m = smooth[p]
        rows.append(p[m])
        cols.append(q[m])
        vals.append(4.0 / denom[p[m]])
        m = crease[p] & e_boundary
        rows.append(p[m])
        cols.append(q[m])
        vals.append(np.full(int(m.sum()), 1.0 / 6.0))
    he = np.flatnonzero(smooth[topo.he_origin])
    diagonal = topo.he_origin[topo.he_next[topo.he_next[he]]]
    rows.append(topo.he_origin[he])
    cols.append(diagonal)
    vals.append(1.0 / denom[topo.he_origin[he]])
    matrix = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nv, nv))
    matrix.sum_duplicates()
    return matrix


class CatmullClark:
    """Catmull-Clark refinement and limit evaluation for one connectivity, as sparse matrices.

    ``refine_matrix`` (``(N, n)``, CSR) maps the ``n`` control vertices to the ``N`` vertices after
    ``levels`` steps; ``limit_matrix`` (``(N, n)``, CSR) maps them to the limit-surface positions of
    those ``N`` vertices. ``corners``/``offsets`` are the refined faces in PolyMesh layout.
    """

    def __init__(self, mesh: PolyMesh | Topology, levels: int = 1, boundary: Boundary = "all"):
        levels = _check_options(levels, boundary)
        if isinstance(mesh, PolyMesh):
            topo, corners, offsets = mesh.topology, mesh.corners, mesh.offsets
        elif isinstance(mesh, Topology):
            topo, corners = mesh, mesh.he_origin
            offsets = np.concatenate([[0], np.cumsum(np.bincount(mesh.he_face, minlength=mesh.n_faces))])
        else:
            raise InputError(f"CatmullClark needs a PolyMesh or Topology, got {type(mesh).__name__}")
        if topo.n_faces == 0:
            raise TopologyError("cannot subdivide a mesh without faces")
        n_out = len(corners) * 4 ** (levels - 1) if levels else topo.n_faces
        if n_out > MAX_REFINED_FACES:
            raise ConfigError(
                f"{levels} levels on {topo.n_faces} faces would make {n_out} faces (limit {MAX_REFINED_FACES})")
        _check_manifold(topo)
        self.levels = levels
        self.boundary = boundary
        self.n_control = topo.n_vertices

        base = (topo, corners, offsets)
        refine = sp.identity(topo.n_vertices, format="csr")
        for _ in range(max(levels, 1)):
            step, corners, offsets = _step(topo, offsets, boundary)
            refine = step @ refine
            topo = Topology(corners, offsets, step.shape[0])
        limit = _limit_stencil(topo, boundary) @ refine
        if levels == 0:
            # Level-0 limit = limit of the level-1 vertex points (they come first).
            limit = limit[: self.n_control]
            refine = sp.identity(self.n_control, format="csr")
            topo, corners, offsets = base
        self.refine_matrix: sp.csr_matrix = sp.csr_matrix(refine)
        self.limit_matrix: sp.csr_matrix = sp.csr_matrix(limit)
        self.topology: Topology = topo
        self._template = PolyMesh(np.zeros((topo.n_vertices, 3)), corners, offsets, _topology=topo)
        self.topology_key: tuple = self._template.topology_key  # of the refined faces, shared by every output
        self.corners: np.ndarray = self._template.corners
        self.offsets: np.ndarray = self._template.offsets

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
        """Approximate memory held by the matrices and the refined faces."""
        m = (self.refine_matrix, self.limit_matrix)
        return sum(x.data.nbytes + x.indices.nbytes + x.indptr.nbytes for x in m) + 2 * self.corners.nbytes

    def _apply(self, matrix: sp.csr_matrix, vertices: np.ndarray) -> PolyMesh:
        v = np.asarray(vertices, dtype=np.float64)
        if v.shape != (self.n_control, 3):
            raise InputError(f"expected ({self.n_control}, 3) control vertices, got shape {v.shape}")
        return self._template.with_vertices(matrix @ v)

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
    """Thread-safe LRU of CatmullClark objects, bounded by entry count and by bytes."""

    def __init__(self, max_entries: int = 256, max_bytes: int = 512 * 2**20):
        self.max_entries, self.max_bytes = max_entries, max_bytes
        self._items: OrderedDict[tuple, CatmullClark] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    def get(self, mesh: PolyMesh, levels: int, boundary: str) -> CatmullClark:
        levels = _check_options(levels, boundary)
        key = (mesh.topology_key, levels, boundary)
        with self._lock:
            cc = self._items.get(key)
            if cc is not None:
                self._items.move_to_end(key)
                self.hits += 1
                return cc
            self.misses += 1
        cc = CatmullClark(mesh, levels, boundary)
        with self._lock:
            if key not in self._items:
                self._items[key] = cc
                self._bytes += cc.nbytes
            while self._items and (len(self._items) > self.max_entries or self._bytes > self.max_bytes):
                _, old = self._items.popitem(last=False)
                self._bytes -= old.nbytes
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
