"""Half-edge topology derived from a flat corner list; built once per connectivity.

Half-edge ``h`` is corner ``h`` of the corner list: it runs from ``corners[h]`` to the next corner of
the same face. Edges are numbered in order of their first half-edge (so edge order is deterministic:
it follows face order, then corner order). ``-1`` marks "none" (boundary twin, boundary edge face).

Twins come from one sort of the undirected edge keys; everything else is linear. Connectivity whose
twins are known in closed form (a Catmull-Clark refinement) skips the sort: :meth:`Topology.from_twins`.
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import TopologyError


class Topology:
    """Connectivity arrays of a polygon mesh (read-only after construction)."""

    def __init__(self, corners: np.ndarray, offsets: np.ndarray, n_vertices: int):
        self._set_faces(corners, offsets, n_vertices)
        if np.any(self.he_origin == self.he_dest):
            raise TopologyError("a face repeats a vertex on consecutive corners")
        # Twins: sort the half-edges by undirected key; an edge is a run of one or two equal keys.
        n = np.int64(max(n_vertices, 1))
        lo = np.minimum(self.he_origin, self.he_dest)
        hi = np.maximum(self.he_origin, self.he_dest)
        undirected = lo * n + hi
        order = np.argsort(undirected)
        key = undirected[order]
        pair = np.flatnonzero(key[1:] == key[:-1])
        first, second = order[pair], order[pair + 1]
        if (np.any(pair[1:] == pair[:-1] + 1)  # three or more half-edges on one edge
                or np.any(self.he_origin[first] == self.he_origin[second])):
            raise TopologyError(
                "an edge is used twice in the same direction (non-manifold or inconsistently oriented faces)")
        twin = np.full(len(self.he_origin), -1, dtype=np.int64)
        twin[first] = second
        twin[second] = first
        self._set_edges(twin)

    @classmethod
    def from_twins(cls, corners: np.ndarray, offsets: np.ndarray, n_vertices: int, he_twin: np.ndarray) -> Topology:
        """The topology of faces whose twin half-edges are already known (``-1`` on the boundary).

        No sorting and no checks: for connectivity derived in closed form from a valid topology
        (Catmull-Clark refinement), where it gives the same arrays as the constructor.
        """
        self = cls.__new__(cls)
        self._set_faces(corners, offsets, n_vertices)
        self._set_edges(np.asarray(he_twin, dtype=np.int64))
        return self

    def _set_faces(self, corners: np.ndarray, offsets: np.ndarray, n_vertices: int) -> None:
        corners = np.asarray(corners, dtype=np.int64)
        offsets = np.asarray(offsets, dtype=np.int64)
        sizes = np.diff(offsets)
        self.n_vertices = int(n_vertices)
        self.n_faces = len(sizes)
        if corners.size == 4 * self.n_faces and np.all(sizes == 4):  # all quads (any refined mesh)
            h = np.arange(corners.size)
            self.he_face = h >> 2
            self.he_next = (h & -4) | ((h + 1) & 3)
            self.he_prev = (h & -4) | ((h + 3) & 3)
        else:
            self.he_face = np.repeat(np.arange(self.n_faces), sizes)
            start = offsets[:-1][self.he_face]
            size = sizes[self.he_face]
            local = np.arange(corners.size) - start
            self.he_next = start + (local + 1) % size
            self.he_prev = start + (local - 1) % size
        self.he_origin = corners
        self.he_dest = corners[self.he_next]

    def _set_edges(self, twin: np.ndarray) -> None:
        """Edges from twins, numbered by first half-edge: an edge starts at ``h`` unless ``twin(h) < h``."""
        self.he_twin = twin
        h = np.arange(len(twin))
        starts = (twin < 0) | (twin > h)
        self.edge_halfedge = np.flatnonzero(starts)
        self.n_edges = len(self.edge_halfedge)
        self.he_edge = (np.cumsum(starts) - 1)[np.where(starts, h, twin)]
        h0 = self.edge_halfedge
        self.edges = np.stack([self.he_origin[h0], self.he_dest[h0]], axis=1)
        t0 = twin[h0]
        self.edge_faces = np.stack([self.he_face[h0], np.where(t0 >= 0, self.he_face[t0], -1)], axis=1)
        for a in vars(self).values():
            if isinstance(a, np.ndarray):
                a.setflags(write=False)

    @functools.cached_property
    def edge_is_boundary(self) -> np.ndarray:
        return self.edge_faces[:, 1] < 0

    @functools.cached_property
    def vertex_valence(self) -> np.ndarray:
        """Number of edges at each vertex."""
        return np.bincount(self.edges.ravel(), minlength=self.n_vertices)

    @functools.cached_property
    def vertex_is_boundary(self) -> np.ndarray:
        out = np.zeros(self.n_vertices, dtype=bool)
        out[self.edges[self.edge_is_boundary].ravel()] = True
        return out

    @functools.cached_property
    def vertex_faces_csr(self) -> tuple[np.ndarray, np.ndarray]:
        """``(indptr, faces)``: the faces around each vertex (unordered), CSR layout."""
        order = np.argsort(self.he_origin, kind="stable")
        indptr = np.concatenate([[0], np.cumsum(np.bincount(self.he_origin, minlength=self.n_vertices))])
        return indptr, self.he_face[order]

    @property
    def is_closed(self) -> bool:
        return not bool(np.any(self.edge_is_boundary))

    @property
    def euler_characteristic(self) -> int:
        used = int(np.count_nonzero(self.vertex_valence))
        return used - self.n_edges + self.n_faces

    @functools.cached_property
    def vertex_fans(self) -> np.ndarray:
        """Number of separate fans of faces around each vertex (1 for a manifold vertex, 0 if unused), read-only.

        Corners ``h`` and ``twin(prev(h))`` at the same vertex touch. Pointer jumping along that map: once
        ``2**rounds`` exceeds every vertex's corner count, an open fan is represented by its last corner and
        a closed one by its lowest.
        """
        rot = self.he_twin[self.he_prev]
        h = np.arange(len(rot))
        last = rot < 0
        jump = np.where(last, h, rot)
        low = h
        for _ in range(int(np.bincount(self.he_origin).max(initial=0)).bit_length()):
            low = np.minimum(low, low[jump])
            jump = jump[jump]
        fan = np.where(last[jump], jump, low) == h
        fans = np.bincount(self.he_origin[fan], minlength=self.n_vertices)
        fans.setflags(write=False)
        return fans

    @functools.cached_property
    def is_manifold(self) -> bool:
        """Edge-manifold is guaranteed by construction; also require manifold vertices (one fan each)."""
        return not bool(np.any(self.vertex_fans > 1))
