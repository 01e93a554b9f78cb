"""PolyMesh: an immutable polygon mesh (n-gons and boundaries allowed).

Vertices are a read-only ``(n, 3)`` float array; faces are a flat corner list ``corners`` with
``offsets`` (face ``f`` is ``corners[offsets[f]:offsets[f + 1]]``, counter-clockwise seen from outside).
Topology (half-edges, edges, adjacency) is derived once on first use and shared by every mesh that
only moved vertices (:meth:`PolyMesh.with_vertices`), so that caches keyed by :attr:`topology_key`
(subdivision matrices) survive vertex moves.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence

import numpy as np

from ..errors import TopologyError


class PolyMesh:
    """An immutable polygon mesh; build it with :meth:`from_faces` or the constructor."""

    __slots__ = ("vertices", "corners", "offsets", "_topology", "_key", "__dict__")

    def __init__(self, vertices: np.ndarray, corners: np.ndarray, offsets: np.ndarray, _topology=None):
        v = _frozen(vertices, np.float64).reshape(-1, 3)
        c = _frozen(corners, np.int64).ravel()
        o = _frozen(offsets, np.int64).ravel()
        if _topology is None:
            if o.size == 0 or o[0] != 0 or o[-1] != c.size or np.any(np.diff(o) < 3):
                raise TopologyError("faces need at least 3 corners each")
            if c.size and (c.min() < 0 or c.max() >= len(v)):
                raise TopologyError("a face refers to a vertex that does not exist")
        self.vertices, self.corners, self.offsets = v, c, o
        self._topology = _topology
        self._key = None

    @classmethod
    def from_faces(cls, vertices: np.ndarray | Sequence, faces: Iterable[Sequence[int]]) -> PolyMesh:
        """Build from a vertex array and a sequence of vertex-index cycles."""
        faces = [tuple(int(i) for i in f) for f in faces]
        sizes = np.array([len(f) for f in faces], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)]) if faces else np.zeros(1, np.int64)
        corners = np.fromiter((i for f in faces for i in f), dtype=np.int64, count=int(sizes.sum()))
        return cls(vertices, corners, offsets)

    @classmethod
    def _trusted(cls, vertices: np.ndarray, corners: np.ndarray, offsets: np.ndarray, topology=None,
                 key: tuple | None = None) -> PolyMesh:
        """A mesh on arrays already read-only, float64 ``(n, 3)`` / int64 and valid (the mesh ops' output,
        valid by construction): no checks, no copies. ``key``, when given, must be :attr:`topology_key`."""
        mesh = object.__new__(cls)
        mesh.vertices, mesh.corners, mesh.offsets = vertices, corners, offsets
        mesh._topology = topology
        mesh._key = key
        return mesh

    def with_vertices(self, vertices: np.ndarray) -> PolyMesh:
        """Same faces (valid already: not checked again), new positions; shares the topology (and its caches) if
        it was built."""
        v = _frozen(vertices, np.float64).reshape(-1, 3)
        if v.shape != self.vertices.shape:
            raise TopologyError("with_vertices needs as many vertices as the mesh has")
        return PolyMesh._trusted(v, self.corners, self.offsets, self._topology, self._key)

    # --- sizes and faces -------------------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.offsets) - 1

    @functools.cached_property
    def face_sizes(self) -> np.ndarray:
        return np.diff(self.offsets)

    @functools.cached_property
    def face_index(self) -> np.ndarray:
        """Face of each corner (length ``len(corners)``)."""
        return np.repeat(np.arange(self.n_faces), self.face_sizes)

    @property
    def faces(self) -> list[tuple[int, ...]]:
        """Faces as tuples of vertex indices."""
        c = self.corners.tolist()
        o = self.offsets.tolist()
        return [tuple(c[o[f]:o[f + 1]]) for f in range(self.n_faces)]

    def face(self, f: int) -> np.ndarray:
        """Vertex indices of face ``f``."""
        return self.corners[self.offsets[f]:self.offsets[f + 1]]

    # --- derived geometry ------------------------------------------------------------------------
    @functools.cached_property
    def bbox(self) -> np.ndarray:
        """``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        return float(np.linalg.norm(self.bbox[1] - self.bbox[0]))

    @functools.cached_property
    def face_newell(self) -> np.ndarray:
        """Newell area vectors (twice the vector area) of every face, ``(n_faces, 3)``."""
        p = self.vertices[self.corners]
        q = self.vertices[self.corners[self.topology.he_next]]
        cross = np.stack([
            (p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2]),
            (p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0]),
            (p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1]),
        ], axis=1)
        out = np.zeros((self.n_faces, 3))
        np.add.at(out, self.face_index, cross)
        return out

    @property
    def face_areas(self) -> np.ndarray:
        return 0.5 * np.linalg.norm(self.face_newell, axis=1)

    @property
    def face_normals(self) -> np.ndarray:
        """Unit Newell normals (zero rows for zero-area faces)."""
        n = self.face_newell
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    @functools.cached_property
    def face_centroids(self) -> np.ndarray:
        """Mean of each face's vertices (Blender's median centre)."""
        sums = np.zeros((self.n_faces, 3))
        np.add.at(sums, self.face_index, self.vertices[self.corners])
        return sums / self.face_sizes[:, None]

    # --- topology --------------------------------------------------------------------------------
    @property
    def topology(self):
        """Half-edge topology (:class:`~gsr_cad.geometry.topology.Topology`), built once."""
        if self._topology is None:
            from .topology import Topology

            self._topology = Topology(self.corners, self.offsets, self.n_vertices)
        return self._topology

    @property
    def topology_key(self) -> tuple:
        """Hashable key of the connectivity alone (for caches that survive vertex moves)."""
        if self._key is None:
            self._key = (self.n_vertices, self.offsets.tobytes(), self.corners.tobytes())
        return self._key

    def __repr__(self) -> str:
        return f"PolyMesh({self.n_vertices} vertices, {self.n_faces} faces)"


def _frozen(array, dtype) -> np.ndarray:
    """A read-only array of ``dtype``: arrays that already are read-only are shared, others copied."""
    if isinstance(array, np.ndarray) and array.dtype == dtype and not array.flags.writeable:
        return array
    out = np.array(array, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


def unit_cube(size: float = 1.0, center: Sequence[float] = (0.0, 0.0, 0.0)) -> PolyMesh:
    """The default template: an axis-aligned cube, outward-facing quads.

    Vertex ``i`` has coordinates ``(+-, +-, +-) * size / 2`` with bit 0 -> x, bit 1 -> y, bit 2 -> z;
    faces in order -x, +x, -y, +y, -z, +z.
    """
    bits = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], dtype=np.float64)
    verts = (bits - 0.5) * size + np.asarray(center, dtype=np.float64)
    faces = [
        (0, 4, 6, 2),  # -x
        (1, 3, 7, 5),  # +x
        (0, 1, 5, 4),  # -y
        (2, 6, 7, 3),  # +y
        (0, 2, 3, 1),  # -z
        (4, 5, 7, 6),  # +z
    ]
    return PolyMesh.from_faces(verts, faces)
