"""Connectivity isomorphisms between closed polygon meshes (which vertex of one is which vertex of the other).

Two modelling histories can build the same control mesh with its vertices and faces numbered
differently (an inset then an extrude, or two edge loops, on a cube). On a connected oriented manifold
mesh an orientation-preserving isomorphism is fixed by where it sends one half-edge, so trying every
half-edge of the other mesh as the image of one fixed half-edge and following ``next`` and ``twin`` from it
finds them all in ``O(E^2)``. :func:`connectivity_hash` (Weisfeiler-Lehman refinement of the vertex-face
incidence) rules most pairs out first.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator

import numpy as np

from ..errors import TopologyError
from .polymesh import PolyMesh
from .topology import Topology

_BLOCK = 256
"""Candidate images of half-edge 0 followed at once (memory: ``E * _BLOCK`` indices)."""


def connectivity_hash(mesh: PolyMesh, rounds: int = 4) -> str:
    """A hash of the vertex-face incidence graph invariant under renumbering (equal for isomorphic meshes)."""
    faces = mesh.faces
    v_label = ["v"] * mesh.n_vertices
    f_label = [f"f{len(f)}" for f in faces]
    at_vertex: list[list[int]] = [[] for _ in range(mesh.n_vertices)]
    for fi, f in enumerate(faces):
        for v in f:
            at_vertex[v].append(fi)
    for _ in range(rounds):
        new_f = [f_label[fi] + "(" + ",".join(sorted(v_label[v] for v in f)) + ")" for fi, f in enumerate(faces)]
        new_v = [v_label[v] + "[" + ",".join(sorted(f_label[fi] for fi in at_vertex[v])) + "]"
                 for v in range(mesh.n_vertices)]
        f_label = [hashlib.sha1(x.encode()).hexdigest()[:12] for x in new_f]
        v_label = [hashlib.sha1(x.encode()).hexdigest()[:12] for x in new_v]
    return hashlib.sha1(",".join(sorted(v_label) + sorted(f_label)).encode()).hexdigest()


def _spanning_layers(topo: Topology) -> list[tuple[np.ndarray, ...]] | None:
    """Breadth-first layers from half-edge 0 along ``next`` and ``twin``: per layer, the half-edges first
    reached through ``next`` and their predecessors, then those first reached through ``twin`` and theirs
    (on a closed mesh both are permutations, so no half-edge is reached twice in one step). None when some
    half-edge is never reached (a mesh in several pieces)."""
    seen = np.zeros(len(topo.he_origin), dtype=bool)
    seen[0] = True
    frontier, layers = np.zeros(1, dtype=np.int64), []
    while frontier.size:
        layer = []
        for step in (topo.he_next, topo.he_twin):
            child = step[frontier]
            new = ~seen[child]
            seen[child[new]] = True
            layer += [child[new], frontier[new]]
        layers.append(tuple(layer))
        frontier = np.concatenate(layer[0::2])
    return layers if seen.all() else None


def isomorphisms(a: PolyMesh, b: PolyMesh, limit: int = 64) -> Iterator[np.ndarray]:
    """Orientation-preserving isomorphisms from ``a``'s connectivity to ``b``'s, as arrays ``phi`` with
    ``phi[vertex of a] = vertex of b`` (at most ``limit``; none unless both are connected closed
    manifolds with equal counts).

    Such a map is a bijection of half-edges commuting with ``next`` and ``twin``, fixed by the image of
    half-edge 0: every half-edge of ``b`` is tried as that image in turn.
    """
    if ((a.n_vertices, a.n_faces) != (b.n_vertices, b.n_faces) or a.n_faces == 0
            or not np.array_equal(np.sort(a.face_sizes), np.sort(b.face_sizes))):
        return
    try:
        ta, tb = a.topology, b.topology
    except TopologyError:
        return
    if not (ta.is_closed and tb.is_closed):
        return
    layers = _spanning_layers(ta)
    if layers is None:
        return
    n_he, found = len(ta.he_origin), 0
    for lo in range(0, n_he, _BLOCK):
        h = np.empty((n_he, min(n_he - lo, _BLOCK)), dtype=np.int64)  # column j: the images if 0 -> lo + j
        h[0] = np.arange(lo, lo + h.shape[1])
        for next_child, next_parent, twin_child, twin_parent in layers:
            h[next_child] = tb.he_next[h[next_parent]]
            h[twin_child] = tb.he_twin[h[twin_parent]]
        commutes = np.all(h[ta.he_next] == tb.he_next[h], axis=0) & np.all(h[ta.he_twin] == tb.he_twin[h], axis=0)
        for j in np.flatnonzero(commutes):
            phi = _vertex_map(ta, tb, h[:, j])
            if phi is not None:
                yield phi
                found += 1
                if found >= limit:
                    return


def _vertex_map(ta: Topology, tb: Topology, hmap: np.ndarray) -> np.ndarray | None:
    """The vertex map of a half-edge map commuting with ``next`` and ``twin`` when the map is a bijection that
    sends each vertex's corners to one vertex and no two vertices to one, else None."""
    if np.bincount(hmap, minlength=len(hmap)).max() > 1:
        return None
    phi = np.full(ta.n_vertices, -1, dtype=np.int64)
    phi[ta.he_origin] = tb.he_origin[hmap]
    if (not np.array_equal(phi[ta.he_origin], tb.he_origin[hmap]) or np.any(phi < 0)
            or np.bincount(phi, minlength=len(phi)).max() > 1):
        return None
    return phi


__all__ = ["connectivity_hash", "isomorphisms"]
