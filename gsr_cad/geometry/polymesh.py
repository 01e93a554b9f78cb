"""PolyMesh: an immutable polygon mesh (n-gons and boundaries allowed).

Vertices are a read-only ``(n, 3)`` float array; faces are a flat corner list ``corners`` with
``offsets`` (face ``f`` is ``corners[offsets[f]:offsets[f + 1]]``, counter-clockwise seen from outside).
Topology (half-edges, edges, adjacency) is derived once on first use and shared by every mesh that
only moved vertices (:meth:`PolyMesh.with_vertices`), so that caches keyed by :attr:`topology_key`
(subdivision matrices) survive vertex moves.

Edge sharpness (creases, as OpenSubdiv defines them: ``0`` smooth, ``> 0`` semi-sharp, ``>= 10``
infinitely sharp) is optional topology-like data: a mapping of sorted vertex pairs ``(a, b)``, ``a < b``,
to positive sharpness, stored as two read-only arrays (:attr:`PolyMesh.crease_pairs`, lexicographic
order, and :attr:`PolyMesh.crease_values`, clipped to ``10``). :attr:`PolyMesh.topology_key` includes
it (a creased mesh subdivides differently); :attr:`PolyMesh.connectivity_key` is the faces alone.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from ..errors import InputError, TopologyError

SHARPNESS_INFINITE = 10.0
"""OpenSubdiv's infinitely sharp edge: sharpness at or above it never decays."""
Creases = tuple[np.ndarray, np.ndarray]


class PolyMesh:
    """An immutable polygon mesh; build it with :meth:`from_faces` or the constructor."""

    __slots__ = ("vertices", "corners", "offsets", "_topology", "_key", "_creases", "__dict__")

    def __init__(self, vertices: np.ndarray, corners: np.ndarray, offsets: np.ndarray, _topology=None,
                 creases: Mapping[tuple[int, int], float] | None = None):
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
        self._creases = None if not creases else _normalised_creases(self, creases)

    @classmethod
    def from_faces(cls, vertices: np.ndarray | Sequence, faces: Iterable[Sequence[int]],
                   creases: Mapping[tuple[int, int], float] | None = None) -> PolyMesh:
        """Build from a vertex array, a sequence of vertex-index cycles and optional edge sharpness."""
        faces = [tuple(int(i) for i in f) for f in faces]
        sizes = np.array([len(f) for f in faces], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)]) if faces else np.zeros(1, np.int64)
        corners = np.fromiter((i for f in faces for i in f), dtype=np.int64, count=int(sizes.sum()))
        return cls(vertices, corners, offsets, creases=creases)

    @classmethod
    def _trusted(cls, vertices: np.ndarray, corners: np.ndarray, offsets: np.ndarray, topology=None,
                 key: tuple | None = None, creases: Creases | None = None) -> PolyMesh:
        """A mesh on arrays already read-only, float64 ``(n, 3)`` / int64 and valid (the mesh ops' output,
        valid by construction): no checks, no copies. ``key``, when given, must be :attr:`connectivity_key`;
        ``creases``, when given, normalised ``(pairs, values)`` on edges of the faces."""
        mesh = object.__new__(cls)
        mesh.vertices, mesh.corners, mesh.offsets = vertices, corners, offsets
        mesh._topology = topology
        mesh._key = key
        mesh._creases = creases
        return mesh

    def with_vertices(self, vertices: np.ndarray) -> PolyMesh:
        """Same faces (valid already: not checked again) and creases, new positions; shares the topology (and its
        caches) if it was built."""
        v = _frozen(vertices, np.float64).reshape(-1, 3)
        if v.shape != self.vertices.shape:
            raise TopologyError("with_vertices needs as many vertices as the mesh has")
        return PolyMesh._trusted(v, self.corners, self.offsets, self._topology, self._key, self._creases)

    def with_creases(self, creases: Mapping[tuple[int, int], float] | None) -> PolyMesh:
        """Same vertices and faces, edge sharpness ``creases`` (``{(a, b): sharpness}``, either vertex order;
        zero entries are dropped; TopologyError when a pair is not an edge)."""
        return PolyMesh._trusted(self.vertices, self.corners, self.offsets, self._topology, self._key,
                                 _normalised_creases(self, creases) if creases else None)

    # --- creases ---------------------------------------------------------------------------------
    @property
    def crease_pairs(self) -> np.ndarray:
        """``(k, 2)`` sorted vertex pairs of the creased edges, lexicographic order (read-only)."""
        return self._creases[0] if self._creases is not None else _NO_PAIRS

    @property
    def crease_values(self) -> np.ndarray:
        """``(k,)`` sharpness of :attr:`crease_pairs`, in ``(0, 10]`` (read-only)."""
        return self._creases[1] if self._creases is not None else _NO_VALUES

    @property
    def creases(self) -> dict[tuple[int, int], float]:
        """Edge sharpness as ``{(a, b): sharpness}`` with ``a < b`` (empty when nothing is creased)."""
        return {(int(a), int(b)): float(s) for (a, b), s in zip(self.crease_pairs, self.crease_values)}

    @functools.cached_property
    def edge_sharpness(self) -> np.ndarray:
        """Sharpness of every :attr:`topology` edge (``0`` where smooth), read-only."""
        out = np.zeros(self.topology.n_edges)
        if self._creases is not None:
            out[_edge_index(self.topology, self.crease_pairs)] = self.crease_values
        out.setflags(write=False)
        return out

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
    def connectivity_key(self) -> tuple:
        """Hashable key of the faces alone (for caches that survive vertex moves and crease changes)."""
        if self._key is None:
            self._key = (self.n_vertices, self.offsets.tobytes(), self.corners.tobytes())
        return self._key

    @property
    def topology_key(self) -> tuple:
        """Hashable key of the connectivity and the creases (for caches that survive vertex moves); equal to
        :attr:`connectivity_key` when nothing is creased."""
        if self._creases is None:
            return self.connectivity_key
        return (*self.connectivity_key, self._creases[0].tobytes(), self._creases[1].tobytes())

    def __repr__(self) -> str:
        return f"PolyMesh({self.n_vertices} vertices, {self.n_faces} faces)"


_NO_PAIRS = np.zeros((0, 2), dtype=np.int64)
_NO_PAIRS.setflags(write=False)
_NO_VALUES = np.zeros(0)
_NO_VALUES.setflags(write=False)


def _edge_index(topo, pairs: np.ndarray) -> np.ndarray:
    """Topology edge index of each sorted vertex pair; TopologyError for a pair that is no edge."""
    n = np.int64(max(topo.n_vertices, 1))
    keys = np.sort(topo.edges, axis=1) @ np.array([n, 1])
    order = np.argsort(keys)
    want = pairs @ np.array([n, 1])
    at = np.minimum(np.searchsorted(keys, want, sorter=order), len(keys) - 1)
    found = order[at] if len(keys) else at
    if len(want) and (not len(keys) or np.any(keys[found] != want)):
        bad = pairs[keys[found] != want][0] if len(keys) else pairs[0]
        raise TopologyError(f"a crease names vertices {int(bad[0])}-{int(bad[1])}, which share no edge")
    return found


def sorted_creases(pairs: np.ndarray, values: np.ndarray) -> Creases | None:
    """Normalised crease arrays (read-only, sorted pairs in lexicographic order, zero sharpness dropped,
    values clipped to :data:`SHARPNESS_INFINITE`; the last of repeated pairs wins), None when empty."""
    pairs = np.sort(np.asarray(pairs, dtype=np.int64).reshape(-1, 2), axis=1)
    values = np.minimum(np.asarray(values, dtype=np.float64).ravel(), SHARPNESS_INFINITE)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))[::-1]
    pairs, values = pairs[order], values[order]
    _, first = np.unique(pairs, axis=0, return_index=True)  # the last given, after the reversal
    keep = first[values[first] > 0.0]
    if not keep.size:
        return None
    pairs, values = np.ascontiguousarray(pairs[keep]), np.ascontiguousarray(values[keep])
    pairs.setflags(write=False)
    values.setflags(write=False)
    return pairs, values


def _normalised_creases(mesh: PolyMesh, creases: Mapping[tuple[int, int], float]) -> Creases | None:
    """Checked and normalised crease arrays of ``mesh`` (InputError on a malformed entry)."""
    if not isinstance(creases, Mapping):
        raise InputError(f"creases must be a mapping of vertex pairs to sharpness, got {type(creases).__name__}")
    pairs, values = [], []
    for pair, s in creases.items():
        try:
            a, b = (int(i) for i in pair)
            s = float(s)
        except (TypeError, ValueError):
            raise InputError(f"a crease must map two vertex indices to a number, got {pair!r}: {s!r}") from None
        if not (np.isfinite(s) and s >= 0.0):
            raise InputError(f"crease sharpness must be a finite number >= 0, got {s!r}")
        pairs.append((a, b))
        values.append(s)
    out = sorted_creases(np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(values))
    if out is not None:
        _edge_index(mesh.topology, out[0])
    return out


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
