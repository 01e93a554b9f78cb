"""Connectivity isomorphisms between closed polygon meshes (which vertex of one is which vertex of the other).

Two modelling histories can build the same control mesh with its vertices and faces numbered
differently (an inset then an extrude, or two edge loops, on a cube). On a connected oriented manifold
mesh an orientation-preserving isomorphism is fixed by where it sends one directed edge, so trying every
directed edge of the other mesh as the image of one fixed edge and walking faces and twins from it finds
them all in ``O(E^2)``. :func:`connectivity_hash` (Weisfeiler-Lehman refinement of the vertex-face
incidence) rules most pairs out first.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator

import numpy as np

from .polymesh import PolyMesh


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


def _directed_edges(faces: list[tuple[int, ...]]) -> dict[tuple[int, int], tuple[int, int]]:
    """``(u, v) -> (face, corner of u)`` for every directed edge of every face."""
    out = {}
    for fi, f in enumerate(faces):
        k = len(f)
        for c in range(k):
            out[(f[c], f[(c + 1) % k])] = (fi, c)
    return out


def isomorphisms(a: PolyMesh, b: PolyMesh, limit: int = 64) -> Iterator[np.ndarray]:
    """Orientation-preserving isomorphisms from ``a``'s connectivity to ``b``'s, as arrays ``phi`` with
    ``phi[vertex of a] = vertex of b`` (at most ``limit``; none unless both are connected closed
    manifolds with equal counts)."""
    if (a.n_vertices, a.n_faces) != (b.n_vertices, b.n_faces) or a.n_faces == 0:
        return
    fa, fb = a.faces, b.faces
    ea, eb = _directed_edges(fa), _directed_edges(fb)
    if len(ea) != len(eb) or sorted(map(len, fa)) != sorted(map(len, fb)):
        return
    start = next(iter(ea))
    found = 0
    for image in eb:
        phi = _extend(start, image, fa, fb, ea, eb, a.n_vertices)
        if phi is not None:
            yield phi
            found += 1
            if found >= limit:
                return


def _extend(start: tuple[int, int], image: tuple[int, int], fa, fb, ea, eb, n: int) -> np.ndarray | None:
    """The isomorphism sending directed edge ``start`` of ``a`` to ``image`` of ``b``, or None."""
    vmap = np.full(n, -1, dtype=np.int64)
    used = np.zeros(n, dtype=bool)
    fmap: dict[int, int] = {}
    taken: set[int] = set()
    stack = [(start, image)]
    while stack:
        (u, v), (x, y) = stack.pop()
        f, c = ea[(u, v)]
        if f in fmap:
            continue
        g_c = eb.get((x, y))
        if g_c is None:
            return None
        g, d = g_c
        if len(fa[f]) != len(fb[g]) or g in taken:
            return None
        fmap[f] = g
        taken.add(g)
        k = len(fa[f])
        for i in range(k):
            p, q = fa[f][(c + i) % k], fb[g][(d + i) % k]
            if vmap[p] == -1:
                if used[q]:
                    return None
                vmap[p], used[q] = q, True
            elif vmap[p] != q:
                return None
        for i in range(k):
            p0, p1 = fa[f][(c + i) % k], fa[f][(c + i + 1) % k]
            q0, q1 = fb[g][(d + i) % k], fb[g][(d + i + 1) % k]
            if (p1, p0) not in ea:
                return None  # an open edge: not a closed mesh
            stack.append(((p1, p0), (q1, q0)))
    if len(fmap) != len(fa) or np.any(vmap < 0):
        return None
    return vmap


__all__ = ["connectivity_hash", "isomorphisms"]
