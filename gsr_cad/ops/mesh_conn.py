"""Plain-Python connectivity of a polygon mesh, cached by topology, for the mesh ops.

GA replays apply thousands of short op sequences to small meshes, where dict and list lookups beat
numpy's per-call overhead. :class:`MeshConn` holds what the ops need (face cycles, the face owning each
directed edge, edges numbered exactly as :class:`~gsr_cad.geometry.topology.Topology` numbers them) and is
kept in a small LRU cache keyed by :attr:`PolyMesh.connectivity_key`, so ops that only move vertices
(V, F, S) and repeated prefixes never rebuild it. :class:`MeshView` keeps, for recently seen meshes, the
plain-float positions and the face Newell vectors computed so far, so that the next op of a replay neither
converts the positions again nor recomputes the faces it did not change.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from itertools import accumulate, chain

import numpy as np

from ..errors import TopologyError
from ..geometry.polymesh import PolyMesh


class MeshConn:
    """Face cycles, directed-edge owners and edges (first-appearance order) of one connectivity.

    ``half[(u, v)]`` is the face whose corner cycle runs ``u -> v``. Edges and vertex-face lists are
    derived on first use (only L, B and :func:`~gsr_cad.ops.mesh.random_op` need edges).
    """

    __slots__ = ("faces", "n_vertices", "half", "_edges", "_edge_id", "_vfaces")

    def __init__(self, faces: list[tuple[int, ...]], n_vertices: int,
                 half: dict[tuple[int, int], int] | None = None):
        if half is None:
            heads = [c for cyc in faces for c in cyc]
            tails = [c for cyc in faces for c in cyc[1:] + cyc[:1]]
            owner = [f for f, cyc in enumerate(faces) for _ in cyc]
            half = dict(zip(zip(heads, tails), owner))
            if len(half) != len(heads):
                raise TopologyError("an edge is used twice in the same direction (non-manifold or "
                                    "inconsistently oriented faces)")
        self.faces = faces
        self.n_vertices = n_vertices
        self.half = half
        self._edges: list[tuple[int, int]] | None = None
        self._edge_id: dict[tuple[int, int], int] | None = None
        self._vfaces: list[list[int]] | None = None

    @classmethod
    def updated(cls, old: MeshConn, faces: list[tuple[int, ...]], changed: list[int], n_vertices: int) -> MeshConn:
        """Connectivity of ``faces``, which differ from ``old.faces`` only in the ``changed`` faces
        (modified or appended): the owner map is patched instead of rebuilt."""
        half = dict(old.half)
        n_old = len(old.faces)
        for f in changed:
            if f < n_old:
                cyc = old.faces[f]
                for key in zip(cyc, cyc[1:] + cyc[:1]):
                    if half.get(key) == f:
                        del half[key]
        for f in changed:
            cyc = faces[f]
            for key in zip(cyc, cyc[1:] + cyc[:1]):
                if key in half:
                    raise TopologyError("an edge is used twice in the same direction (non-manifold or "
                                        "inconsistently oriented faces)")
                half[key] = f
        return cls(faces, n_vertices, half)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def _build_edges(self) -> None:
        pairs = [p for cyc in self.faces for p in zip(cyc, cyc[1:] + cyc[:1])]
        keys = [(u, v) if u < v else (v, u) for u, v in pairs]
        first = dict(zip(reversed(keys), reversed(pairs)))  # the earliest half-edge of each edge wins
        order = list(dict.fromkeys(keys))
        self._edges = [first[k] for k in order]
        self._edge_id = dict(zip(order, range(len(order))))

    @property
    def edges(self) -> list[tuple[int, int]]:
        """``(origin, destination)`` of each edge's first half-edge, in Topology's edge order."""
        if self._edges is None:
            self._build_edges()
        return self._edges

    @property
    def edge_id(self) -> dict[tuple[int, int], int]:
        """Edge index of ``(min vertex, max vertex)``."""
        if self._edge_id is None:
            self._build_edges()
        return self._edge_id

    def edge_faces(self, e: int) -> tuple[int, int]:
        """``(face of the edge's first half-edge, face on the other side or -1)``, as Topology.edge_faces."""
        u, v = self.edges[e]
        return self.half[(u, v)], self.half.get((v, u), -1)

    def vertex_faces(self, v: int) -> list[int]:
        """Faces that use vertex ``v`` (in face order)."""
        if self._vfaces is None:
            vf: list[list[int]] = [[] for _ in range(self.n_vertices)]
            for f, cyc in enumerate(self.faces):
                for c in cyc:
                    vf[c].append(f)
            self._vfaces = vf
        return self._vfaces[v]


class _LRU:
    """A small thread-safe LRU map from topology keys to :class:`MeshConn`."""

    def __init__(self, maxsize: int):
        self.maxsize = maxsize
        self._data: OrderedDict[tuple, MeshConn] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple) -> MeshConn | None:
        with self._lock:
            conn = self._data.get(key)
            if conn is not None:
                self._data.move_to_end(key)
            return conn

    def put(self, key: tuple, conn: MeshConn) -> None:
        with self._lock:
            self._data[key] = conn
            self._data.move_to_end(key)
            while len(self._data) > self.maxsize:
                self._data.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._data.clear()


_CACHE = _LRU(maxsize=1024)
"""Each op caches its result's connectivity, which the next op of a replay reads at once: a small cache
serves replays; the rest is reuse across genomes that share prefixes."""


def cached_connectivity(key: tuple) -> MeshConn | None:
    """The cached :class:`MeshConn` of a :attr:`PolyMesh.connectivity_key`, or None."""
    return _CACHE.get(key)


def cache_connectivity(key: tuple, conn: MeshConn) -> None:
    """Remember ``conn`` as the connectivity of topology key ``key``."""
    _CACHE.put(key, conn)


def face_arrays(n_vertices: int, faces: list[tuple[int, ...]]) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Read-only ``(corners, offsets)`` of ``faces`` and the :attr:`PolyMesh.connectivity_key` they give."""
    offsets = np.fromiter(accumulate(map(len, faces), initial=0), np.int64, len(faces) + 1)
    corners = np.fromiter(chain.from_iterable(faces), np.int64, int(offsets[-1]))
    corners.setflags(write=False)
    offsets.setflags(write=False)
    return corners, offsets, (n_vertices, offsets.tobytes(), corners.tobytes())


def connectivity(mesh: PolyMesh) -> MeshConn:
    """The (cached) :class:`MeshConn` of ``mesh``; raises TopologyError for a non-manifold mesh."""
    key = mesh.connectivity_key
    conn = _CACHE.get(key)
    if conn is None:
        conn = MeshConn(mesh.faces, mesh.n_vertices)
        _CACHE.put(key, conn)
    return conn


class MeshView:
    """Plain-Python companion of one mesh for the ops: its vertex rows ``P`` as lists of floats (never
    mutated: ops copy the outer list and replace rows), ``newell[f]`` the Newell vector of face ``f`` as
    :func:`~gsr_cad.ops.mesh_kernel.face_newell` computes it on ``P`` (None until needed), its connectivity
    and ``bounds`` (``(xmin, ymin, zmin, xmax, ymax, zmax)`` of ``P``, None until needed).

    The mesh is immutable, so these never go stale; an op builds the view of its result from its input's
    (faces it did not change and whose vertices did not move keep their Newell vector).
    """

    __slots__ = ("mesh", "P", "newell", "conn", "bounds")

    def __init__(self, mesh: PolyMesh, P: list[list[float]], newell: list, conn: MeshConn,
                 bounds: tuple[float, ...] | None = None):
        self.mesh, self.P, self.newell, self.conn, self.bounds = mesh, P, newell, conn, bounds


class _Views:
    """The views of the last ``maxsize`` meshes, by identity (each entry holds its mesh, so ids stay unique)."""

    def __init__(self, maxsize: int):
        self.maxsize = maxsize
        self._data: dict[int, MeshView] = {}
        self._lock = threading.Lock()

    def get(self, mesh: PolyMesh) -> MeshView | None:
        view = self._data.get(id(mesh))
        return view if view is not None and view.mesh is mesh else None

    def put(self, view: MeshView) -> None:
        with self._lock:
            self._data[id(view.mesh)] = view
            if len(self._data) > self.maxsize:
                del self._data[next(iter(self._data))]

    def clear(self) -> None:
        with self._lock:
            self._data.clear()


_VIEWS = _Views(maxsize=256)


def mesh_view(mesh: PolyMesh) -> MeshView:
    """The :class:`MeshView` of ``mesh`` (built and remembered on first use)."""
    view = _VIEWS.get(mesh)
    if view is None:
        view = MeshView(mesh, mesh.vertices.tolist(), [None] * mesh.n_faces, connectivity(mesh))
        _VIEWS.put(view)
    return view


def remember_view(view: MeshView) -> None:
    """Keep ``view`` (an op's result) for the next op on its mesh."""
    _VIEWS.put(view)


def clear_cache() -> None:
    """Forget every cached connectivity and mesh view (tests, memory)."""
    _CACHE.clear()
    _VIEWS.clear()
