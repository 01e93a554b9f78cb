"""Mesh validation: one clear reason why a mesh cannot be used, and a summary of what it is.

:func:`validate_mesh` raises :class:`~gsr_cad.errors.TopologyError` with a one-line message for the
first problem found (checks run cheapest first); :func:`mesh_report` never raises and describes any
:class:`~gsr_cad.geometry.polymesh.PolyMesh` (counts, Euler characteristic, closed, manifold).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import TopologyError
from .polymesh import SHARPNESS_INFINITE, PolyMesh
from .topology import Topology

DEGENERATE_AREA = 1e-12
"""A face whose area is below this times the squared bounding-box diagonal counts as zero-area."""


def vertex_fans(topology: Topology) -> np.ndarray:
    """Number of separate fans of faces around each vertex (1 for a manifold vertex, 0 if unused):
    :attr:`Topology.vertex_fans`."""
    return topology.vertex_fans


def _edge_keys(mesh: PolyMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per half-edge: origin, destination, directed key, undirected key (no Topology needed)."""
    sizes = mesh.face_sizes
    local = np.arange(len(mesh.corners)) - np.repeat(mesh.offsets[:-1], sizes)
    nxt = np.repeat(mesh.offsets[:-1], sizes) + (local + 1) % np.repeat(sizes, sizes)
    a, b = mesh.corners, mesh.corners[nxt]
    n = np.int64(max(mesh.n_vertices, 1))
    return a, b, a * n + b, np.minimum(a, b) * n + np.maximum(a, b)


def _first_problem(mesh: PolyMesh) -> str | None:
    """The first reason ``mesh`` is unusable, or None."""
    if mesh.n_vertices == 0:
        return "mesh is empty (no vertices)"
    if mesh.n_faces == 0:
        return "mesh has no faces"
    bad = np.flatnonzero(~np.all(np.isfinite(mesh.vertices), axis=1))
    if bad.size:
        return f"vertex {bad[0]} has a NaN or infinite coordinate ({bad.size} such vertices in all)"

    face = mesh.face_index
    order = np.lexsort((mesh.corners, face))
    same = (face[order][1:] == face[order][:-1]) & (mesh.corners[order][1:] == mesh.corners[order][:-1])
    if np.any(same):
        i = order[np.flatnonzero(same)[0]]
        return f"face {face[i]} repeats vertex {mesh.corners[i]}"

    used = np.bincount(mesh.corners, minlength=mesh.n_vertices) > 0
    if not np.all(used):
        unused = np.flatnonzero(~used)
        return f"vertex {unused[0]} is not used by any face ({unused.size} unused vertices in all)"

    a, b, directed, undirected = _edge_keys(mesh)
    _, inverse, counts = np.unique(undirected, return_inverse=True, return_counts=True)
    if np.any(counts > 2):
        h = np.flatnonzero(counts[inverse] > 2)[0]
        return f"edge ({a[h]}, {b[h]}) is shared by {counts[inverse[h]]} faces (non-manifold edge)"
    _, d_inverse, d_counts = np.unique(directed, return_inverse=True, return_counts=True)
    if np.any(d_counts > 1):
        h = np.flatnonzero(d_counts[d_inverse] > 1)
        return (f"faces {face[h[0]]} and {face[h[1]]} run edge ({a[h[0]]}, {b[h[0]]}) the same way "
                "(inconsistent orientation)")

    fans = mesh.topology.vertex_fans
    if np.any(fans > 1):
        v = int(np.flatnonzero(fans > 1)[0])
        return f"vertex {v} is non-manifold ({fans[v]} separate fans of faces meet there)"

    tol = DEGENERATE_AREA * mesh.diagonal**2
    flat = np.flatnonzero(mesh.face_areas <= tol)
    if flat.size:
        return f"face {flat[0]} has zero area ({flat.size} degenerate faces in all)"
    return None


def validate_mesh(mesh: PolyMesh, require_closed: bool = False, require_quads: bool = False) -> PolyMesh:
    """Return ``mesh`` if it is a usable control mesh, else raise TopologyError with the reason.

    Checked: empty, NaN/Inf vertices, repeated vertices in a face, unreferenced vertices,
    non-manifold edges, inconsistent orientation, non-manifold vertices, zero-area faces; and on
    request no boundary edges (``require_closed``) and only quads (``require_quads``).
    """
    problem = _first_problem(mesh)
    if problem is not None:
        raise TopologyError(problem)
    topo = mesh.topology
    if require_closed and not topo.is_closed:
        e = int(np.flatnonzero(topo.edge_is_boundary)[0])
        n_open = int(topo.edge_is_boundary.sum())
        raise TopologyError(f"mesh is open: {n_open} boundary edges (first: {tuple(topo.edges[e].tolist())})")
    if require_quads and np.any(mesh.face_sizes != 4):
        f = int(np.flatnonzero(mesh.face_sizes != 4)[0])
        raise TopologyError(f"face {f} has {mesh.face_sizes[f]} corners; only quads are allowed here")
    return mesh


def mesh_report(mesh: PolyMesh) -> dict[str, Any]:
    """Counts and properties of any PolyMesh; never raises.

    Keys: vertices, faces, edges, boundary_edges, unreferenced_vertices, triangles, quads, ngons,
    components, euler_characteristic, closed, manifold, oriented, genus (closed, connected, valid
    meshes only, else None), creased_edges (edges with sharpness > 0), sharp_edges (infinitely sharp ones),
    valid, problem (validate_mesh's reason or None).
    """
    sizes = mesh.face_sizes
    used = np.bincount(mesh.corners, minlength=mesh.n_vertices) > 0
    out: dict[str, Any] = {
        "vertices": mesh.n_vertices,
        "faces": mesh.n_faces,
        "unreferenced_vertices": int(np.count_nonzero(~used)),
        "triangles": int(np.count_nonzero(sizes == 3)),
        "quads": int(np.count_nonzero(sizes == 4)),
        "ngons": int(np.count_nonzero(sizes > 4)),
    }
    a, b, directed, undirected = _edge_keys(mesh)
    keys, first, counts = np.unique(undirected, return_index=True, return_counts=True)
    edge_manifold = not np.any(counts > 2)
    oriented = edge_manifold and np.unique(directed).size == directed.size
    n_edges = int(keys.size)
    if mesh.n_vertices and n_edges:
        graph = sp.coo_matrix((np.ones(n_edges), (a[first], b[first])), shape=(mesh.n_vertices,) * 2)
        _, labels = connected_components(graph, directed=False)
        components = int(np.unique(labels[used]).size)
    else:
        components = 0
    manifold = edge_manifold
    if oriented and mesh.n_faces and not np.any(a == b):
        manifold = mesh.topology.is_manifold
    chi = int(np.count_nonzero(used)) - n_edges + mesh.n_faces
    closed = bool(n_edges) and not np.any(counts == 1)
    problem = _first_problem(mesh)
    out.update({
        "edges": n_edges,
        "boundary_edges": int(np.count_nonzero(counts == 1)),
        "components": components,
        "euler_characteristic": chi,
        "closed": bool(closed),
        "manifold": bool(manifold),
        "oriented": bool(oriented),
        "genus": (2 - chi) // 2 if (problem is None and closed and components == 1) else None,
        "creased_edges": int(mesh.crease_values.size),
        "sharp_edges": int(np.count_nonzero(mesh.crease_values >= SHARPNESS_INFINITE)),
        "valid": problem is None,
        "problem": problem,
    })
    return out
