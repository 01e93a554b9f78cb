"""The seven surface modelling ops of the paper (letters V E L B I F S) on a closed polygon mesh, the crease
ops C and R (edge sharpness), the hole op H and the region ops X and N (not in the paper).

Each op is a frozen dataclass registered by name around one pure function of
:mod:`gsr_cad.ops.mesh_kernel`, ``PolyMesh -> PolyMesh``; an op that cannot apply, or would leave a
degenerate, folded or flipped face, raises :class:`~gsr_cad.errors.OpError` (repair drops it). The
semantics are those of Blender's bmesh operators, so that the Blender replay
(:mod:`gsr_cad.exporters.blender`) rebuilds the same control mesh; normals are unit Newell normals.

Element references index the mesh as it stands when the op runs: vertices by vertex index, faces by face
index, edges by :class:`~gsr_cad.geometry.topology.Topology` edge index (first appearance walking the
faces' corners). Element order after each op, with ``n`` the old vertex count, ``m`` the old face count,
face ``f`` having corners ``c_0 .. c_{k-1}``:

* V ``translate_vertex(vertex, delta)``, F ``translate_face(face, distance)`` (along the face's normal),
  S ``scale(factor)`` (about the bounding-box centre): positions change, nothing is renumbered.
* E ``extrude(face, distance)``: new vertex ``n + i`` is ``c_i + distance * normal``; face ``f`` keeps
  its index on the new vertices ``(n, .., n + k - 1)``; side quad ``m + i`` is
  ``(c_i, c_{i+1}, n + i + 1, n + i)`` (Blender: ``extrude_face_region`` with ``use_keep_orig=False``).
* I ``inset(face, thickness)``: the same layout as E, with the new vertices inside the face where every
  inner edge lies ``thickness`` from its outer edge (``inset_individual``, even offset).
* L ``edge_loop(edge)``: the ring of opposite edges through quads (see :func:`~gsr_cad.ops.mesh_kernel.edge_ring`:
  ``edge``, then the edges met across its first face, then those met across its second face) is cut at
  the midpoints, new vertex ``n + j`` on ring edge ``j``. Each crossed quad keeps its index with the
  half that holds its first corner (still first); the other halves are appended in ring order. A
  non-quad face where an open ring ends gets the midpoint as an extra corner (a T-vertex)
  (``subdivide_edgering``, one cut).
* B ``bevel(edge, offset)`` on edge ``(a, b)`` whose first face ``f1`` runs ``a -> b``: each end of
  valence ``k`` is replaced by ``k - 1`` boundary vertices, one on each other edge at it: on the two
  edges next to the bevelled one at distance ``offset`` from its line (in the plane of the two edges),
  on any further edge ``offset`` along it. The boundary vertex on the ``f1`` side takes the end's index;
  the others are appended, end ``a`` first, each end in the order of its end polygon. Old faces keep
  their index with the end replaced by its boundary vertices; appended: the bevel quad, then for an end
  of valence >= 4 the polygon of its boundary vertices (end ``a`` first). An end of valence 3 adds the
  two boundary vertices to the third face instead (``bevel`` with ``offset_type='OFFSET'``,
  ``segments=1``, ``profile=0.5``). Corners between the edge and its neighbours must lie in
  ``[15, 165]`` degrees and be convex; otherwise Blender builds something else and the op is invalid.

* H ``hole(face_a, face_b)``: removes two facing faces with as many corners and bridges their rims with
  quads (a through-hole, genus + 1; see :func:`~gsr_cad.ops.mesh_kernel.hole` for the pairing and order).
* X ``extrude_region(faces, distance)``: a region (a set of faces joined by edges, not the whole surface, meeting
  each rim vertex in one fan; see :func:`~gsr_cad.ops.mesh_kernel.region_rim`) moves ``distance`` along the unit
  sum of its faces' Newell vectors. The rim is walked as the region's faces' half-edges whose other side is
  outside, faces in the order listed (ascending), corners in order; rim vertex ``j`` (first appearance in that
  walk) is copied to new vertex ``n + j``; inner vertices keep their indices and move; the region's faces keep
  their indices on the copies; one quad ``(u, v, v', u')`` per rim half-edge ``u -> v`` is appended in rim order
  (Blender: ``extrude_face_region`` of the faces, their edges and vertices, ``use_keep_orig=False``, then a
  translate). A region of one face is E.
* N ``inset_region(faces, thickness)``: the same layout, the inner vertices staying, each rim copy ``thickness``
  inside both rim edges at it (as I places a corner) in the plane of the unit sum of the Newell vectors of the
  region's faces at that vertex (Blender: ``inset_region``; its even offset places corners where the region
  bends by its own rule, so the script then moves them here). A region of one face is I.
* C ``crease(edge, sharpness)``: sets the OpenSubdiv sharpness of an interior edge (``0`` smooth, ``10``
  infinitely sharp; Blender's crease is ``sqrt(sharpness / 10)``); nothing moves or is renumbered.
  R ``crease_rim(face, sharpness)``: the same on every interior edge of a face's rim (one designer action
  for a sharp cap).

Creases are carried through the other ops (:attr:`PolyMesh.creases` by vertex pair): an edge whose two
vertices still share an edge keeps its sharpness (old vertices keep their indices). E: each cap edge also
takes the sharpness of the rim edge it was extruded from (Blender copies the edge); I: the inner edges are
smooth; X: like E, each copied edge keeps the sharpness of its original; N: like I; L: both halves of a cut edge
keep its sharpness (Blender's edge split copies it); B: the bevelled
edge's sharpness is dropped, the edges at its ends keep theirs on their shortened edge.

:func:`random_op` draws ops with parameters scaled by the target's bounding-box diagonal (see
:class:`OpRanges`) and :func:`perturb_op` nudges one (the surface GA's specific mutation).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from ..errors import ConfigError, InputError, OpError
from ..geometry.polymesh import SHARPNESS_INFINITE, PolyMesh
from . import mesh_kernel as K
from .base import Op, register
from .mesh_conn import mesh_view

__all__ = [
    "ALL_OPS_BY_LETTER", "Bevel", "Crease", "CreaseRim", "EdgeLoop", "Extrude", "ExtrudeRegion", "Hole", "Inset",
    "InsetRegion", "MeshOp", "OPS_BY_LETTER", "OpRanges", "PAPER_RANGES", "Scale", "TranslateFace", "TranslateVertex",
    "bevel", "crease", "crease_rim", "edge_loop", "extrude", "extrude_region", "hole", "inset", "inset_region",
    "moves_to", "perturb_op", "random_op", "scale", "translate_face", "translate_vertex",
]

translate_vertex = K.translate_vertex
extrude = K.extrude
edge_loop = K.edge_loop
bevel = K.bevel
inset = K.inset
translate_face = K.translate_face
scale = K.scale
crease = K.crease
crease_rim = K.crease_rim
hole = K.hole
extrude_region = K.extrude_region
inset_region = K.inset_region


def _element(value, what: str) -> int:
    """A non-negative integer index (an integral float from JSON is accepted)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InputError(f"{what} must be a non-negative integer, got {value!r}")
    return int(value)


def _number(value, what: str, positive: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or (positive and not x > 0.0):
        raise InputError(f"{what} must be a finite{' positive' if positive else ''} number, got {value!r}")
    return x + 0.0


def _vector(value, what: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be three numbers, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise InputError(f"{what} must be finite, got {value!r}")
    return (x + 0.0, y + 0.0, z + 0.0)


def _faces(value, what: str) -> tuple[int, ...]:
    """A region's faces: a non-empty list of distinct face indices, kept sorted (one op per region)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise InputError(f"{what} must be a list of face indices, got {value!r}")
    out = tuple(sorted(_element(v, what) for v in value))
    if not out or len(set(out)) != len(out):
        raise InputError(f"{what} must list at least one face, each once, got {value!r}")
    return out


def _positive(value, what: str) -> float:
    return _number(value, what, positive=True)


def _sharpness(value, what: str) -> float:
    x = _number(value, what)
    if not 0.0 <= x <= SHARPNESS_INFINITE:
        raise InputError(f"{what} must lie in [0, {SHARPNESS_INFINITE:g}], got {value!r}")
    return x


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _sharp_text(s: float) -> str:
    return "infinitely sharp" if s >= SHARPNESS_INFINITE else f"sharpness {_fmt(s)}"


_FIELD_CHECKS = {"vertex": _element, "face": _element, "edge": _element, "face_a": _element, "face_b": _element,
                 "faces": _faces, "delta": _vector, "distance": _number, "offset": _positive, "thickness": _positive,
                 "factor": _positive, "sharpness": _sharpness}
"""How :class:`MeshOp` normalises each op field, by field name (InputError on a malformed value)."""


@dataclasses.dataclass(frozen=True)
class MeshOp(Op):
    """Base of the surface ops: ``letter`` is the paper's one-letter code. Fields are checked and
    normalised on construction by name (:data:`_FIELD_CHECKS`): element indices to ``int``, amounts to
    finite ``float`` (offset, thickness and factor positive), deltas to three-float tuples."""

    letter: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for field in self.__match_args__:  # the dataclass fields, in order (cheaper than dataclasses.fields)
            object.__setattr__(self, field, _FIELD_CHECKS[field](getattr(self, field), f"{self.name} {field}"))

    def describe(self) -> str:  # pragma: no cover - every subclass overrides it
        raise NotImplementedError


@register
@dataclasses.dataclass(frozen=True)
class TranslateVertex(MeshOp):
    """V: move vertex ``vertex`` by ``delta``."""

    name: ClassVar[str] = "translate_vertex"
    letter: ClassVar[str] = "V"
    vertex: int
    delta: tuple[float, float, float]

    def apply(self, state: PolyMesh) -> PolyMesh:
        return translate_vertex(state, self.vertex, self.delta)

    def describe(self) -> str:
        return f"translate vertex {self.vertex} by ({', '.join(map(_fmt, self.delta))})"


@register
@dataclasses.dataclass(frozen=True)
class Extrude(MeshOp):
    """E: extrude face ``face`` by ``distance`` along its normal (negative: into the mesh)."""

    name: ClassVar[str] = "extrude"
    letter: ClassVar[str] = "E"
    face: int
    distance: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return extrude(state, self.face, self.distance)

    def describe(self) -> str:
        return f"extrude face {self.face} by {_fmt(self.distance)}"


@register
@dataclasses.dataclass(frozen=True)
class EdgeLoop(MeshOp):
    """L: insert an edge loop across the ring of quads through edge ``edge``."""

    name: ClassVar[str] = "edge_loop"
    letter: ClassVar[str] = "L"
    edge: int

    def apply(self, state: PolyMesh) -> PolyMesh:
        return edge_loop(state, self.edge)

    def describe(self) -> str:
        return f"edge loop through edge {self.edge}"


@register
@dataclasses.dataclass(frozen=True)
class Bevel(MeshOp):
    """B: bevel edge ``edge`` with offset ``offset > 0`` (one segment)."""

    name: ClassVar[str] = "bevel"
    letter: ClassVar[str] = "B"
    edge: int
    offset: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return bevel(state, self.edge, self.offset)

    def describe(self) -> str:
        return f"bevel edge {self.edge} by {_fmt(self.offset)}"


@register
@dataclasses.dataclass(frozen=True)
class Inset(MeshOp):
    """I: inset face ``face`` by ``thickness > 0``."""

    name: ClassVar[str] = "inset"
    letter: ClassVar[str] = "I"
    face: int
    thickness: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return inset(state, self.face, self.thickness)

    def describe(self) -> str:
        return f"inset face {self.face} by {_fmt(self.thickness)}"


@register
@dataclasses.dataclass(frozen=True)
class TranslateFace(MeshOp):
    """F: move face ``face`` by ``distance`` along its normal."""

    name: ClassVar[str] = "translate_face"
    letter: ClassVar[str] = "F"
    face: int
    distance: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return translate_face(state, self.face, self.distance)

    def describe(self) -> str:
        return f"translate face {self.face} by {_fmt(self.distance)}"


@register
@dataclasses.dataclass(frozen=True)
class Scale(MeshOp):
    """S: scale the whole mesh by ``factor > 0`` about its bounding-box centre."""

    name: ClassVar[str] = "scale"
    letter: ClassVar[str] = "S"
    factor: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return scale(state, self.factor)

    def describe(self) -> str:
        return f"scale by {_fmt(self.factor)}"


@register
@dataclasses.dataclass(frozen=True)
class Crease(MeshOp):
    """C: set the sharpness of interior edge ``edge`` (``0`` smooth .. ``10`` infinitely sharp)."""

    name: ClassVar[str] = "crease"
    letter: ClassVar[str] = "C"
    edge: int
    sharpness: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return crease(state, self.edge, self.sharpness)

    def describe(self) -> str:
        return f"crease edge {self.edge} ({_sharp_text(self.sharpness)})"


@register
@dataclasses.dataclass(frozen=True)
class CreaseRim(MeshOp):
    """R: set the sharpness of the interior edges around face ``face``."""

    name: ClassVar[str] = "crease_rim"
    letter: ClassVar[str] = "R"
    face: int
    sharpness: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return crease_rim(state, self.face, self.sharpness)

    def describe(self) -> str:
        return f"crease the rim of face {self.face} ({_sharp_text(self.sharpness)})"


@register
@dataclasses.dataclass(frozen=True)
class Hole(MeshOp):
    """H: open a through-hole between facing faces ``face_a`` and ``face_b``."""

    name: ClassVar[str] = "hole"
    letter: ClassVar[str] = "H"
    face_a: int
    face_b: int

    def apply(self, state: PolyMesh) -> PolyMesh:
        return hole(state, self.face_a, self.face_b)

    def describe(self) -> str:
        return f"hole through faces {self.face_a} and {self.face_b}"


@register
@dataclasses.dataclass(frozen=True)
class ExtrudeRegion(MeshOp):
    """X: extrude a region of faces together (its inner vertices move, its rim is copied) along its mean normal."""

    name: ClassVar[str] = "extrude_region"
    letter: ClassVar[str] = "X"
    faces: tuple[int, ...]
    distance: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return extrude_region(state, self.faces, self.distance)

    def describe(self) -> str:
        return f"extrude faces {list(self.faces)} by {_fmt(self.distance)} along their mean normal"


@register
@dataclasses.dataclass(frozen=True)
class InsetRegion(MeshOp):
    """N: inset a region of faces together (new rim vertices ``thickness`` inside the old rim)."""

    name: ClassVar[str] = "inset_region"
    letter: ClassVar[str] = "N"
    faces: tuple[int, ...]
    thickness: float

    def apply(self, state: PolyMesh) -> PolyMesh:
        return inset_region(state, self.faces, self.thickness)

    def describe(self) -> str:
        return f"inset faces {list(self.faces)} together by {_fmt(self.thickness)}"


OPS_BY_LETTER: dict[str, type[MeshOp]] = {
    cls.letter: cls for cls in (TranslateVertex, Extrude, EdgeLoop, Bevel, Inset, TranslateFace, Scale)
}
"""The paper's seven ops."""
ALL_OPS_BY_LETTER: dict[str, type[MeshOp]] = {**OPS_BY_LETTER, "C": Crease, "R": CreaseRim, "H": Hole,
                                               "X": ExtrudeRegion, "N": InsetRegion}
"""Every surface op :func:`random_op` can draw: the paper's, C, R, H, X and N."""


@dataclasses.dataclass(frozen=True)
class OpRanges:
    """Ranges of :func:`random_op`; ``d`` is the ``scale`` argument (the target's bounding-box diagonal).

    * V: ``delta`` uniform in ``[-move * d, move * d]^3`` (the paper: ``move = 1``);
    * E: ``|distance|`` uniform in ``[0.05, 1] * extrude * d``, negative (a pocket) with probability
      ``inward`` (the paper: up to ``d``, outwards);
    * F: ``distance`` uniform in ``[-face_move * d, face_move * d]``;
    * S: ``factor`` log-uniform in ``[1 / max_factor, max_factor]``;
    * B: ``offset`` uniform in ``offset`` times the shortest other edge at the edge's ends (an offset
      slides along those edges, so a longer one is always invalid);
    * I: ``thickness`` uniform in ``thickness`` times the face's smallest centroid-to-edge distance;
    * C, R: infinitely sharp with probability ``infinite``, else ``sharpness`` uniform in ``sharpness``;
    * H: the first face uniform, the second the nearest one facing it (:func:`_hole_faces`);
    * X, N: a region of up to ``region_faces`` faces grown from a uniform face (:func:`_random_region`), the
      distance or thickness as for E or I (the thickness on the region's smallest face).
    """

    move: float = 0.1
    extrude: float = 0.5
    inward: float = 0.2
    face_move: float = 0.1
    max_factor: float = 1.25
    offset: tuple[float, float] = (0.05, 0.6)
    thickness: tuple[float, float] = (0.05, 0.6)
    sharpness: tuple[float, float] = (0.5, 3.0)
    infinite: float = 0.5
    region_faces: int = 4

    def __post_init__(self) -> None:
        for name in ("move", "extrude", "face_move"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ConfigError(f"op range {name} must be a finite number >= 0, got {getattr(self, name)!r}")
        for name in ("inward", "infinite"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"op range {name} must lie in [0, 1], got {getattr(self, name)!r}")
        lo, hi = self.sharpness
        if not 0.0 < lo <= hi <= SHARPNESS_INFINITE:
            raise ConfigError(f"op range sharpness must satisfy 0 < low <= high <= 10, got {(lo, hi)!r}")
        if not (math.isfinite(self.max_factor) and self.max_factor >= 1.0):
            raise ConfigError(f"op range max_factor must be a finite number >= 1, got {self.max_factor!r}")
        if isinstance(self.region_faces, bool) or not isinstance(self.region_faces, int) or self.region_faces < 1:
            raise ConfigError(f"op range region_faces must be an integer >= 1, got {self.region_faces!r}")
        for name in ("offset", "thickness"):
            lo, hi = getattr(self, name)
            if not 0.0 < lo <= hi:
                raise ConfigError(f"op range {name} must satisfy 0 < low <= high, got {(lo, hi)!r}")


PAPER_RANGES = OpRanges(move=1.0, extrude=1.0, inward=0.0)
"""The paper's ranges: vertex moves anywhere in ``[-d, d]^3``, extrusions outwards up to ``d``."""


def _local_edge_size(P: list[list[float]], conn, edge: int) -> float:
    """Shortest other edge at the two ends of ``edge``."""
    a, b = conn.edges[edge]
    best = math.inf
    for v in (a, b):
        for f in conn.vertex_faces(v):
            cyc = conn.faces[f]
            i = cyc.index(v)
            for x in (cyc[i - 1], cyc[(i + 1) % len(cyc)]):
                if x != a and x != b:
                    best = min(best, math.dist(P[v], P[x]))
    return best if math.isfinite(best) else math.dist(P[a], P[b])


def _face_inradius(P: list[list[float]], cyc: tuple[int, ...]) -> float:
    """Smallest distance from the face's centroid to the lines of its edges."""
    k = len(cyc)
    c = [sum(P[i][j] for i in cyc) / k for j in range(3)]
    best = math.inf
    for u, v in zip(cyc, cyc[1:] + cyc[:1]):
        e = K._sub(P[v], P[u])
        length = K._norm(e)
        if length > 0.0:
            best = min(best, K._norm(K._cross(e, K._sub(c, P[u]))) / length)
    return best if math.isfinite(best) else 0.0


def _hole_faces(view, face: int) -> tuple[int, int]:
    """``face`` and its partner for a hole: the nearest face (by centroid) with as many corners, no shared
    vertex and no edge to ``face``'s vertices that faces it across the solid (``face`` twice, an invalid op,
    when none does)."""
    conn = view.conn
    cyc = conn.faces[face]
    corners = set(cyc)
    mine = corners | {v for u, v in conn.half if u in corners}
    P = view.P
    c = [sum(P[i][j] for i in cyc) / len(cyc) for j in range(3)]
    best, partner = math.inf, face
    for g, other in enumerate(conn.faces):
        if len(other) != len(cyc) or mine.intersection(other) or not K.facing(view, face, g):
            continue
        d = math.dist(c, [sum(P[i][j] for i in other) / len(other) for j in range(3)])
        if d < best:
            best, partner = d, g
    return face, partner


def _random_region(rng: np.random.Generator, conn, size: int) -> tuple[int, ...]:
    """Up to ``size`` faces (the count uniform in ``1..size``): a uniform face, then uniform picks among the faces
    sharing an edge with those taken (the region op checks the rest)."""
    want = int(rng.integers(1, size + 1))
    region = [int(rng.integers(conn.n_faces))]
    while len(region) < want:
        taken = set(region)
        rims = sorted({g for f in region for u, v in zip(conn.faces[f], conn.faces[f][1:] + conn.faces[f][:1])
                       if (g := conn.half.get((v, u), -1)) >= 0 and g not in taken})
        if not rims:
            break
        region.append(rims[int(rng.integers(len(rims)))])
    return tuple(region)


def random_ops(rng: np.random.Generator, mesh: PolyMesh, n: int, kinds: str = "VELBIFS",
               scale: float | None = None, tries: int | None = None) -> tuple[tuple[MeshOp, ...], PolyMesh]:
    """``n`` random ops (:func:`random_op`, ``scale`` the diagonal, else the current mesh's) that apply in turn
    to ``mesh``, invalid draws skipped, and the mesh they build; OpError after ``tries`` draws (default
    ``1000 * n``) without ``n`` valid ones."""
    ops: list[MeshOp] = []
    limit = 1000 * n if tries is None else tries
    for _ in range(limit):
        if len(ops) == n:
            break
        op = random_op(rng, mesh, mesh.diagonal if scale is None else scale, kinds)
        try:
            mesh = op.apply(mesh)
        except OpError:
            continue
        ops.append(op)
    if len(ops) < n:
        raise OpError(f"only {len(ops)} of {n} random ops applied in {limit} draws")
    return tuple(ops), mesh


def random_op(rng: np.random.Generator, mesh: PolyMesh, scale: float, kinds: str = "VELBIFS",
              ranges: OpRanges = OpRanges(),
              crease_edges: Sequence[int] | Callable[[PolyMesh], Sequence[int]] | None = None,
              crease_faces: Sequence[int] | Callable[[PolyMesh], Sequence[int]] | None = None) -> MeshOp:
    """A random op for ``mesh``: kind uniform over the letters in ``kinds``, element uniform, parameters
    drawn from ``ranges`` (see :class:`OpRanges`) with ``scale`` the target's bounding-box diagonal.
    A C op picks its edge from ``crease_edges`` (edges of ``mesh`` proposed along the target's feature
    lines, :mod:`gsr_cad.reconstruct.features`, or a function of ``mesh`` giving them, called only for a C
    op) when some are given; an R op picks its face from ``crease_faces`` (the same kinds of proposals) with
    probability 3/4 when some are given. The op may still be invalid for ``mesh`` (repair drops it)."""
    letters = [k for k in kinds if k in ALL_OPS_BY_LETTER]
    if not letters or len(letters) != len(kinds):
        raise ConfigError(f"op kinds must be letters from {''.join(ALL_OPS_BY_LETTER)}, got {kinds!r}")
    if not (math.isfinite(scale) and scale > 0.0):
        raise ConfigError(f"op scale must be a finite positive number, got {scale!r}")
    kind = letters[int(rng.integers(len(letters)))]
    if kind == "S":
        return Scale(float(math.exp(rng.uniform(-1.0, 1.0) * math.log(ranges.max_factor))))
    if kind == "V":
        vertex = int(rng.integers(mesh.n_vertices))
        return TranslateVertex(vertex, tuple((rng.uniform(-1.0, 1.0, 3) * ranges.move * scale).tolist()))
    view = mesh_view(mesh)  # the apply that follows reuses it
    conn = view.conn
    if kind == "H":
        return Hole(*_hole_faces(view, int(rng.integers(conn.n_faces))))
    if kind in "XN":
        region = _random_region(rng, conn, ranges.region_faces)
        if kind == "X":
            distance = rng.uniform(0.05, 1.0) * ranges.extrude * scale
            return ExtrudeRegion(region, float(-distance if rng.random() < ranges.inward else distance))
        size = min(_face_inradius(view.P, conn.faces[f]) for f in region) or scale
        return InsetRegion(region, float(rng.uniform(*ranges.thickness) * size))
    if kind in "EIF":
        face = int(rng.integers(conn.n_faces))
        if kind == "E":
            distance = rng.uniform(0.05, 1.0) * ranges.extrude * scale
            return Extrude(face, float(-distance if rng.random() < ranges.inward else distance))
        if kind == "F":
            return TranslateFace(face, float(rng.uniform(-1.0, 1.0) * ranges.face_move * scale))
        size = _face_inradius(view.P, conn.faces[face]) or scale  # a zero-area face: any size
        return Inset(face, float(rng.uniform(*ranges.thickness) * size))
    if kind in "CR":
        sharpness = (SHARPNESS_INFINITE if rng.random() < ranges.infinite else float(rng.uniform(*ranges.sharpness)))
        if kind == "R":
            proposed = crease_faces(mesh) if callable(crease_faces) else crease_faces
            faces = [f for f in (proposed or ()) if 0 <= f < conn.n_faces]
            if faces and rng.random() < 0.75:
                return CreaseRim(int(faces[int(rng.integers(len(faces)))]), sharpness)
            return CreaseRim(int(rng.integers(conn.n_faces)), sharpness)
        proposed = crease_edges(mesh) if callable(crease_edges) else crease_edges
        edges = [e for e in (proposed or ()) if 0 <= e < len(conn.edges)]
        edge = int(edges[int(rng.integers(len(edges)))]) if edges else int(rng.integers(len(conn.edges)))
        return Crease(edge, sharpness)
    edge = int(rng.integers(len(conn.edges)))
    if kind == "L":
        return EdgeLoop(edge)
    size = _local_edge_size(view.P, conn, edge) or scale
    return Bevel(edge, float(rng.uniform(*ranges.offset) * size))


def perturb_op(op: Op, rng: np.random.Generator, scale: float, rel: float = 0.02, log_sigma: float = 0.1) -> MeshOp:
    """The same kind of op on the same element with its parameters nudged (the surface GA's specific mutation).

    Lengths (V delta per axis, E, X and F distances) move by ``N(0, (rel * scale)^2)``; positive amounts
    (B offset, I and N thickness, a semi-sharp C sharpness, at most 10) are multiplied by ``exp(N(0, log_sigma^2))``
    and the S factor by ``exp(N(0, rel^2))``, so they stay positive. L, H and an infinitely sharp C come back
    unchanged.
    """
    if not (math.isfinite(scale) and scale > 0.0):
        raise ConfigError(f"perturbation scale must be a finite positive number, got {scale!r}")
    if not (math.isfinite(rel) and rel >= 0.0 and math.isfinite(log_sigma) and log_sigma >= 0.0):
        raise ConfigError(f"perturbation sizes must be finite numbers >= 0, got rel={rel!r}, log_sigma={log_sigma!r}")
    sigma = rel * scale
    if isinstance(op, TranslateVertex):
        return TranslateVertex(op.vertex, tuple((np.asarray(op.delta) + rng.normal(0.0, sigma, 3)).tolist()))
    if isinstance(op, Extrude):
        return Extrude(op.face, op.distance + float(rng.normal(0.0, sigma)))
    if isinstance(op, TranslateFace):
        return TranslateFace(op.face, op.distance + float(rng.normal(0.0, sigma)))
    if isinstance(op, Bevel):
        return Bevel(op.edge, op.offset * float(np.exp(rng.normal(0.0, log_sigma))))
    if isinstance(op, Inset):
        return Inset(op.face, op.thickness * float(np.exp(rng.normal(0.0, log_sigma))))
    if isinstance(op, ExtrudeRegion):
        return ExtrudeRegion(op.faces, op.distance + float(rng.normal(0.0, sigma)))
    if isinstance(op, InsetRegion):
        return InsetRegion(op.faces, op.thickness * float(np.exp(rng.normal(0.0, log_sigma))))
    if isinstance(op, Scale):
        return Scale(op.factor * float(np.exp(rng.normal(0.0, rel))))
    if isinstance(op, (EdgeLoop, Hole)):
        return op
    if isinstance(op, (Crease, CreaseRim)):
        if op.sharpness >= SHARPNESS_INFINITE:
            return op
        return dataclasses.replace(op, sharpness=min(op.sharpness * float(np.exp(rng.normal(0.0, log_sigma))),
                                                     SHARPNESS_INFINITE))
    raise InputError(f"perturb_op knows only surface ops, got {type(op).__name__}")


def moves_to(state: PolyMesh, goal_vertices: np.ndarray, tol: float, order: np.ndarray | None = None
             ) -> tuple[tuple[TranslateVertex, ...], PolyMesh, int]:
    """``translate_vertex`` ops taking the vertices of ``state`` that are further than ``tol`` from
    ``goal_vertices`` there, one op each, in passes while the ops accept some (a move that would fold a
    face now may not after its neighbours moved), in index order or, given, that of ``order`` (a
    permutation of the vertices): ``(ops, resulting mesh, how many were refused)``."""
    goal_vertices = np.asarray(goal_vertices, dtype=np.float64)
    far = np.linalg.norm(goal_vertices - state.vertices, axis=1) > tol
    pending = [int(i) for i in (np.flatnonzero(far) if order is None else np.asarray(order)[far[order]])]
    moves: list[TranslateVertex] = []
    while pending:
        left = []
        for i in pending:
            op = TranslateVertex(i, tuple(float(x) for x in goal_vertices[i] - state.vertices[i]))
            try:
                state = op.apply(state)
            except OpError:
                left.append(i)
                continue
            moves.append(op)
        if len(left) == len(pending):
            return tuple(moves), state, len(left)
        pending = left
    return tuple(moves), state, 0
