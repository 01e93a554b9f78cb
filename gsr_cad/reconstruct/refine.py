"""Coarse-to-fine refinement (beyond the paper): structure grown where the residual is.

After the search, the winner's cage is refined level by level. Each level measures the two-sided
residual of the current cage (the target's points -> their foot points on the exact limit surface, the
surface's area samples -> the target) and attributes it to the control vertices by the weights with which
each point depends on them (its sparse row of the limit map), then to the faces around them. The
proposals aim at it: an edge loop (L) across each of the rings of quads carrying most residual, an
extrude (E) of the face under the largest outward error (arms, ears, protrusions), a pocket (an inset, then an
extrude into the mesh, :func:`pocket`) of the face over the largest inward error (engravings, dimples), an inset (I) of the
face with the largest error and a bevel (B) of the edge whose faces carry most error where the cage
bends; insets of the faces carrying half the residual at once (:func:`inset_batch`: vertices added where
the error is, not around whole rings); and a split of the whole cage (an edge loop through every ring: one Catmull-Clark step's
connectivity, its vertices placed so that the limit surface stays the same, :func:`split_all`); and a balanced
split (edge loops across the rings with the longest edges until the cage has ``BALANCED_GROWTH`` times its
vertices, :func:`balanced_split`: quads about square, where a split keeps a box's proportions on an elongated
target); when no split fits the faces or the time left, as many of its loops as do, across the rings with most
residual (:func:`budget_split`). Each proposal is fitted by a few rounds of the adaptive least-squares fit
(:meth:`~gsr_cad.reconstruct.surface.SurfaceProblem.fit`, sparse, which keeps every face sound and clear
of the ops' limits), a split or a balanced split by a full fit (it starts at about the same distance); the one that gains most for
its growth (``LEVEL_COST``) is kept and fitted further, the next one when its full fit gains too little or
its moves cannot replay (then the cage the replayable moves reach stands, if it gains); when no trial gains,
the closest ones get their full fit all the same. Each level's cage is then fitted on to convergence
(:func:`_finish`) before the next grows from it; a level of several ops is checked against the prefix of them
nearest the middle of its growth, fitted alike, and the closer of the two is the level (:func:`_middle`: a split
can converge to a local minimum its own prefix beats). Its residual aims the next ops at what the structure cannot
fit, not at what a few more rounds would (example012: 642 control vertices at 3.0e-3 of the diagonal both ways
and ahead of the quad-remesh baseline at every front point, against 1,056 at 3.1e-3 and five front points
behind it without). Cages that ops grow from keep their corners convex (the ops then apply to them); those no
op will grow from (the last level, the front's cages) are finished with corners free to turn concave
(:func:`_finish`). When no single proposal gains, several edge loops are added at once (:func:`_fallback`). Faces the fit starts from
unsound (a split of a skewed cage) keep their vertices; the rest of the cage still moves. The fits' back
direction projects onto a fine mesh target's triangles near a bounded area sample of it
(:class:`~gsr_cad.geometry.surface_distance.NearTriangles`), the reported metrics onto all of them. Levels
stop once the distance reaches the goal, the time or face budget runs out, nothing gains, or a level's history
would exceed what a result holds (``MAX_OPS``).

History: the structural ops replay on the geometry the search left them (the template's, moved by the
search's ops), where they apply cleanly, followed by the moves of the final fit (in stages when the
straight path would fold a face); when those moves cannot replay, a level's ops follow the previous
level's moves instead (after moves onto a smoother cage, :func:`limit_cage` and its own, where the fitted
quads are too skewed for them, :func:`_after`). A proposal that folds a face on the fitted cage is built on such a
smoother cage and carried back onto the fitted one (:func:`carried`). Every level is a point of the accuracy/complexity front,
and so, in the time left, are prefixes of the levels that added several ops at once (:func:`_fill_front`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import GsrError, OpError
from ..geometry.limit_surface import LimitSurface, get_layout
from ..geometry.polymesh import PolyMesh
from ..geometry.subdivision import get_catmull_clark
from ..ops.mesh import Bevel, EdgeLoop, Extrude, Inset, MeshOp, TranslateVertex
from ..ops.mesh_conn import mesh_view
from ..ops.mesh_kernel import distinct_rings, edge_ring, unsound_faces
from .result import MAX_OPS

TRIAL_ROUNDS = 3  # least-squares rounds a candidate gets before it is compared
BATCH_SHARE = 0.5  # the batch of insets (:func:`inset_batch`) covers the faces with this share of the residual
BATCH_FACES = 0.25  # and at most this share of the faces
BALANCED_GROWTH = 3.0  # a balanced split (:func:`balanced_split`) grows the cage's vertices this many times
BALANCE_RATIO = 1.5  # and is proposed when the longest ring's edges are this many times the median ring's
LEVEL_ROUNDS = 12  # rounds the kept candidate gets
LEVEL_TRIES = 3  # proposals given the full fit, best first, until one gains
MIN_GAIN = 0.995  # a level must shrink the distance below this factor of the last one's
FINISH_ROUNDS = 60  # most rounds the last cage's fit gets after the levels (:func:`_finish`)
FILL_STEP = 1.25  # the front's points between levels (:func:`_fill_front`) grow by at least this factor
FRONT_TAIL = 1.5  # the front's cages are finished while this many times the final cage's tail is left
SNAP_PASSES = 3  # passes of snapping far control vertices onto the target and refitting (:func:`snapped`)
SNAP_FACTOR = 2.0
LEVEL_SNAPS = 1  # snap passes after each level's fit (LEVEL_ROUNDS rounds each)
SNAP_ROUNDS = 30
REACH_REFITS = 2
LAST_ROUNDS = 180  # a level with no room for this many more fit rounds is taken as the last (:func:`_finish`)
SOUND_PASSES = 4  # passes putting faces the ops refuse back on the smoother cage (:func:`carried`)
SMOOTHINGS = 3  # smoother cages a level's ops may follow when they fold a face on the fitted one (:func:`_after`)
REACH_SLACK = 1.05  # a partly replayed level's cage is refitted while it is this much farther than its fit
"""Where some of a level's moves refuse (they would fold a face on the way), the cage the others reach is fitted
again from there and moved to, up to this many times (example010's first split: 7 of 42 vertices refused and the
refinement stopped at 2.3e-2 of the diagonal with four fifths of its time left)."""
STIFFNESS = 0.1  # first stiffness of the adaptive fits (see SurfaceProblem.fit)
LEVEL_COST = 1.0
"""A level's own cost in the proposals' ranking, as the log of a cage growth: a proposal scores its log-gain
in distance over (log of the cage's growth + this), so a split that gains more per level beats a local op
that gains more per added vertex when the residual is spread (coarse to fine within the time)."""


@dataclasses.dataclass(frozen=True)
class Level:
    """One refinement level: the ops added (none for the starting cage), the fitted cage, its distance, the
    seconds since the refinement started and the proposal that made it (``KINDS``)."""

    ops: tuple[MeshOp, ...]
    control: PolyMesh
    cost: float
    seconds: float
    kind: str = "start"


KINDS = ("start", "split", "balanced split", "budget split", "edge loop", "extrude", "inset", "bevel", "pocket",
         "inset batch", "loops at once", "middle prefix", "finish")
"""What made a level: the cage the refinement started from, a proposal of the module docstring (a single op by its
name; ``loops at once``: :func:`_fallback`), the middle prefix of a level of several ops (:func:`_middle`), or the
last cage fitted on to convergence."""


@dataclasses.dataclass(frozen=True)
class Residual:
    """Residual of a cage attributed to its faces: ``total`` (both directions), ``outward`` (target
    points outside the surface, along its normal) and ``inward`` (inside it) per face."""

    total: np.ndarray
    outward: np.ndarray
    inward: np.ndarray


def residual(problem, mesh: PolyMesh) -> Residual:
    """The two-sided residual of ``mesh``'s limit surface on ``problem``'s target, per control face."""
    layout = get_layout(mesh, problem.config.boundary, problem.config.limit_depth)
    surface = LimitSurface(layout, mesh.vertices)
    pairs, _ = problem._pairs(surface)
    foot = pairs.foot
    d_fwd = problem.point_weight * foot.distance
    signed = np.einsum("ij,ij->i", problem.points - foot.point, foot.normal)
    out_fwd = problem.point_weight * np.maximum(signed, 0.0)
    in_fwd = problem.point_weight * np.maximum(-signed, 0.0)
    d_back = pairs.weight * np.linalg.norm(pairs.goal - pairs.samples.point, axis=1)
    R1 = abs(surface.rows(foot))
    R2 = abs(surface.rows(pairs.samples))
    per_vertex = R1.T @ d_fwd + R2.T @ d_back
    out_vertex = R1.T @ out_fwd
    in_vertex = R1.T @ in_fwd
    sizes = mesh.face_sizes
    inc = sp.csr_matrix((np.ones(len(mesh.corners)), (np.repeat(np.arange(mesh.n_faces), sizes), mesh.corners)),
                        shape=(mesh.n_faces, mesh.n_vertices))
    return Residual(*(np.asarray(inc @ x).ravel() / sizes for x in (per_vertex, out_vertex, in_vertex)))


def edge_rings(mesh: PolyMesh) -> list[tuple[int, list[int]]]:
    """Every distinct ring an edge loop can cut through quads without meeting itself at a vertex:
    ``(an edge of it, the faces it crosses)``."""
    conn = mesh_view(mesh).conn
    out = []
    for e, ring, quads in distinct_rings(conn):
        ends = [v for r in ring for v in conn.edges[r]]
        if quads and len(set(ends)) == len(ends):
            out.append((e, [f for f, _ in quads]))
    return out


def _inradius(mesh: PolyMesh, face: int) -> float:
    cyc = mesh.faces[face]
    p = mesh.vertices[list(cyc)]
    c = p.mean(axis=0)
    return float(np.linalg.norm(p - c, axis=1).min())


def candidates(mesh: PolyMesh, res: Residual, n_loops: int = 3) -> list[MeshOp]:
    """Structural ops aimed at the residual (module docstring): the ``n_loops`` edge rings with most total
    residual and the densest one, an extrude of the face with most outward residual, an inset of the face
    with most residual, a bevel of the edge between the two faces with most residual where they bend."""
    ops: list[MeshOp] = []
    rings = edge_rings(mesh)
    if rings:
        total = np.array([res.total[faces].sum() for _, faces in rings])
        dense = total / np.array([len(faces) for _, faces in rings])
        pick = list(np.argsort(-total)[:n_loops]) + [int(np.argmax(dense))]
        ops += [EdgeLoop(rings[i][0]) for i in dict.fromkeys(int(i) for i in pick)]
    if np.any(res.outward > 0):
        f = int(np.argmax(res.outward))
        size = _inradius(mesh, f)
        if size > 0:
            ops.append(Extrude(f, 0.25 * size))
    f = int(np.argmax(res.total))
    size = _inradius(mesh, f)
    if size > 0:
        ops.append(Inset(f, 0.3 * size))
    conn = mesh_view(mesh).conn
    edges = np.array(conn.edges, dtype=np.int64).reshape(-1, 2)
    sides = np.array([conn.edge_faces(e) for e in range(len(edges))], dtype=np.int64).reshape(-1, 2)
    inner = np.flatnonzero(sides[:, 1] >= 0)
    if inner.size:
        a, b = sides[inner, 0], sides[inner, 1]
        n = mesh.face_newell
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        score = (1.0 - np.einsum("ij,ij->i", n[a], n[b])) * (res.total[a] + res.total[b])
        k = int(np.argmax(score))
        if score[k] > 0:
            u, v = edges[inner[k]]
            ops.append(Bevel(int(inner[k]), 0.15 * float(np.linalg.norm(mesh.vertices[u] - mesh.vertices[v]))))
    return ops


def pocket(mesh: PolyMesh, res: Residual) -> tuple[MeshOp, ...]:
    """A pocket in the face with most inward residual (target points inside the surface: an engraving, a
    dimple, a slot): an inset by ``0.3`` of its inradius, then an extrude of the inner face into the mesh by
    ``0.25`` of it (an inward extrude alone would stand its walls on the neighbouring faces where they meet at a
    right angle or less). Empty when no face has inward residual."""
    if not np.any(res.inward > 0):
        return ()
    f = int(np.argmax(res.inward))
    size = _inradius(mesh, f)
    return (Inset(f, 0.3 * size), Extrude(f, -0.25 * size)) if size > 0 else ()


def inset_batch(mesh: PolyMesh, res: Residual) -> tuple[MeshOp, ...]:
    """Insets of the faces carrying ``BATCH_SHARE`` of the residual, most first (at most a ``BATCH_FACES`` share of
    the faces, at least two): vertices added where the error is, where an edge loop's ring or a split adds them
    around the whole cage, through regions the surface already fits. Each face's inset is ``0.3`` of its inradius;
    the faces keep their indices, so the insets apply in turn. Empty when fewer than two faces carry residual."""
    order = np.argsort(-res.total, kind="stable")
    share = np.cumsum(res.total[order]) / max(float(res.total.sum()), 1e-300)
    count = int(np.searchsorted(share, BATCH_SHARE)) + 1
    count = max(2, min(count, int(BATCH_FACES * mesh.n_faces)))
    ops = []
    for f in order[:count]:
        size = _inradius(mesh, int(f))
        if size > 0 and res.total[f] > 0:
            ops.append(Inset(int(f), 0.3 * size))
    return tuple(ops) if len(ops) >= 2 else ()


def carried(ops: tuple[MeshOp, ...], mesh: PolyMesh, soft: PolyMesh | None = None) -> PolyMesh | None:
    """``ops`` applied where they fold a face on the fitted ``mesh``: on ``soft`` (its cage moved towards the limit
    cage as far as moves replay, :func:`softened`) or its first limit cage where they apply (:func:`limit_cage`, up
    to ``SMOOTHINGS`` deep), then carried back onto ``mesh``: each of its vertices moved by its own offset from that
    cage, each new vertex by the mean offset of its neighbours that have one, except where that leaves a face the
    ops would refuse (those faces keep the smoother cage's positions: a fit holds such faces, and a cage with them
    cannot be reached by moves). None when they apply on none. On a converged cage most ops fold a face
    (LetterBlock, 324 control vertices: every edge loop and the bevel), though its fit would gain (each loop:
    2-3 % in 12 rounds)."""
    smooth = mesh
    for k in range(-1 if soft is not None else 0, SMOOTHINGS):
        smooth = soft if k < 0 else limit_cage(mesh if smooth is soft else smooth)
        built = apply_ops(ops, smooth)
        if built is not None:
            break
    else:
        return None
    n = mesh.n_vertices
    offset = np.zeros_like(built.vertices)
    offset[:n] = mesh.vertices - smooth.vertices
    known = np.zeros(built.n_vertices, dtype=bool)
    known[:n] = True
    corners, sizes = built.corners, built.face_sizes
    starts = np.repeat(np.cumsum(sizes) - sizes, sizes)
    nxt = starts + (np.arange(len(corners)) - starts + 1) % np.repeat(sizes, sizes)
    a = np.concatenate([corners, corners[nxt]])
    b = np.concatenate([corners[nxt], corners])
    adjacency = sp.csr_matrix((np.ones(len(a)), (a, b)), shape=(built.n_vertices,) * 2)
    adjacency.data[:] = 1.0
    while not known.all():
        count = adjacency @ known.astype(np.float64)
        reach = ~known & (count > 0)
        if not reach.any():
            return None
        offset[reach] = (adjacency @ (offset * known[:, None]))[reach] / count[reach, None]
        known |= reach
    out = built.vertices + offset
    for _ in range(SOUND_PASSES):
        bad = unsound_faces(built.with_vertices(out), built.face_newell)
        if not bad.any():
            break
        corners = built.corners[np.repeat(bad, built.face_sizes)]
        out[corners] = built.vertices[corners]
    return built.with_vertices(out)


def balanced_split(mesh: PolyMesh, growth: float = BALANCED_GROWTH) -> tuple[MeshOp, ...]:
    """Edge loops, each across the ring whose edges are longest on average (the current ones), until the cage
    has ``growth`` times its vertices: its quads made about square, as a designer adds loops along a long
    part. A split keeps the cage's proportions: a box on an elongated target keeps quads as long as the
    target's aspect (bone, 4:4:4 loops, 98 control vertices fitted: 3.9e-3 of the diagonal both ways; 8:3:2
    loops, 94: 8.2e-4). Where the longest ring's loop would fold a face (a fitted cage's skewed quads), the next
    longest is cut. Empty when the cage is not all quads (as for a split), it is balanced already (its longest
    ring's edges under ``BALANCE_RATIO`` times the median ring's: then the split, which keeps the limit surface,
    does as well and the level's time goes to one full fit, not two), or the loops that apply grow it less than
    ``FILL_STEP`` times: that is no split, and it must not stand in for one (example007's 546-vertex cage: one
    loop applied, the next folded a face, and that one loop kept the budget split from being proposed)."""
    ops: list[MeshOp] = []
    if np.any(mesh.face_sizes != 4):
        return ()  # a loop ends in a face that is not a quad and adds a side to it: ever higher n-gons
    goal = growth * mesh.n_vertices
    current = mesh
    while current.n_vertices < goal:
        conn = mesh_view(current).conn
        P = current.vertices
        rings, lengths = [], []
        for e, ring, quads in distinct_rings(conn):
            ends = [v for r in ring for v in conn.edges[r]]
            if quads and len(set(ends)) == len(ends):
                pairs = np.array([conn.edges[r] for r in ring], dtype=np.int64)
                rings.append(e)
                lengths.append(float(np.linalg.norm(P[pairs[:, 0]] - P[pairs[:, 1]], axis=1).mean()))
        if not rings or (not ops and max(lengths) < BALANCE_RATIO * float(np.median(lengths))):
            break  # nothing to cut, or the quads are about square already (a split does as well, and keeps the limit)
        for i in np.argsort(-np.asarray(lengths), kind="stable"):  # the longest ring whose loop folds no face
            try:
                grown = EdgeLoop(rings[int(i)]).apply(current)
            except OpError:
                continue
            current = grown
            ops.append(EdgeLoop(rings[int(i)]))
            break
        else:
            break
    return tuple(ops) if current.n_vertices >= FILL_STEP * mesh.n_vertices else ()


def budget_split(mesh: PolyMesh, res: Residual, room: Callable[[PolyMesh], bool],
                 soft: PolyMesh | None = None) -> tuple[MeshOp, ...]:
    """Edge loops across the rings carrying most residual, most first, while the cage they build has ``room`` (the
    time or faces left; a split, every ring at once, has not): a split's resolution where the error is, as much
    of it as the budget holds. The rings are cut on ``soft`` (:func:`softened`), else on the first limit cage
    (:func:`limit_cage`), where a converged cage's skewed quads would fold under them. Empty when fewer than two
    loops fit or they grow the cage less than ``FILL_STEP`` times (a single loop is proposed on its own)."""
    rings = edge_rings(mesh)
    if len(rings) < 2:
        return ()
    total = np.array([res.total[faces].sum() for _, faces in rings])
    ends = mesh_view(mesh).conn.edges
    ops: tuple[MeshOp, ...] = ()
    built = limit_cage(mesh) if soft is None else soft
    for i in np.argsort(-total, kind="stable"):
        # a loop splits only its own ring's edges: the others keep their ends, found by them
        index = {frozenset(e): k for k, e in enumerate(mesh_view(built).conn.edges)}
        e = index.get(frozenset(ends[rings[int(i)][0]]))
        if e is None:
            continue
        try:
            grown = EdgeLoop(e).apply(built)
        except OpError:
            continue
        if not room(grown):
            break
        ops, built = ops + (EdgeLoop(e),), grown
    return ops if len(ops) >= 2 and built.n_vertices >= FILL_STEP * mesh.n_vertices else ()


def split_all(state: PolyMesh, fitted: PolyMesh) -> tuple[tuple[MeshOp, ...], PolyMesh, PolyMesh] | None:
    """An edge loop through every ring of ``state`` (a closed all-quad mesh whose rings are all closed):
    the connectivity of one Catmull-Clark step. Returns ``(the loops, the mesh they build from state,
    that mesh with the vertices of the Catmull-Clark step of fitted)`` (the same limit surface as
    ``fitted``, which has ``state``'s connectivity), or None when the loops build something else."""
    n = state.n_vertices
    if np.any(state.face_sizes != 4) or np.any(state.topology.edge_faces[:, 1] < 0):
        return None
    weights = [{i: 1.0} for i in range(n)]
    ops: list[MeshOp] = []
    mesh = state
    while True:
        conn = mesh_view(mesh).conn
        todo = [e for e, (u, v) in enumerate(conn.edges) if u < n and v < n]
        if not todo:
            break
        try:
            ring, _, _, closed = edge_ring(conn, todo[0])
            if not closed:
                return None
            grown = EdgeLoop(todo[0]).apply(mesh)
        except OpError:
            return None
        for e in ring:
            u, v = conn.edges[e]
            w: dict[int, float] = {}
            for k, x in (*weights[u].items(), *weights[v].items()):
                w[k] = w.get(k, 0.0) + 0.5 * x
            weights.append(w)
        ops.append(EdgeLoop(todo[0]))
        mesh = grown
    topo = state.topology
    edge_index = {(int(a), int(b)): i for i, (a, b) in enumerate(topo.edges)}
    edge_index.update({(b, a): i for (a, b), i in list(edge_index.items())})
    face_index = {frozenset(f): i for i, f in enumerate(state.faces)}
    n_e = topo.n_edges
    where = np.empty(mesh.n_vertices, dtype=np.int64)
    for i, w in enumerate(weights):
        key = sorted(w)
        if len(key) == 1:
            where[i] = key[0]
        elif len(key) == 2 and tuple(key) in edge_index:
            where[i] = n + edge_index[tuple(key)]
        elif len(key) == 4 and frozenset(key) in face_index:
            where[i] = n + n_e + face_index[frozenset(key)]
        else:
            return None
    cc = get_catmull_clark(fitted, 1, "all")
    refined = cc.refine(fitted.vertices)
    mapped = {tuple(sorted(int(where[v]) for v in f)) for f in mesh.faces}
    if mapped != {tuple(sorted(f)) for f in refined.faces}:
        return None
    return tuple(ops), mesh, mesh.with_vertices(refined.vertices[where])


def _stop_when(deadline: float | None, should_stop: Callable[[], bool] | None) -> Callable[[], bool]:
    def out_of_time() -> bool:
        return ((deadline is not None and time.perf_counter() >= deadline)
                or (should_stop is not None and bool(should_stop())))
    return out_of_time


_MARGIN = 1.3  # predicted seconds are this many times the measured ones (the load varies)
MIN_ROUNDS = 2  # a fit starts only when this many of its rounds are predicted to end in time
_GROWTH = {"round": 1.0, "residual": 1.0, "commit": 2.0}
"""How each kind of the refinement's work grows with the cage's control vertices: a fit round and the residual
linearly (target points, area samples and unknowns), a level's commit as the square (each of its moves replays
on the whole cage)."""


class Timing:
    """Seconds of the refinement's work measured per kind (``_GROWTH``) and cage size, and predicted for another
    cage: the median of the measurements at the three largest cages not larger, each grown by ``_GROWTH`` (the
    smallest measured cage's as it is for a smaller one), ``_MARGIN`` times; 0 before any measurement."""

    def __init__(self) -> None:
        self.seen: dict[str, dict[int, float]] = {}

    def add(self, kind: str, vertices: int, seconds: float) -> None:
        self.seen.setdefault(kind, {})[int(vertices)] = float(seconds)

    def predict(self, kind: str, vertices: int) -> float:
        seen = self.seen.get(kind)
        if not seen:
            return 0.0
        below = sorted(n for n in seen if n <= vertices)[-3:] or [min(seen)]
        # the median of the three largest cages' (one slow commit, e.g. many staged moves, would otherwise
        # reserve minutes for every later commit and end the refinement with half the budget unused)
        grown = [seen[n] * max(vertices / n, 1.0) ** _GROWTH[kind] for n in below]
        return _MARGIN * float(np.median(grown))


class _Fitter:
    """The refinement's fits (adaptive, :meth:`~gsr_cad.reconstruct.surface.SurfaceProblem.fit`), timed: a fit
    whose first ``MIN_ROUNDS`` rounds are predicted to end after its deadline is skipped, and no round of one
    starts that would end after it. A cage's deadline leaves room for the work after its fit: its commit as a
    level and ``tail(vertices)`` (the caller's work after the refinement). ``should_stop()`` turning true ends a
    fit after its current round (Ctrl-C, or a second path told to stop: a large cage's fit takes tens of seconds)."""

    def __init__(self, problem, deadline: float | None, tail: Callable[[int], float] | None = None,
                 should_stop: Callable[[], bool] | None = None, free_corners: bool = False):
        self.problem = problem
        self.deadline = deadline
        self.tail = tail
        self.should_stop = should_stop
        self.free_corners = free_corners  # every fit lets corners turn concave (``convex`` is then ignored)
        self.timing = Timing()

    def end(self, mesh: PolyMesh) -> float | None:
        """The deadline of a fit of ``mesh`` (None: no time limit)."""
        if self.deadline is None:
            return None
        n = mesh.n_vertices
        return self.deadline - self.timing.predict("commit", n) - (self.tail(n) if self.tail is not None else 0.0)

    def late(self, mesh: PolyMesh) -> float | None:
        """The deadline of the work on ``mesh`` after its fit (its commit): the caller's tail kept free."""
        if self.deadline is None:
            return None
        return self.deadline - (self.tail(mesh.n_vertices) if self.tail is not None else 0.0)

    def fits_in_time(self, mesh: PolyMesh, rounds: int, extra: str | None = None) -> bool:
        """Whether a fit of ``mesh`` (after ``extra`` work of that kind, e.g. its residual) can do
        ``min(rounds, MIN_ROUNDS)`` rounds before its deadline."""
        end = self.end(mesh)
        if end is None:
            return True
        n = mesh.n_vertices
        ahead = self.timing.predict("round", n) * (min(rounds, MIN_ROUNDS) + 1)
        if extra is not None:
            ahead += self.timing.predict(extra, n)
        return time.perf_counter() + ahead <= end

    def has_room(self, mesh: PolyMesh, rounds: int) -> bool:
        """Whether ``rounds`` rounds of a fit of ``mesh`` (all of them, where :meth:`fits_in_time` asks for the
        first few), its residual and its commit are predicted to end before its deadline."""
        end = self.end(mesh)
        if end is None:
            return True
        n = mesh.n_vertices
        ahead = self.timing.predict("round", n) * (rounds + 1) + self.timing.predict("residual", n)
        return time.perf_counter() + ahead <= end

    def __call__(self, mesh: PolyMesh, rounds: int, stiffness: float = STIFFNESS,
                 fairing: float | None = None, convex: bool = True) -> tuple[np.ndarray, float]:
        start = time.perf_counter()
        out = self.problem.fit(mesh, rounds, min_gain=1.0, adaptive=True, stiffness=stiffness,
                               deadline=self.end(mesh), fairing=fairing, convex=convex and not self.free_corners,
                               should_stop=self.should_stop, settle=True)
        done = getattr(self.problem, "fit_rounds", rounds)
        self.timing.add("round", mesh.n_vertices, (time.perf_counter() - start) / (done + 1))
        return out

    def timed(self, kind: str, mesh: PolyMesh, work: Callable[[], object]):
        """``work()``, its seconds recorded as ``kind`` for a cage the size of ``mesh``."""
        start = time.perf_counter()
        out = work()
        self.timing.add(kind, mesh.n_vertices, time.perf_counter() - start)
        return out


def refine(problem, genome: tuple, goal: float, deadline: float | None, max_faces: int,
           record: Callable[[PolyMesh, float, tuple], None] | None = None,
           should_stop: Callable[[], bool] | None = None,
           tail: Callable[[int], float] | None = None,
           deferred: list[tuple[list[Level], Callable[[int], None]]] | None = None,
           free_corners: bool = False) -> tuple[tuple, list[Level]]:
    """Grow ``genome``'s cage on ``problem``'s target until its distance is at most ``goal`` (module
    docstring). ``deadline``: a ``time.perf_counter()`` value (None: no time limit); ``max_faces``: the
    largest cage. ``record(control, cost, genome)`` is called at every level with a genome that replays
    to it. ``tail(vertices)``: the seconds the caller needs after the refinement for a cage that size (kept
    free before the deadline; each fit, residual and commit is timed and the next predicted from them,
    :class:`Timing`). Returns the refined genome and the levels. The front's points between levels
    (:func:`_fill_front`) are filled in the time left, for at most ``config.refine_fill`` of the refinement's
    work (:attr:`~gsr_cad.reconstruct.surface.SurfaceProblem.evaluations`, which a seed repeats, where seconds
    would not), or, with ``deferred``, appended there as ``(levels, a call that fills them for at most the
    evaluations given)`` for the caller to run after its other refinements. ``free_corners``: every fit lets
    corners turn concave, not only those of cages no op grows from (another strategy, for a second path: closer
    on some chains, bone and example007's, behind on others, airplane's).

    The genome of a level is the structural ops (the search's, then the refinement's, replayed on the
    template's own geometry, where they apply cleanly) followed by one move per control vertex to the
    fitted cage; when those moves cannot all replay, each level's ops follow the previous level's moves.
    """
    started = time.perf_counter()
    work = problem.evaluations
    out_of_time = _stop_when(deadline, should_stop)
    _fit = _Fitter(problem, deadline, tail, should_stop, free_corners)
    genome = tuple(genome)
    fitted = problem.control_mesh(genome)
    base = tuple(op for op in genome if not isinstance(op, TranslateVertex))
    kept, base_state = problem.walk(base)
    if len(kept) != len(base) or base_state.topology_key != fitted.topology_key:
        base, base_state = genome, fitted
    v0, cost0 = _fit(fitted, LEVEL_ROUNDS)
    v, cost, via = snapped(problem, _fit, out_of_time, fitted.with_vertices(v0), cost0, LEVEL_SNAPS, LEVEL_ROUNDS)

    def start() -> tuple:  # the snapped fit, else the plain one, from the base or after the genome
        for goal, legs, c in ((v, via, cost), (v0, (), cost0)):
            for b, state in ((base, base_state), (genome, fitted)):
                reached = _reach(problem, b, state, goal, legs)
                if reached is not None:
                    return reached, goal, c
        return genome, fitted.vertices, problem.fit(fitted, 0)[1]

    full, v, cost = _fit.timed("commit", fitted, start)
    mesh = fitted.with_vertices(v)
    levels = [Level((), mesh, cost, time.perf_counter() - started, "start")]
    stages = [(base, base_state, full, mesh, cost)]  # what each level's cage is built from (for _finish)
    middles: set[int] = set()  # the vertices of the prefixes fitted by _middle (the fills skip them)
    if record is not None:
        record(mesh, cost, full)
    while (cost > goal and mesh.n_faces < max_faces and not out_of_time()
           and _fit.fits_in_time(mesh, TRIAL_ROUNDS, "residual")):
        res = _fit.timed("residual", mesh, lambda: residual(problem, mesh))
        soft: list[tuple] = []  # the level's softened cage (:func:`softened`), made once where an op needs it

        def softer() -> PolyMesh:
            if not soft:
                soft.append((full, *softened(problem, full)))
            return soft[0][2]

        proposals = []  # (ops, what they build from base_state or None, the cage to fit)
        split = split_all(base_state, mesh)
        smooth = mesh
        for _ in range(SMOOTHINGS if split is None else 0):
            # the loops on ever smoother cages, as :func:`_after` will place them (example012, 162 control
            # vertices: a loop folded a face on the base's geometry and on the first limit cage; no split was
            # proposed, no other op gained, and the refinement stopped with a third of its time left)
            smooth = limit_cage(smooth)
            split = split_all(smooth, mesh)
            if split is not None:
                split = (split[0], None, split[2])
                break
        kinds: dict[tuple, str] = {}
        if split is not None:
            proposals.append(split)
            kinds[split[0]] = "split"
        balanced = balanced_split(mesh)
        if balanced:
            b = apply_ops(balanced, mesh)
            if b is not None:
                a = apply_ops(balanced, base_state)
                proposals.append((balanced, a if a is not None and a.topology_key == b.topology_key else None, b))
                kinds.setdefault(balanced, "balanced split")
        batch = inset_batch(mesh, res)
        dug = pocket(mesh, res)
        local = [(op,) for op in candidates(mesh, res)] + [ops for ops in (dug, batch) if ops]
        kinds.update({dug: "pocket", batch: "inset batch"})
        kinds.update({ops: ops[0].name.replace("_", " ") for ops in local if len(ops) == 1})
        whole: set[tuple] = set()  # the local proposals fitted in full at once
        if not any(b.n_faces <= max_faces and _fit.fits_in_time(b, LEVEL_ROUNDS) for _, _, b in proposals):
            # no split fits the faces or the time left: as many of its loops as do, where the residual is (airplane,
            # its placed cube refined up to 250 faces: from 82 control vertices at 4.6e-3 of the diagonal, 132 at
            # 2.6e-3 and on to 181 at 1.7e-3, where single loops went on to 164 at 2.7e-3)
            part = budget_split(mesh, res, lambda g: g.n_faces <= max_faces and _fit.has_room(g, 2 * LEVEL_ROUNDS),
                                softer())
            if part:
                local.append(part)
                kinds.setdefault(part, "budget split")
                # fitted in full like a split: its trial rounds lag behind one op's (example007, 546 -> 1,584
                # control vertices: 5.95e-3 of the diagonal after three rounds, behind six single ops, where the
                # level stood at 5.67e-3; 5.05e-3 after its full fit)
                whole = {part}
        for ops in local:
            b = apply_ops(ops, mesh)
            if b is None:
                b = carried(ops, mesh, softer())
            if b is None:
                continue
            a = apply_ops(ops, base_state)
            proposals.append((ops, a if a is not None and a.topology_key == b.topology_key else None, b))
        scored = []
        for ops, a, b in proposals:
            # a split keeps the limit surface: it needs its whole fit to show what it gains
            rounds = TRIAL_ROUNDS if ops in local and ops not in whole else LEVEL_ROUNDS
            if out_of_time() or b.n_faces > max_faces or not _fit.fits_in_time(b, rounds):
                continue
            try:
                # a local op's fit continues the converged one without the fairing rows, which hold the cage
                # where it is (an edge loop on a blob's converged 26-vertex cage: 2.0e-3 of the diagonal after
                # three faired rounds, 1.2e-3 without them, 1.4e-3 before the loop)
                v, c = _fit(b, rounds, fairing=0.0 if ops in local else None)
                if ops not in local and not c < cost and _fit.fits_in_time(b, rounds):
                    # a split of a converged cage: the fairing rows pull it off its fit and every round is
                    # undone (bone, 834 control vertices: 1.2e-4 -> 1.2e-4 faired, 4.2e-5 without them)
                    v, c = _fit(b, rounds, fairing=0.0)
            except GsrError:
                continue
            if not math.isfinite(c) or (c >= cost and rounds == LEVEL_ROUNDS):
                continue  # a split fitted in full that does not gain
            gain = math.log(cost / c) / (math.log(b.n_vertices / mesh.n_vertices) + LEVEL_COST) if c > 0 else math.inf
            # those not gaining yet after their trial rounds last, closest first
            scored.append((c >= cost, -gain if c < cost else c, len(scored), ops, a, b, v, c))
        chosen = None
        # the best gain per added vertex first; the next if its full fit gains too little or cannot replay. When
        # no trial gains, the closest get their full fit all the same: a coarse cage fitted to convergence is
        # ahead of any proposal's first rounds (airplane's bevelled cube, 10 vertices at 2.3e-2 of the
        # diagonal: every op's three rounds were behind it, and the refinement stopped there)
        ranked = sorted(scored, key=lambda t: t[:3])
        for *_, ops, a, b, v, c in ranked[:LEVEL_TRIES]:
            if out_of_time():
                break
            if ops in local and ops not in whole and _fit.fits_in_time(b, LEVEL_ROUNDS):  # else the full fit stands
                v, c = _fit(b.with_vertices(v), LEVEL_ROUNDS, fairing=0.0)
            if c < MIN_GAIN * cost:  # the level's fins and webs snapped before its residual aims the next ops
                v, c, via = snapped(problem, _fit, out_of_time, b.with_vertices(v), c, LEVEL_SNAPS, LEVEL_ROUNDS)
                chosen = _fit.timed("commit", b, lambda: _commit(problem, base, base_state, full, ops, a,
                                                                 b.with_vertices(v), c, cost, _fit.late(b), via,
                                                                 soft[0] if soft and apply_ops(ops, mesh) is None
                                                                 else None))
                if chosen is not None:
                    break
        if chosen is None:
            chosen = _fallback(problem, _fit, out_of_time, mesh, cost, base, base_state, full, res, max_faces)
            kind = "loops at once"
        else:
            kind = kinds.get(chosen[0], "loops at once")
        if chosen is None:
            break
        if len(chosen[3]) > MAX_OPS:  # a history no result may hold (moves staged past merging): the last level stands
            break
        ops, base, base_state, full, mesh, cost = chosen
        # a level likely the last (no time for another after its finish) is finished with free corners
        done = _finish(problem, _fit, out_of_time, mesh, cost, base, base_state, full,
                       convex=_fit.has_room(mesh, LAST_ROUNDS))
        if done is not None:
            base, base_state, full, mesh, cost = done
        # a level of several ops can be a local minimum that a prefix of them beats: the prefix nearest the middle
        # of its growth is fitted too, and the closer is the level (airplane, its placed cube refined with no time
        # limit: the 26 -> 98-vertex split fitted 7.8e-3 of the diagonal, its 56-vertex prefix 6.7e-3; on from the
        # prefix, 102 vertices 3.5e-3 where the path from the split had 5.4e-3, and 164 2.7e-3 where it had 166 at
        # 3.1e-3)
        mid = _middle(problem, _fit, out_of_time, stages[-1], ops, mesh, soft[0] if soft else None)
        if mid is not None:
            middles.add(mid[4].n_vertices)
        if mid is not None and record is not None:
            record(mid[4], mid[5], mid[3])
        if mid is not None and mid[5] < cost:
            if record is not None:
                record(mesh, cost, full)
            ops, base, base_state, full, mesh, cost = mid
            kind = "middle prefix"
        levels.append(Level(ops, mesh, cost, time.perf_counter() - started, kind))
        stages.append((base, base_state, full, mesh, cost))
        if record is not None:
            record(mesh, cost, full)
    finished = _finish(problem, _fit, out_of_time, mesh, cost, base, base_state, full, convex=False)
    if finished is not None:
        base, base_state, full, mesh, cost = finished
        levels.append(Level((), mesh, cost, time.perf_counter() - started, "finish"))
        if record is not None:
            record(mesh, cost, full)
    if record is not None:
        # the earlier levels' cages, smallest first, converged too in the time left: each is a point of the
        # front, and a user picking a simpler cage gets its structure's best fit, not a stage on the way;
        # their fits keep the final cage's tail free
        last = mesh.n_vertices
        front_fit = _Fitter(problem, deadline, None if tail is None else lambda n: FRONT_TAIL * tail(max(n, last)),
                            should_stop, free_corners)
        front_fit.timing = _fit.timing
        for stage in stages[:-1]:
            if out_of_time():
                break
            done = _finish(problem, front_fit, out_of_time, stage[3], stage[4], *stage[:3], convex=False)
            if done is not None:
                record(done[3], done[4], done[2])

        def fill(evaluations: int) -> None:
            until = problem.evaluations + evaluations
            _fill_front(problem, front_fit, lambda: out_of_time() or problem.evaluations >= until, stages, levels,
                        record, middles)

        if deferred is None:
            fill(int(problem.config.refine_fill * (problem.evaluations - work)))
        else:
            deferred.append((levels, fill))
    return full, levels


def fill_counts(sizes: list[int], low: int, high: int, step: float = FILL_STEP) -> list[int]:
    """Which prefixes of a level's ops fill the front's gap between ``low`` and ``high`` control vertices:
    indices into ``sizes`` (the cage's vertices after each prefix, growing), each at least ``step`` times the
    last point kept (``low`` first) and at most ``high / step``."""
    out, last = [], low
    for k, n in enumerate(sizes):
        if n >= step * last and n * step <= high:
            out.append(k)
            last = n
    return out


def _prefix_sizes(ops: tuple, mesh: PolyMesh, soft: PolyMesh | None = None) -> list[int]:
    """The control vertices after each op of ``ops`` on ``mesh``, or on the first of its smoother cages
    (``soft``, then :func:`limit_cage`'s) where they all apply (a converged cage's skewed quads fold under a loop);
    empty when they apply on none."""
    states = [mesh] + ([] if soft is None else [soft])
    for k in range(SMOOTHINGS + len(states)):
        state = states[k] if k < len(states) else limit_cage(mesh if k == len(states) else state)
        sizes, built = [], state
        for op in ops:
            built = apply_ops((op,), built)
            if built is None:
                break
            sizes.append(built.n_vertices)
        else:
            return sizes
    return []


def _fill_front(problem, _fit, out_of_time, stages: list[tuple], levels: list[Level],
                record: Callable[[PolyMesh, float, tuple], None],
                skip: set[int] | frozenset[int] = frozenset()) -> None:
    """Points of the front between levels that grew the cage by several ops at once (a split, a balanced split,
    a batch of insets): a prefix of the level's ops, fitted, committed and finished as a level, in the time left
    (the smallest gaps first). A user picking a simpler cage (``--max-distance``) then gets a cage of about that
    size fitted in full, where the front held only the search's cages (bone: 30 and 114 control vertices from the
    refinement, the search's 66 at 8.5e-3 of the diagonal).

    Each prefix is fitted from two starts, the closer kept: the previous level's converged cage with the ops
    applied, and the level's own converged cage without its later ops (the ops only append vertices, so the
    prefix's vertices are the first ones of the level's cage). The second is ahead where the previous level's
    fit is a local minimum that the prefix's loops do not leave (bone, 30 -> 114 vertices by seven loops, their
    prefixes fitted both ways: 54 vertices 1.05e-2 and 7.6e-3 of the diagonal, 90 vertices 8.2e-3 and 3.8e-3;
    each next larger filled cage as the start instead did no better). Prefixes of ``skip``'s sizes (control
    vertices) were fitted by the refinement already (:func:`_middle`)."""
    for stage, level in zip(stages, levels[1:]):
        mesh = stage[3]
        ops = level.ops
        if len(ops) < 2 or level.control.n_vertices < FILL_STEP ** 2 * mesh.n_vertices:
            continue
        sizes = _prefix_sizes(ops[:-1], mesh)
        for k in fill_counts(sizes, mesh.n_vertices, level.control.n_vertices):
            if sizes[k] in skip:  # fitted by the refinement already (:func:`_middle`)
                continue
            if out_of_time():
                return
            done = _prefix_level(problem, _fit, out_of_time, stage, ops[:k + 1], level.control, convex=False)
            if done is not None:
                record(done[4], done[5], done[3])


def _middle(problem, _fit, out_of_time, stage: tuple, ops: tuple, control: PolyMesh,
            soft: tuple | None = None) -> tuple | None:
    """The prefix of a level's several ops (``ops``, built on ``stage``'s cage, converged at ``control``) nearest the
    geometric middle of the level's growth, as :func:`_prefix_level` makes it; None for a level of one op or little
    growth. ``soft``: the stage's :func:`softened` cage, as :func:`_commit` takes it, when it was made."""
    low, high = stage[3].n_vertices, control.n_vertices
    if len(ops) < 2 or high < FILL_STEP ** 2 * low:
        return None
    sizes = _prefix_sizes(ops[:-1], stage[3], None if soft is None else soft[2])
    ks = [k for k, n in enumerate(sizes) if FILL_STEP * low <= n <= high / FILL_STEP]
    if not ks:
        return None
    k = min(ks, key=lambda k: abs(math.log(sizes[k] / math.sqrt(low * high))))
    return _prefix_level(problem, _fit, out_of_time, stage, ops[:k + 1], control, soft=soft)


def _prefix_level(problem, _fit, out_of_time, stage: tuple, part: tuple, control: PolyMesh,
                  convex: bool = True, soft: tuple | None = None) -> tuple | None:
    """The cage ``part`` (a prefix of a level's ops) builds from the level before it (``stage``: its
    ``(base, base_state, genome, cage, distance)``), fitted from two starts (:func:`_fill_front`; ``control``: the
    level's own converged cage), snapped, committed and finished as a level: ``(ops, base, base_state, genome,
    cage, distance)``, or None when it does not gain on the level before or cannot replay. ``convex`` False (a
    front point only, no level): finished with free corners (:func:`_finish`). Ops that fold a face on the
    stage's cage are placed on its softened cage (``soft``, made here when not given: :func:`softened`)."""
    base, base_state, full, mesh, cost = stage
    b = apply_ops(part, mesh)
    if b is None:
        if soft is None or soft[0] != full:
            soft = (full, *softened(problem, full))
        b = carried(part, mesh, soft[2])
    else:
        soft = None
    if b is None or not _fit.fits_in_time(b, 2 * LEVEL_ROUNDS):
        return None
    tries = []
    for start in (b, b.with_vertices(control.vertices[:b.n_vertices])):
        try:
            tries.append(_fit(start, LEVEL_ROUNDS, fairing=0.0))
        except GsrError:
            continue
    if not tries:
        return None
    v, c = min(tries, key=lambda t: t[1])
    if not c < MIN_GAIN * cost:
        return None
    chosen = _snapped_level(problem, _fit, out_of_time, base, base_state, full, part, b.with_vertices(v), c, cost,
                            soft)
    if chosen is None or len(chosen[3]) > MAX_OPS:
        return None
    done = _finish(problem, _fit, out_of_time, chosen[4], chosen[5], *chosen[1:4], convex=convex)
    return chosen if done is None else (part, *done)


def _finish(problem, _fit, out_of_time, mesh: PolyMesh, cost: float, base: tuple, base_state: PolyMesh,
            full: tuple, convex: bool = True) -> tuple | None:
    """A level's cage fitted on to convergence (up to ``FINISH_ROUNDS`` more rounds while they gain, in the
    time left), no new structure: ``(base, base_state, genome, cage, distance)``, or None when that gains
    less than ``MIN_GAIN`` (bone's 426-vertex cage: 1.6e-3 of the diagonal after its level's rounds, 4.5e-4
    after 60 more). The rounds with the fairing
    rows stop where those outweigh the residual; 30 rounds without them go on (642 vertices: 6.7e-4 -> 5.9e-4
    both ways, where the faired fit could not gain a round).

    ``convex`` False (a cage no op will grow from: the last level, the front's cages): the fit lets corners turn
    concave, where a cage that ops will be applied to keeps them convex. Converged convex cages gain about 7 %
    (example007, 386 control vertices: 7.8e-3 -> 7.3e-3 of the diagonal; airplane, 181: 1.70e-3 -> 1.58e-3);
    free corners at every level lose more than that later (airplane's chain stopped at 110 vertices, 6.0e-3)."""
    if FINISH_ROUNDS <= 0 or out_of_time() or not _fit.fits_in_time(mesh, FINISH_ROUNDS):
        return None
    try:  # faired while that gains, then without the fairing rows, which stall a converged fit
        v, c = _fit(mesh, FINISH_ROUNDS, convex=convex)
        if not out_of_time():
            v2, c2 = _fit(mesh.with_vertices(v), FINISH_ROUNDS // 2, fairing=0.0, convex=convex)
            if c2 < c:
                v, c = v2, c2
        v, c, via = snapped(problem, _fit, out_of_time, mesh.with_vertices(v), c, convex=convex)
    except GsrError:
        return None
    if not c < MIN_GAIN * cost:
        return None
    a = base_state if base_state.topology_key == mesh.topology_key else None
    chosen = _fit.timed("commit", mesh, lambda: _commit(problem, base, base_state, full, (), a,
                                                        mesh.with_vertices(v), c, cost, _fit.late(mesh), via))
    if chosen is None or len(chosen[3]) > MAX_OPS:
        return None
    return chosen[1:]


def snapped(problem, _fit, out_of_time, mesh: PolyMesh, cost: float, passes: int = SNAP_PASSES,
            rounds: int = SNAP_ROUNDS, convex: bool = True) -> tuple[np.ndarray, float, tuple[np.ndarray, ...]]:
    """``mesh`` (fitted, at ``cost``) after up to ``passes`` passes of its snap (the
    control vertices whose limit points lie over ``SNAP_FACTOR`` times ``cost`` from the target) each followed
    by ``rounds`` rounds of the fit without fairing, while they gain: its vertices, cost and the positions on
    the way (``mesh``'s, then each pass's snapped and fitted ones before the last: the moves of a history
    replay through them where the straight path to the end folds a face, :meth:`SurfaceProblem._moves`)
    (:func:`~gsr_cad.reconstruct.snap.snap_far_vertices`). Fins and webs
    are local minima of the fit that this steps out of (bone, 162 control vertices: 2.0e-3 -> 9.3e-4 of the
    diagonal both ways in three passes)."""
    v = mesh.vertices
    via: list[np.ndarray] = []
    for _ in range(passes):
        if out_of_time() or not _fit.fits_in_time(mesh, rounds):
            break
        moved, count = problem.snap(mesh.with_vertices(v), SNAP_FACTOR * cost * problem.diag)
        if not count:
            break
        v2, c2 = _fit(moved, rounds, fairing=0.0, convex=convex)
        if not c2 < cost:
            break
        via += [v, moved.vertices]
        v, cost = v2, c2
    return v, cost, tuple(via)


def snapped_within(problem, mesh: PolyMesh, cost: float, deadline: float | None,
                   should_stop: Callable[[], bool] | None = None) -> tuple[np.ndarray, float, tuple]:
    """:func:`snapped` for a cage fitted outside the refinement (the search's front cages), no fit round
    ending after ``deadline``."""
    return snapped(problem, _Fitter(problem, deadline, None, should_stop), _stop_when(deadline, should_stop), mesh,
                   cost)


def _commit(problem, base: tuple, base_state: PolyMesh, full: tuple, ops: tuple, a: PolyMesh | None,
            fitted: PolyMesh, c: float, cost: float, deadline: float | None = None,
            via: tuple[np.ndarray, ...] = (), soft: tuple | None = None) -> tuple | None:
    """A level from the fitted cage of ``ops``: ``(ops, the new base, its state, the level's genome, the cage it
    replays to, its distance)``. The ops replay on the base's geometry (``a``, when they apply there) or
    after the last level's moves (:func:`_after`); the fitted positions are reached by moves. Where some
    moves refuse on both, the cage the others reach (the path with fewer refusals first) is fitted again
    from there and moved to, up to ``REACH_REFITS`` times, and stands if it still gains (below ``MIN_GAIN``
    of ``cost``); else None. ``via``: positions the moves may pass through (:meth:`SurfaceProblem._moves`).
    (Only the second path used to be refitted: bone's first split, 418 control vertices, reached 5.9e-3 of
    the diagonal from 1.1e-2 on the first path with 60 refusals, found no place to follow the previous
    moves, and was dropped.)

    ``soft``: :func:`_after`'s, given for ops that fold a face on the last level's cage and were placed on its
    softened cage (:func:`softened`); the path after the last level's moves is then tried first, and the base's
    geometry only where the ops do not apply there either (example007, a budget split of its 546-vertex cage
    to 1,584: the moves from the template's geometry took 70 s and 1,254 vertices did not get there)."""
    partial: list[tuple] = []
    for path in ((1, 0) if soft is not None else (0, 1)):
        if path == 0 and a is not None:
            new_base, new_state = base + ops, a
        elif path == 1:
            prefix, new_state = _after(problem, full, ops, deadline, soft)
            if new_state is None:
                continue
            new_base = prefix + ops
        else:
            continue
        step, reached, left = _reach_partial(problem, new_base, new_state, fitted.vertices, deadline, via)
        if not left:
            return ops, new_base, new_state, step, fitted, c
        partial.append((left, path, new_base, new_state, step, reached))
        if soft is not None:
            break
    for _, _, new_base, new_state, step, reached in sorted(partial, key=lambda t: t[:2]):
        level = _refit_reached(problem, step, reached, cost, deadline, c)
        if level is not None:
            return (ops, new_base, new_state, *level)
        if deadline is not None and time.perf_counter() >= deadline:
            break
    return None


def _refit_reached(problem, step: tuple, reached: PolyMesh, cost: float, deadline: float | None,
                   fitted: float = 0.0) -> tuple[tuple, PolyMesh, float] | None:
    """``(genome, cage, distance)`` from a level's partly replayed moves (``step`` builds the sound cage
    ``reached``): while moves refuse and the reached cage is over ``REACH_SLACK`` times the fitted cage's
    distance ``fitted`` (or does not gain), it is fitted again from there and moved to (at most ``REACH_REFITS``
    times); the best reached cage, if it gains (below ``MIN_GAIN`` of ``cost``), else None. (Stopping at
    the first reached cage that gained threw away most of a snapped fit: bone, 378 control vertices, fitted
    to 4.4e-4 of the diagonal, 18 moves refused, committed at 8.0e-4.)"""
    best = None
    left = 1
    for attempt in range(REACH_REFITS + 1):
        try:
            c = problem.fit(reached, 0)[1]
        except GsrError:
            break
        if best is None or c < best[2]:
            best = (step, reached, c)
        if (not left or attempt == REACH_REFITS or (c < MIN_GAIN * cost and c <= REACH_SLACK * fitted)
                or (deadline is not None and time.perf_counter() >= deadline)):
            break
        # the cage the moves did reach is sound: fitted again from there, its positions mostly replay
        try:
            v, _ = problem.fit(reached, LEVEL_ROUNDS, min_gain=1.0, adaptive=True, stiffness=STIFFNESS,
                               deadline=deadline, fairing=0.0, settle=True)
        except GsrError:
            break
        step, reached, left = _reach_partial(problem, step, reached, v, deadline)
    return best if best is not None and best[2] < MIN_GAIN * cost else None


def _fallback(problem, _fit, out_of_time, mesh: PolyMesh, cost: float, base: tuple, base_state: PolyMesh,
              full: tuple, res: Residual, max_faces: int) -> tuple | None:
    """When no single proposal gains: every edge ring the residual picks at once (a coarse-to-fine jump where
    the residual is spread), then those of the whole cage (each added where it applies), each fitted in full.
    A level as :func:`_commit` makes it, or None."""
    rings = edge_rings(mesh)
    if not rings:
        return None
    total = np.array([res.total[faces].sum() for _, faces in rings])
    order = [int(i) for i in np.argsort(-total)]
    for count in dict.fromkeys((max(2, len(order) // 2), len(order))):
        if out_of_time():
            return None
        ops, b = (), mesh
        for i in order[:count]:
            # a loop splits only its own ring's edges: the others keep their ends, found by them
            u, w = mesh_view(mesh).conn.edges[rings[i][0]]
            index = {frozenset(e): k for k, e in enumerate(mesh_view(b).conn.edges)}
            e = index.get(frozenset((u, w)))
            if e is None:
                continue
            try:
                grown = EdgeLoop(e).apply(b)
            except OpError:
                continue
            if grown.n_faces > max_faces:
                break
            ops, b = ops + (EdgeLoop(e),), grown
        if not ops or not _fit.fits_in_time(b, LEVEL_ROUNDS):
            continue
        try:
            v, c = _fit(b, LEVEL_ROUNDS, fairing=0.0)
        except GsrError:
            continue
        if not c < MIN_GAIN * cost:
            continue
        chosen = _snapped_level(problem, _fit, out_of_time, base, base_state, full, ops, b.with_vertices(v), c, cost)
        if chosen is not None:
            return chosen
    return None


def _snapped_level(problem, _fit, out_of_time, base: tuple, base_state: PolyMesh, full: tuple, ops: tuple,
                   fitted: PolyMesh, c: float, cost: float, soft: tuple | None = None) -> tuple | None:
    """The cage ``ops`` build from the last level, fitted (``fitted``, at ``c``), snapped (:data:`LEVEL_SNAPS`
    passes) and committed as a level (:func:`_commit`, with ``soft``; the ops replay on ``base_state`` where they
    apply)."""
    v, c, via = snapped(problem, _fit, out_of_time, fitted, c, LEVEL_SNAPS, LEVEL_ROUNDS)
    a = apply_ops(ops, base_state)
    a = a if a is not None and a.topology_key == fitted.topology_key else None
    return _fit.timed("commit", fitted, lambda: _commit(problem, base, base_state, full, ops, a,
                                                        fitted.with_vertices(v), c, cost, _fit.late(fitted), via,
                                                        soft))


def limit_cage(mesh: PolyMesh) -> PolyMesh:
    """``mesh`` with each control vertex moved to its own point on the limit surface: a smoother cage,
    near the fitted one, on which the structural ops apply where the fitted cage's quads are too skewed."""
    cc = get_catmull_clark(mesh, 1, "all")
    return mesh.with_vertices(cc.limit_matrix[:mesh.n_vertices] @ mesh.vertices)


def apply_ops(ops: tuple, state: PolyMesh) -> PolyMesh | None:
    """``state`` after ``ops`` in turn, or None when one refuses."""
    try:
        for op in ops:
            state = op.apply(state)
    except OpError:
        return None
    return state


def softened(problem, genome: tuple) -> tuple[tuple, PolyMesh]:
    """The cage ``genome`` builds moved towards its limit cage (:func:`limit_cage`) as far as the moves replay: the
    moves and the cage they reach. Unlike the limit cage, every face of it is one the ops accept, and it is where
    :func:`_after` places ops first, so ops cut on it (a budget split, :func:`carried`) can be committed (example007,
    546 control vertices: 31 faces of the limit cage fail the ops' checks, the moves towards it stop at 26
    vertices, and a budget split cut on the limit cage folded a face on every cage a history could reach)."""
    state = problem.control_mesh(genome)
    moves, reached, _ = problem._moves(state, limit_cage(state).vertices)
    return moves, reached


def _after(problem, genome: tuple, ops: tuple, deadline: float | None = None,
           soft: tuple[tuple, tuple, PolyMesh] | None = None) -> tuple[tuple, PolyMesh | None]:
    """Where ``ops`` can follow ``genome``: ``(genome, or genome plus moves towards a smoother cage, the state
    the ops then build)``; None for the state when they apply at none. The smoother cages are the limit cage
    (:func:`limit_cage`) and its own limit cages, up to ``SMOOTHINGS`` deep, each reached by the moves that
    replay: a converged cage's quads are skewed enough that an edge loop folds a face on it and on its first
    limit cage (LetterBlock, 162 control vertices: the split to 642 gained 1.06e-2 -> 6.3e-3 of the diagonal,
    could not be committed and the refinement lost it). No staged move starts after ``deadline``. ``soft``:
    ``(genome, its moves, the cage they reach)`` of :func:`softened`, tried first."""
    state = problem.control_mesh(genome)
    built = apply_ops(ops, state)
    if built is not None:
        return genome, built
    if soft is not None and soft[0] == genome:
        built = apply_ops(ops, soft[2])
        if built is not None:
            return genome + soft[1], built
    smooth = state
    for _ in range(SMOOTHINGS):
        smooth = limit_cage(smooth)
        moves, reached, _ = problem._moves(state, smooth.vertices, deadline)
        built = apply_ops(ops, reached)
        if built is not None:
            return genome + moves, built
    return genome, None


def _reach_partial(problem, base: tuple, state: PolyMesh, vertices: np.ndarray,
                   deadline: float | None = None, via: tuple[np.ndarray, ...] = ()) -> tuple[tuple, PolyMesh, int]:
    """``base`` (which builds ``state``) followed by the moves towards ``vertices`` that replay
    (:meth:`SurfaceProblem._moves`), the cage they reach and how many vertices did not get there (no staged
    attempt of the moves starting after ``deadline``)."""
    moves, reached, refused = problem._moves(state, vertices, deadline, via)
    return base + moves, reached, refused


def _reach(problem, base: tuple, state: PolyMesh, vertices: np.ndarray,
           via: tuple[np.ndarray, ...] = ()) -> tuple | None:
    """``base`` (which builds ``state``) followed by the moves to ``vertices`` (:meth:`SurfaceProblem._moves`), or None
    when some move cannot replay."""
    moves, _, refused = problem._moves(state, vertices, None, via)
    return None if refused else base + moves
