"""A shorter modelling history for the same control mesh: the designer's history, not the search's.

The search ends with whatever ops got there first, and its vertex polish is written as moves; several
histories build the same connectivity (on a cube, an inset then an extrude of the inset face, two
parallel edge loops, or two extrusions). :func:`simplify_history` looks for the history a designer would
write: a *skeleton* of structural ops (E L B I) that builds the same connectivity, whose op parameters
place as many vertices as they can, so that fewer ``translate_vertex`` moves are left:

1. skeletons of at most as many structural ops as the genome has are enumerated from the template with
   nominal parameters, breadth first, within a budget of op applications;
2. for each that builds a mesh isomorphic to the goal (:mod:`gsr_cad.geometry.isomorphism`), the
   template's vertices are first moved to where the goal has them, then the skeleton's parameters are
   fitted by least squares to the goal's vertices, and moves fix whatever is left;
3. the shortest such history replaces the genome if it is shorter; it replays to the goal's control
   mesh within a tolerance (by default ``1e-12`` of the diagonal: exactly), vertices and faces renumbered
   as its ops number them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence

import numpy as np
import scipy.optimize

from ..errors import OpError
from ..geometry.isomorphism import connectivity_hash, isomorphisms
from ..geometry.polymesh import PolyMesh
from .base import replay
from .mesh import Bevel, EdgeLoop, Extrude, Inset, MeshOp, _face_inradius, _local_edge_size, moves_to
from .mesh_conn import mesh_view

STRUCTURAL = "ELBI"
"""Ops that change the connectivity (the others only move vertices)."""
EXACT = 1e-12
"""Vertices closer than this (over the diagonal) count as in place."""
_NOMINAL = 0.25  # nominal I thickness / B offset, as a fraction of the room the element has


def _candidates(mesh: PolyMesh, kinds: str, scale: float) -> Iterator[MeshOp]:
    """Every structural op of ``kinds`` on ``mesh`` with nominal parameters."""
    view = mesh_view(mesh)
    conn, P = view.conn, view.P
    for f in range(conn.n_faces):
        if "E" in kinds:
            yield Extrude(f, 0.1 * scale)
        if "I" in kinds:
            size = _face_inradius(P, conn.faces[f])
            if size > 0:
                yield Inset(f, _NOMINAL * size)
    for e in range(len(conn.edges)):
        if "L" in kinds:
            yield EdgeLoop(e)
        if "B" in kinds:
            size = _local_edge_size(P, conn, e)
            if size > 0:
                yield Bevel(e, _NOMINAL * size)


def skeletons(template: PolyMesh, goal: PolyMesh, kinds: str = STRUCTURAL, max_ops: int = 3,
              budget: int = 6000, should_stop: Callable[[], bool] | None = None) -> Iterator[tuple[MeshOp, ...]]:
    """Sequences of at most ``max_ops`` structural ops (letters ``kinds``) that build, from ``template``, a
    mesh with ``goal``'s connectivity (nominal parameters; at most ``budget`` op applications; the
    enumeration ends early once ``should_stop()`` is true)."""
    kinds = "".join(k for k in kinds if k in STRUCTURAL)
    want = connectivity_hash(goal)
    scale = template.diagonal
    frontier: list[tuple[tuple[MeshOp, ...], PolyMesh]] = [((), template)]
    seen: set[tuple[str, bytes, tuple]] = set()
    spent = 0
    for depth in range(max_ops):
        nxt = []
        for ops, state in frontier:
            for op in _candidates(state, kinds, scale):
                spent += 1
                if spent > budget or (should_stop is not None and should_stop()):
                    return
                try:
                    mesh = op.apply(state)
                except OpError:
                    continue
                if mesh.n_vertices > goal.n_vertices or mesh.n_faces > goal.n_faces:
                    continue
                # the same mesh by another route (an edge loop named by any edge of its ring) is explored once
                key = ("".join(o.letter for o in ops) + op.letter, np.round(mesh.vertices / scale, 9).tobytes(),
                       mesh.topology_key)
                if key in seen:
                    continue
                seen.add(key)
                same_size = (mesh.n_vertices, mesh.n_faces) == (goal.n_vertices, goal.n_faces)
                if same_size and connectivity_hash(mesh) == want:
                    yield ops + (op,)
                if depth + 1 < max_ops:
                    nxt.append((ops + (op,), mesh))
        frontier = nxt
        if not frontier:
            return


def _with_parameter(op: MeshOp, x: float) -> MeshOp:
    """``op`` with its parameter set from the fitting variable ``x`` (positive ones through ``exp``)."""
    if isinstance(op, Extrude):
        return Extrude(op.face, x)
    if isinstance(op, Inset):
        return Inset(op.face, math.exp(x))
    if isinstance(op, Bevel):
        return Bevel(op.edge, math.exp(x))
    return op


def _parameter(op: MeshOp) -> float | None:
    if isinstance(op, Extrude):
        return op.distance
    if isinstance(op, Inset):
        return math.log(op.thickness)
    if isinstance(op, Bevel):
        return math.log(op.offset)
    return None


def _fitted(template: PolyMesh, skeleton: Sequence[MeshOp], goal: PolyMesh, phi: np.ndarray, tol: float,
            prefixes: dict) -> tuple[tuple[MeshOp, ...], PolyMesh] | None:
    """The history "template moves, ``skeleton`` with fitted parameters, moves" for one isomorphism
    ``phi`` (skeleton vertex -> goal vertex; vertices within ``tol`` need no move) and the mesh it builds,
    or None if its ops refuse. ``prefixes`` memoises the template moves (:func:`~gsr_cad.ops.mesh.moves_to`)
    across calls."""
    target = goal.vertices[phi]
    n0 = template.n_vertices
    key = (target[:n0].tobytes(), tol)
    if key not in prefixes:
        prefixes[key] = moves_to(template, target[:n0], tol)
    prefix, start, refused = prefixes[key]
    if refused:
        return None
    slots = [i for i, op in enumerate(skeleton) if _parameter(op) is not None]
    x0 = np.array([_parameter(skeleton[i]) for i in slots], dtype=float)
    miss = 10.0 * goal.diagonal

    def ops_for(x: np.ndarray) -> list[MeshOp]:
        ops = list(skeleton)
        for j, i in enumerate(slots):
            ops[i] = _with_parameter(ops[i], float(x[j]))
        return ops

    def residual(x: np.ndarray) -> np.ndarray:
        try:
            state = replay(start, ops_for(x))
        except (OpError, ValueError, OverflowError):
            return np.full(target.size, miss)
        return (state.vertices - target).ravel()

    if slots:
        fit = scipy.optimize.least_squares(residual, x0, method="lm" if target.size >= len(x0) else "trf",
                                           xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=50 * (len(x0) + 1))
        x = fit.x if np.abs(fit.fun).max() < miss else x0
    else:
        x = x0
    ops = ops_for(x)
    try:
        state = replay(start, ops)
    except OpError:
        return None
    rest, built, refused = moves_to(state, target, tol)
    return None if refused else (prefix + tuple(ops) + rest, built)


def simplify_history(template: PolyMesh, genome: Sequence[MeshOp], tolerance: float | Sequence[float] = EXACT,
                     accept: Callable[[tuple[MeshOp, ...]], bool] | None = None, kinds: str = STRUCTURAL,
                     max_ops: int = 3, max_isomorphisms: int = 48, budget: int = 6000,
                     should_stop: Callable[[], bool] | None = None) -> tuple[MeshOp, ...]:
    """The shortest history found that builds ``genome``'s control mesh from ``template`` (see the module
    doc), or ``genome`` itself when none is shorter.

    Every vertex of the new history's mesh lies within ``tolerance`` (over the diagonal) of the old
    one's, so its limit surface moves no further. ``accept`` (e.g. "the fit to the target is still good")
    can veto a history; with several tolerances, the loosest is tried first (fewest moves), then tighter
    ones for a still shorter history (their fits may pass ``accept`` where a looser one's did not).
    ``kinds`` limits the structural ops tried; genomes with more than ``max_ops`` structural ops are
    returned as they are. Once ``should_stop()`` is true (polled between steps) the shortest history
    found so far is returned.
    """
    def stopping() -> bool:
        return should_stop is not None and bool(should_stop())

    genome = tuple(genome)
    n_struct = sum(op.letter in STRUCTURAL for op in genome)
    if n_struct == 0 or n_struct > max_ops:
        return genome
    try:
        goal = replay(template, genome)
    except OpError:
        return genome
    tolerances = sorted({max(float(t), EXACT) for t in np.atleast_1d(tolerance)}, reverse=True)
    found = []
    for skeleton in skeletons(template, goal, kinds, n_struct, budget, should_stop):
        found += [(skeleton, phi) for phi in isomorphisms(replay(template, skeleton), goal, max_isomorphisms)]
    best = genome
    prefixes: dict = {}
    for rel in tolerances:  # loosest first (fewest moves); a tighter one serves when ``accept`` vetoes it
        tol = rel * goal.diagonal
        tries = []  # (fewest ops it can take: template vertices to move first + skeleton, order, skeleton, phi)
        for skeleton, phi in found:
            off = np.linalg.norm(goal.vertices[phi[:template.n_vertices]] - template.vertices, axis=1) > tol
            tries.append((int(off.sum()) + len(skeleton), len(tries), skeleton, phi))
        tries.sort(key=lambda t: t[:2])
        cap = len(best) - 1  # the most ops a history may have
        for least, _, skeleton, phi in tries:
            if least > cap or stopping():
                break
            fitted = _fitted(template, skeleton, goal, phi, tol, prefixes)
            if fitted is None or len(fitted[0]) > cap:
                continue
            history, built = fitted
            if np.abs(built.vertices - goal.vertices[phi]).max() <= tol and (accept is None or accept(history)):
                best, cap = history, len(history) - 1
    return best


__all__ = ["EXACT", "STRUCTURAL", "simplify_history", "skeletons"]
