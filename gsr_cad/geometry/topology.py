"""Half-edge topology derived from a flat corner list; built once per connectivity.

Half-edge ``h`` is corner ``h`` of the corner list: it runs from ``corners[h]`` to the next corner of
the same face. Edges are numbered in order of their first half-edge (so edge order is deterministic:
it follows face order, then corner order). ``-1`` marks "none" (boundary twin, boundary edge face).
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import TopologyError


class Topology:
    """Connectivity arrays of a polygon mesh (read-only after construction)."""

    def __init__(self, corners: np.ndarray, offsets: np.ndarray, n_vertices: int):
        corners = np.asarray(corners, dtype=np.int64)
        offsets = np.asarray(offsets, dtype=np.int64)
        n_he = corners.size
        sizes = np.diff(offsets)
        self.n_vertices = int(n_vertices)
        self.n_faces = len(sizes)
        self.he_face = np.repeat(np.arange(self.n_faces), sizes)
        local = np.arange(n_he) - offsets[self.he_face]
        self.he_next = offsets[self.he_face] + (local + 1) % sizes[self.he_face]
        self.he_prev = offsets[self.he_face] + (local - 1) % sizes[self.he_face]
        self.he_origin = corners
        self.he_dest = corners[self.he_next]
        if np.any(self.he_origin == self.he_dest):
            raise TopologyError("a face repeats a vertex on consecutive corners")

        n = np.int64(max(n_vertices, 1))
        directed = self.he_origin * n + self.he_dest
        order = np.argsort(directed, kind="stable")
        sorted_keys = directed[order]
        if np.any(sorted_keys[1:] == sorted_keys[:-1]):
            raise TopologyError(
                "an edge is used twice in the same direction (non-manifold or inconsistently oriented faces)")
        reverse = self.he_dest * n + self.he_origin
        pos = np.searchsorted(sorted_keys, reverse)
        pos_c = np.minimum(pos, n_he - 1)
        found = (pos < n_he) & (sorted_keys[pos_c] == reverse)
        self.he_twin = np.where(found, order[pos_c], -1)

        lo = np.minimum(self.he_origin, self.he_dest)
        hi = np.maximum(self.he_origin, self.he_dest)
        undirected = lo * n + hi
        _, first, inverse = np.unique(undirected, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        self.he_edge = rank[inverse.ravel()]
        self.n_edges = len(first)
        self.edge_halfedge = np.empty(self.n_edges, dtype=np.int64)
        self.edge_halfedge[self.he_edge[::-1]] = np.arange(n_he)[::-1]
        h0 = self.edge_halfedge
        self.edges = np.stack([self.he_origin[h0], self.he_dest[h0]], axis=1)
        t0 = self.he_twin[h0]
        self.edge_faces = np.stack([self.he_face[h0], np.where(t0 >= 0, self.he_face[np.maximum(t0, 0)], -1)], axis=1)
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
    def is_manifold(self) -> bool:
        """Edge-manifold is guaranteed by construction; also require manifold vertices (one fan each)."""
        # Walk the fan of outgoing half-edges around every vertex: h -> twin(prev(h)).
        n_he = len(self.he_origin)
        seen = np.zeros(n_he, dtype=bool)
        fans = np.zeros(self.n_vertices, dtype=np.int64)
        start_candidates = np.where(self.he_twin < 0)[0]  # boundary fans start at a boundary half-edge
        for starts in (start_candidates, np.arange(n_he)):
            for h in starts:
                if seen[h]:
                    continue
                fans[self.he_origin[h]] += 1
                cur = h
                while cur >= 0 and not seen[cur]:
                    seen[cur] = True
                    t = self.he_twin[self.he_prev[cur]]
                    cur = t
        return bool(np.all(fans[self.vertex_valence > 0] <= 1))
