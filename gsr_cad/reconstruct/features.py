"""Sharp feature lines of a surface target, and the control edges a crease op (C) should try.

A mesh target's feature lines are its edges whose faces meet at a dihedral angle above ``angle_deg`` (and its
boundary edges); a cloud's are its points whose neighbourhood is far from planar (surface variation
``l0 / (l0 + l1 + l2)`` of the covariance eigenvalues of its ``k`` nearest neighbours above ``variation``).
Either way the result is a set of points on the feature lines, spaced about ``spacing`` of the diagonal
apart. A control edge is proposed when the limit points of both its ends and of its midpoint lie within
``radius`` of that set: then the limit curve of the edge runs along a feature line. A control face is
proposed for a rim crease (op R) when the farthest limit midpoint of its edges from the feature lines is
within ``FACE_SLACK`` times the best face's: the faces whose outlines follow the feature lines most closely
(a cylinder's caps, a nut's end rings), even while the smooth limit is still far from them; faces whose rim is
already infinitely sharp all round are left out.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import ConfigError
from ..geometry.polymesh import SHARPNESS_INFINITE, PolyMesh
from ..geometry.subdivision import get_catmull_clark

FEATURE_ANGLE_DEG = 30.0
"""Dihedral angle (degrees) above which a target mesh edge is a feature line."""
FACE_SLACK = 1.25
CLOUD_NEIGHBOURS = 16
CLOUD_VARIATION = 0.04
"""Surface variation above which a cloud point is on a feature line (0 on a plane, 1/3 at most)."""


def _triangle_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    n = np.cross(points[faces[:, 1]] - points[faces[:, 0]], points[faces[:, 2]] - points[faces[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def mesh_feature_edges(points: np.ndarray, faces: np.ndarray, angle_deg: float = FEATURE_ANGLE_DEG) -> np.ndarray:
    """``(k, 2)`` vertex pairs of the triangle mesh's feature edges: boundary edges, edges on more than two
    triangles, and edges whose two triangles' normals differ by more than ``angle_deg``."""
    if not 0.0 < angle_deg < 180.0:
        raise ConfigError(f"the feature angle must lie in (0, 180) degrees, got {angle_deg!r}")
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    pairs = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    tri = np.repeat(np.arange(len(faces)), 3)
    keys, inverse, counts = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    normals = _triangle_normals(np.asarray(points, dtype=np.float64), faces)
    two = counts == 2
    a, b = tri[order[start[two]]], tri[order[start[two] + 1]]
    cos = np.einsum("ij,ij->i", normals[a], normals[b])
    sharp = np.zeros(len(keys), dtype=bool)
    sharp[np.flatnonzero(two)[cos < np.cos(np.radians(angle_deg))]] = True
    sharp |= counts != 2
    return keys[sharp]


def _along(points: np.ndarray, edges: np.ndarray, step: float) -> np.ndarray:
    """Points along the segments ``edges`` at most ``step`` apart, ends included."""
    p, q = points[edges[:, 0]], points[edges[:, 1]]
    n = np.maximum(np.ceil(np.linalg.norm(q - p, axis=1) / step).astype(np.int64), 1)
    owner = np.repeat(np.arange(len(edges)), n + 1)
    t = (np.arange(owner.size) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)) / np.repeat(n, n + 1)
    return p[owner] + t[:, None] * (q - p)[owner]


def cloud_feature_points(points: np.ndarray, k: int = CLOUD_NEIGHBOURS, variation: float = CLOUD_VARIATION,
                         tree: cKDTree | None = None) -> np.ndarray:
    """The cloud points whose ``k`` nearest neighbours have surface variation above ``variation``."""
    points = np.asarray(points, dtype=np.float64)
    if len(points) <= k:
        return points[:0]
    _, idx = (tree or cKDTree(points)).query(points, k=k)
    nb = points[idx] - points[idx].mean(axis=1, keepdims=True)
    eig = np.linalg.eigvalsh(np.einsum("nki,nkj->nij", nb, nb))
    total = eig.sum(axis=1)
    score = np.divide(eig[:, 0], total, out=np.zeros(len(points)), where=total > 0)
    return points[score > variation]


def feature_points(points: np.ndarray, faces: np.ndarray | None, spacing: float = 0.01,
                   angle_deg: float = FEATURE_ANGLE_DEG) -> np.ndarray:
    """Points on the target's feature lines (mesh: sampled every ``spacing`` of the diagonal along the feature
    edges; cloud: the high-variation points)."""
    points = np.asarray(points, dtype=np.float64)
    if faces is None:
        return cloud_feature_points(points)
    edges = mesh_feature_edges(points, faces, angle_deg)
    diag = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))) if len(points) else 0.0
    if not len(edges) or diag == 0.0:
        return points[:0]
    return _along(points, edges, spacing * diag)


class CreaseProposals:
    """The feature points of one target and the control edges near them (see the module docstring)."""

    def __init__(self, points: np.ndarray, faces: np.ndarray | None, radius: float = 0.02,
                 boundary: str = "all"):
        self.features = feature_points(points, faces)
        diag = float(np.linalg.norm(np.ptp(np.asarray(points, dtype=np.float64), axis=0))) if len(points) else 0.0
        self.radius = radius * diag
        self.boundary = boundary
        self._tree = cKDTree(self.features) if len(self.features) else None

    def edges(self, control: PolyMesh) -> list[int]:
        """Interior edges of ``control`` whose ends' and midpoint's limit points lie within ``radius`` of a
        feature point, nearest first (empty when the target has no feature line)."""
        if self._tree is None:
            return []
        topo = control.topology
        limit = get_catmull_clark(control, 1, self.boundary).limit_matrix @ control.vertices
        d, _ = self._tree.query(limit[:topo.n_vertices + topo.n_edges])
        worst = np.maximum(np.maximum(d[topo.edges[:, 0]], d[topo.edges[:, 1]]), d[topo.n_vertices:])
        ok = np.flatnonzero((worst <= self.radius) & ~topo.edge_is_boundary)
        return ok[np.argsort(worst[ok], kind="stable")].tolist()

    def faces(self, control: PolyMesh) -> list[int]:
        """Faces of ``control`` whose edges' limit midpoints all lie within ``FACE_SLACK`` times the best face's
        distance of the feature lines, nearest first (empty when the target has no feature line)."""
        if self._tree is None:
            return []
        topo = control.topology
        limit = get_catmull_clark(control, 1, self.boundary).limit_matrix @ control.vertices
        d, _ = self._tree.query(limit[topo.n_vertices:topo.n_vertices + topo.n_edges])
        worst = np.maximum.reduceat(d[topo.he_edge], control.offsets[:-1])
        # a rim already creased all round (the sharp edges' limit lies on the feature line) is no proposal
        open_edge = (control.edge_sharpness < SHARPNESS_INFINITE) & ~topo.edge_is_boundary
        worst[~np.logical_or.reduceat(open_edge[topo.he_edge], control.offsets[:-1])] = np.inf
        if not np.isfinite(worst).any():
            return []
        ok = np.flatnonzero(worst <= FACE_SLACK * worst.min())
        return ok[np.argsort(worst[ok], kind="stable")].tolist()
