"""Sharp edges: a fitted cage's control edges that run along the target's sharp feature lines
(:class:`~gsr_cad.reconstruct.features.CreaseProposals`), creased infinitely sharp (op C, a designer's "mark
sharp"), kept where the creased cage, fitted again, is closer (``config.sharp_edges``).

A smooth Catmull-Clark limit rounds every edge of a box-like part, and no least-squares fit takes that rounding
out: an E core's body with its three prongs (144 control vertices) fits 2.2e-3 of the diagonal both ways smooth and
1.0e-3 with the 88 edges along its part edges creased. Creasing pays only where the cage's edges run along the
part's: a designer's start (module :mod:`.starts`: its loops are slid onto the blocks' sides) and the simple cages
of the front. A converged cage grown by loops and splits has edges beside the part's edges, not on them
(LetterBlock's 594 control vertices: 4.2e-3 smooth, 4.35e-3 creased), and the edge loops of the refinement keep
the sharpness of the edges they cut, so the start's creases carry through its path. The placed cube tries its
sharp edges all creased and, per direction, all but that direction's (:func:`crease_sets`).
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import GsrError
from ..geometry.polymesh import SHARPNESS_INFINITE, PolyMesh
from ..ops.mesh import Crease
from .features import CreaseProposals
from .refine import apply_ops

MIN_GAIN = 0.9
"""The creased cage is kept when its fitted distance is at most this share of the smooth cage's."""
CAGE_ANGLE = 60.0
"""A coarse cage's edge whose faces meet at more than this many degrees is creased when no limit curve runs along
a feature line yet: the smooth limit of a fitted cube lies 8 % of the diagonal inside a box's corners, far from its
edges, and only the creased cube, fitted, shows whether it is a box."""
PARALLEL = 0.9
"""Two edges of a cage as placed are parallel when the cosine of their directions exceeds this."""


def _proposals(problem) -> CreaseProposals:
    """The target's feature lines, built once per problem (the search's own when its crease ops are on)."""
    found = getattr(problem, "proposals", None) or getattr(problem, "_sharp_proposals", None)
    if found is None:
        target = problem.target
        found = CreaseProposals(target.points, target.faces, boundary=problem.config.boundary)
        problem._sharp_proposals = found
    return found


def cage_sharp_edges(mesh: PolyMesh, angle_deg: float = CAGE_ANGLE) -> np.ndarray:
    """The interior edges of ``mesh`` whose two faces' normals differ by more than ``angle_deg``."""
    normals = mesh.face_newell
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    faces = mesh.topology.edge_faces
    inner = faces[:, 1] >= 0
    cos = np.einsum("ij,ij->i", normals[faces[:, 0]], normals[np.maximum(faces[:, 1], 0)])
    return np.flatnonzero(inner & (cos < np.cos(np.radians(angle_deg))))


def parallel_classes(mesh: PolyMesh, edges: np.ndarray) -> list[np.ndarray]:
    """``edges`` of ``mesh`` grouped by direction (:data:`PARALLEL`), in ``mesh``'s own positions: a placed
    box's three axes."""
    ends = mesh.vertices[mesh.topology.edges[edges]]
    direction = ends[:, 1] - ends[:, 0]
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
    classes, left = [], np.arange(len(edges))
    while len(left):
        same = np.abs(direction[left] @ direction[left[0]]) > PARALLEL
        classes.append(edges[left[same]])
        left = left[~same]
    return classes


def crease_sets(problem, cage: PolyMesh, fitted: PolyMesh, coarse: bool = False) -> list[tuple[Crease, ...]]:
    """The crease sets tried on ``fitted`` (``cage`` fitted): :func:`sharp_ops`'s, and with ``coarse`` on a
    box-like cage (its creased edges of three directions as ``cage`` is placed), also each with one direction's
    edges left smooth: the rims of a cylinder or of a rounded slab. Creasing all twelve edges of the placed
    cube squares a capacitor's can (1.7e-2 of the diagonal both ways, the smooth cube 2.7e-2); leaving the four
    along its axis smooth fits 7.6e-3, a power package's tab 1.5e-2 (all creased 4.4e-2)."""
    ops = sharp_ops(problem, fitted, coarse)
    if not ops or not coarse:
        return [ops] if ops else []
    edges = np.array([op.edge for op in ops], dtype=np.int64)
    classes = parallel_classes(cage, edges)
    if len(classes) != 3:
        return [ops]
    smooth = [set(c.tolist()) for c in classes]
    return [ops] + [tuple(op for op in ops if op.edge not in s) for s in smooth]


def sharp_ops(problem, fitted: PolyMesh, coarse: bool = False) -> tuple[Crease, ...]:
    """A crease (infinitely sharp) of each smooth interior edge of ``fitted`` whose limit curve runs along a
    feature line of ``problem``'s target; with ``coarse``, when none does, of each of its edges whose faces meet
    at more than :data:`CAGE_ANGLE` (module docstring). Empty when ``config.sharp_edges`` is off or the target
    has no feature line."""
    if not problem.config.sharp_edges:
        return ()
    proposals = _proposals(problem)
    edges = np.asarray(proposals.edges(fitted), dtype=np.int64)
    if not len(edges) and coarse and len(proposals.features):
        edges = cage_sharp_edges(fitted)
    edges = edges[fitted.edge_sharpness[edges] < SHARPNESS_INFINITE] if len(edges) else edges
    return tuple(Crease(int(e), float(SHARPNESS_INFINITE)) for e in sorted(edges.tolist()))


def sharpened(problem, cage: PolyMesh, fitted: np.ndarray, cost: float, rounds: int,
              deadline: float | None = None, coarse: bool = False
              ) -> tuple[tuple[Crease, ...], np.ndarray, float, bool] | None:
    """``(the creases, the creased cage's fitted vertices, its distance, whether that fit started from
    ``fitted``)`` for ``cage`` (its vertices ``fitted`` are at ``cost``), fitted ``rounds`` as the gate fits
    (adaptive) from both ``fitted`` and ``cage``'s own positions, the closer kept: the creases move the limit
    off the fitted positions, and either start may stall (an E core's start, 89 creases: 8.3e-4 of the diagonal
    from the fitted cage, 1.3e-3 from its own; a power package's, 114: 1.6e-3 and 1.0e-3). None when nothing
    is creased, the fits fail or time runs out, or the closer is not :data:`MIN_GAIN` closer than ``cost``.
    ``coarse``: see :func:`sharp_ops`."""
    if deadline is not None and time.perf_counter() >= deadline:
        return None
    moved = cage.with_vertices(fitted)
    best = None
    for ops in crease_sets(problem, cage, moved, coarse):
        found = None
        for start, warm in ((moved, True), (cage, False)):
            state = apply_ops(ops, start)
            if state is None or (deadline is not None and time.perf_counter() >= deadline):
                break
            try:
                vertices, creased = problem.fit(state, rounds, min_gain=1.0, adaptive=True, deadline=deadline,
                                                settle=True)
            except GsrError:
                continue
            if np.isfinite(creased) and (found is None or creased < found[2]):
                found = (ops, vertices, float(creased), warm)
        # a cube with fewer creases replaces the fully creased one only where it is MIN_GAIN closer: the
        # template's path grows from it (an inductor's rounded slab, its rims creased: 1.88e-2 at 8 vertices,
        # 1.94e-2 fully creased; its path ran 1.1-2.8x behind the quad-remesh baseline from 98 to 258 vertices,
        # the fully creased cube's was ahead up to 80 and even at 162)
        if found is not None and (best is None or found[2] <= MIN_GAIN * best[2]):
            best = found
    return best if best is not None and best[2] <= MIN_GAIN * cost else None
