"""Curve reconstruction: ordered 2D or 3D points -> control polygon + the op history that builds it.

The GA (paper, section 3) evolves genomes of ``add_point``/``move_point``/``corner`` ops on a 4-point
template. Two evaluations are offered:

* ``preset="paper"``: the paper exactly - open curves, the genome's own positions, fitness = sum of
  index-wise distances between the target and as many evenly spaced curve samples.
* ``preset="default"`` (Lamarckian): the data are checked first (unordered points are put in
  nearest-neighbour order with a warning, or refused; a closed outline is detected and becomes a periodic
  B-spline; sharp turns become corner candidates; long inputs are subsampled for the search). A genome's
  structure - its number of points ``n`` and its corners, each matched to the nearest candidate - is scored
  after the least-squares placement of its control points, segment by segment between corners (see
  :mod:`gsr_cad.reconstruct.curve_model`), with errors measured both ways (data -> curve and curve -> data).
  The cost ``exp(2 (n + 2 corners) ln m / m) * max(rms / diag, tolerance, excursion)^2`` is the exponential
  of a BIC per sample (a corner frees two continuity conditions): exact data get their exact count back and
  noisy data are not over-fitted, nor given corners by their noise. With ``max_distance`` X
  the floor is X and structures missing X (both ways) are penalised, so the count is the fewest that meets
  X. The memetic step searches corner sets and counts around the best genome; the winner's placement is
  written back into its history (insertions at their final positions, ``move_point`` ops for the template's
  points, then ``corner`` ops), so the saved genome replays exactly to the result. With X the final curve is
  checked on all points, both ways; segments that miss get more control points where the residual is (refitted
  on all their points when the search saw a subsample, or on the data's model when the points alone are too
  coarse), and a segment that still misses is cut in two where it misses most (a C0 joint: the paper's
  segmentation, so each part gets its own knot spacing); a remaining miss is reported in
  ``metrics["tolerance_met"]``. Without X, a noisy open curve without corners gets the count its sampling
  supports (:meth:`~gsr_cad.reconstruct.curve_model.CurveModel.sampling`: an index-wise model with a smooth
  warp, chosen by BIC and kept only when an F test against free foot points does not reject it; the outcome
  is ``metrics["sampling"]``) and end points fitted like the others (the result's template starts and ends
  there).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from .. import genome as genome_mod
from ..errors import ConfigError, OpError
from ..ga import GAConfig, GenerationReport, RunResult, fingerprint, start_or_resume
from ..geometry import bspline
from ..geometry.curveprep import corner_candidates, detect_closed, is_unordered, nearest_neighbour_order, subsample
from ..geometry.distance import chord_length_params, foot_points, index_wise, two_sided
from ..ops import curve as curve_ops
from .config import CurveConfig
from .curve_model import CurveModel, SamplingChoice
from .inputs import CurveTarget, curve_target
from .result import Result


def _common_prefix(a: tuple, b: tuple) -> int:
    """Length of the common prefix of two tuples (slice comparisons: identical items compare in C)."""
    n = min(len(a), len(b))
    if a[:n] == b[:n]:
        return n
    lo, hi = 0, n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if a[:mid] == b[:mid]:
            lo = mid
        else:
            hi = mid
    return lo


class CurveWarning(UserWarning):
    """Something about the curve data the user should know (reordered points, a missed tolerance)."""


@dataclasses.dataclass(frozen=True)
class PreparedCurve:
    """The data as the search sees them: ordered points (closing duplicate dropped), closure, corner
    candidates and the subsample searched (both as indices into ``points``)."""

    points: np.ndarray
    closed: bool
    reordered: bool
    candidates: np.ndarray
    search: np.ndarray
    angles: np.ndarray


def prepare_curve(points: np.ndarray, config: CurveConfig) -> PreparedCurve:
    """Order, closure, corner candidates and search subsample of curve data (warns when it reorders)."""
    pts = np.asarray(points, dtype=np.float64)
    reordered = False
    if is_unordered(pts):
        pts = pts[nearest_neighbour_order(pts)]
        reordered = True
        warnings.warn("the points are not in curve order; they were put in nearest-neighbour order",
                      CurveWarning, stacklevel=3)
    closed = detect_closed(pts) if config.closure == "auto" else config.closure == "closed"
    diag = float(np.linalg.norm(np.ptp(pts, axis=0)))
    if closed and len(pts) > 4 and np.linalg.norm(pts[-1] - pts[0]) <= 1e-9 * diag:
        pts = pts[:-1]
    use_corners = config.find_corners and config.polish
    cand, angles = (corner_candidates(pts, closed, config.corner_angle, with_angles=True) if use_corners
                    else (np.zeros(0, dtype=np.int64), np.zeros(0)))
    limit = config.search_points if config.polish else 0
    search = subsample(pts, limit, cand, closed) if limit else np.arange(len(pts))
    return PreparedCurve(pts, closed, reordered, cand, search, angles)


class CurveProblem:
    """The GA problem for one target: random ops, repair, and the cost of a genome."""

    def __init__(self, target: CurveTarget, config: CurveConfig):
        self.target = target
        self.config = config
        self.prepared = prepare_curve(target.points, config)
        prep = self.prepared
        self.closed = prep.closed
        self.points = prep.points[prep.search]
        self.m = len(self.points)
        self.diag = target.diagonal
        self.degree = 2 if config.scheme == "chaikin" else 3
        self.template = curve_ops.template(self.points, margin=config.bounds_margin, closed=self.closed,
                                           degree=self.degree)
        self.lo = np.asarray(self.template.lo, dtype=np.float64)
        self.hi = np.asarray(self.template.hi, dtype=np.float64)
        self.max_ctrl = config.max_control_points or max(4, self.m)
        self._chord = chord_length_params(self.points)
        self._trie: dict = {}
        self._trie_size = 0
        self._path_ops: tuple = ()
        self._path: list = [(self.template, self._trie)]
        subsampled = len(self.points) < len(prep.points)
        # The search samples the curve more coarsely than the final check: a margin (segments a subsampled
        # search gets wrong are refitted on all their points by the final check).
        limit = config.max_distance * 0.97 if config.max_distance else None
        cand = np.searchsorted(prep.search, prep.candidates)
        self.model = CurveModel(self.points, self.closed, cand, config, self.degree, self.diag, limit,
                                self.lo, self.hi, sharp=cand[prep.angles >= 2.0 * config.corner_angle],
                                full=prep.points if subsampled else None, search=prep.search)
        self.limit = limit
        self._sites = self.points[cand] if cand.size else np.zeros((0, self.points.shape[1]))
        self._site_tree = cKDTree(self._sites) if cand.size else None
        self._best_structures: dict[tuple[int, ...], tuple[float, int]] = {}
        self.sampling: SamplingChoice | None = None  # the noisy open curve's sampling test (see final)

    # --- GA protocol -------------------------------------------------------------------------------
    def _state(self, prefix: tuple) -> curve_ops.Polygon:
        """The polygon after ``prefix`` with invalid ops skipped (repair semantics), cached in a trie of ops.

        Genomes grow and are rebuilt gene by gene, so each state is one op applied to a cached parent; the
        trie makes a look-up linear in the genome's length (long histories of real curves have hundreds of ops).
        """
        return self._walk(prefix)[0]

    def _walk(self, ops: tuple, keep: list | None = None) -> tuple[curve_ops.Polygon, dict]:
        """Walk ``ops`` through the trie (applying each new op once); ``keep`` collects the valid ones (an add
        beyond :attr:`max_ctrl` counts as invalid there).

        The last walk's path is kept: a walk resumes where it leaves the previous one, so the growing prefixes
        of a mutation (``random_gene`` per mutated gene) cost the new ops only, not the whole genome each time.
        """
        start = _common_prefix(ops, self._path_ops)
        path = self._path
        del path[start + 1:]
        state, children = path[start]
        for op in ops[start:]:
            entry = self._child(state, children, op)
            path.append(entry)
            state, children = entry
        self._path_ops = ops
        if keep is not None:
            kept, prev, capped = [], self.template, False
            for op, (nxt, _) in zip(ops, path[1:]):
                if isinstance(op, curve_ops.AddPoint) and nxt is not prev and prev.n >= self.max_ctrl:
                    capped = True
                    break
                if nxt is not prev:
                    kept.append(op)
                prev = nxt
            if capped:  # a dropped add changes every later state: the plain walk, op by op
                return self._capped_walk(ops, keep)
            keep.extend(kept)
        if self._trie_size >= 200_000:
            self._reset_trie()
        return state, children

    def _child(self, state: curve_ops.Polygon, children: dict, op) -> tuple[curve_ops.Polygon, dict]:
        """The trie entry of ``op`` applied to ``state`` (whose children are ``children``), made on first use;
        an invalid op leaves the state as it is."""
        entry = children.get(op)
        if entry is None:
            try:
                nxt = op.apply(state)
            except OpError:
                nxt = state
            entry = children[op] = (nxt, {})
            self._trie_size += 1
        return entry

    def _capped_walk(self, ops: tuple, keep: list) -> tuple[curve_ops.Polygon, dict]:
        """:meth:`_walk` with ``keep`` when some add would exceed :attr:`max_ctrl` (that add is skipped)."""
        state, children = self.template, self._trie
        for op in ops:
            entry = self._child(state, children, op)
            nxt = entry[0]
            if nxt is state or (isinstance(op, curve_ops.AddPoint) and state.n >= self.max_ctrl):
                continue
            keep.append(op)
            state, children = entry
        self._path_ops, self._path = (), [(self.template, self._trie)]
        if self._trie_size >= 200_000:
            self._reset_trie()
        return state, children

    def _reset_trie(self) -> None:
        self._trie, self._trie_size = {}, 0
        self._path_ops, self._path = (), [(self.template, self._trie)]

    def random_gene(self, rng: np.random.Generator, prefix: tuple) -> genome_mod.Op:
        poly = self._state(prefix)
        p_add = self.config.p_add if poly.n < self.max_ctrl else 0.0
        p_corner = 0.02 if len(self._sites) else 0.0
        return curve_ops.random_op(rng, poly, p_add=p_add, move_scale=self.config.move_scale,
                                   local_add=self.config.local_add, corner_sites=self._sites, p_corner=p_corner)

    def repair(self, genome: tuple, rng: np.random.Generator) -> tuple:
        kept: list = []
        state = self._walk(tuple(genome), kept)[0]
        while len(kept) < self.config.min_ops:
            op = self.random_gene(rng, tuple(kept))
            try:
                state = op.apply(state)
            except OpError:
                continue
            kept.append(op)
        return tuple(kept)

    def structure(self, genome: tuple) -> tuple[tuple[int, ...], int]:
        """A genome's corner set (search indices of the candidates nearest its corner points) and point count."""
        poly = self._state(tuple(genome))
        if not poly.corners or self._site_tree is None:
            return (), poly.n
        _, near = self._site_tree.query(poly.points[list(poly.corners)])
        cand = self.model.candidates[np.unique(np.atleast_1d(near))]
        return tuple(int(c) for c in np.sort(cand)), poly.n

    def cost(self, genome: tuple) -> float:
        poly = self._state(tuple(genome))
        if self.config.polish:
            return self.structure_cost(*self.structure(genome))
        if self.config.fitness == "index":
            samples = bspline.sample_uniform(poly.points, self.m, self.degree)
            return float(index_wise(samples, self.points).sum())
        _, dist = foot_points(poly.points, self.points, self._chord, degree=self.degree)
        return float(dist.sum())

    def structure_cost(self, corners: tuple[int, ...], n: int) -> float:
        """The penalised error of the best placement of ``n`` control points with these corners."""
        counts = self.model.allocation(corners, n)
        if counts is None:  # too few points for this corner set (or the limit): graded by the shortfall
            low = self.model.minimum_total(corners)
            return 1e15 if low is None else 1e12 * (1.0 + abs(low - n))
        rms, both, excess = self.model.errors(corners, counts)
        if self.limit is None:  # a C0 corner frees two continuity conditions: two parameters more in the BIC
            grow = math.exp(2.0 * (n + 2 * len(corners)) * math.log(self.m) / self.m)
            return grow * max(rms, self.config.tolerance, excess) ** 2
        grow = math.exp(2.0 * n * math.log(self.m) / self.m)
        cost = grow * max(rms, self.config.tolerance, self.limit) ** 2 * (1.0 + 1e-3 * rms / self.limit)
        if both > self.limit:
            cost *= 1e6 * (both / self.limit) ** 2  # infeasible: worse, and graded by the miss
        return cost

    def local_search(self, genome: tuple) -> tuple:
        """Memetic step on the best genome (Lamarckian mode only): search corner sets and point counts.

        From the genome's corners and from every candidate, corners are dropped one at a time while that does
        not raise the cost, then candidates added while that lowers it; each corner set gets its best count
        (the fewest meeting the limit, or a walk of +1..+3 / -1..-2 points on the penalised error). Returns
        the genome of the best structure (a clean history at the current placement).
        """
        if not self.config.polish:
            return genome
        corners, n = self.structure(genome)
        pool = tuple(int(c) for c in self.model.candidates)
        walks = [self._corner_walk(self._valid(pool), n)]  # from every candidate, dropping those that do not pay
        own = self._valid(corners)
        if own != walks[0][1]:
            walks.append((*self._count_walk(own, n)[:1], own, self._count_walk(own, n)[1]))
        best = min(walks, key=lambda r: (r[0], len(r[1])))
        _, best_corners, best_n = best
        counts = self.model.allocation(best_corners, best_n)
        if counts is None:
            return genome
        ctrl, idx = self.model.assemble(best_corners, counts)
        built = self.history(ctrl, idx, self.template)
        try:
            genome_mod.replay(self.template, built)
        except OpError:
            return genome
        return built

    def seed_genomes(self) -> list[tuple]:
        """The structure search's result from every corner candidate, as a first-generation genome."""
        return [self.local_search(())] if self.config.polish else []

    def _valid(self, corners: tuple[int, ...]) -> tuple[int, ...]:
        """Drop repeated corners (and, on open curves, corners on the end points)."""
        kept: list[int] = []
        for c in sorted(corners):
            if (kept and c - kept[-1] < 1) or (not self.closed and (c < 1 or c > self.m - 2)):
                continue
            kept.append(c)
        if self.closed and len(kept) > 1 and kept[0] + self.m - kept[-1] < 1:
            kept.pop()
        return tuple(kept)

    def _count_walk(self, corners: tuple[int, ...], n: int) -> tuple[float, int]:
        """Best count for a corner set: the fewest meeting the limit, or a local walk on the cost."""
        if corners in self._best_structures:
            return self._best_structures[corners]
        low = self.model.minimum_total(corners)
        if low is None:
            out = (math.inf, n)
        elif self.limit is not None:
            out = (self.structure_cost(corners, low), low)
        else:
            best_n, best_cost = max(n, low), self.structure_cost(corners, max(n, low))
            for _ in range(100_000):
                for step in (1, 2, 3, -1, -2):
                    cand = best_n + step
                    if cand < low or cand > self.max_ctrl:
                        continue
                    if (c := self.structure_cost(corners, cand)) < best_cost:
                        best_n, best_cost = cand, c
                        break
                else:
                    break
            if best_n - low <= 40:  # the walk can climb past a lower minimum (the true count): scan below it
                for cand in range(low, best_n):
                    if (c := self.structure_cost(corners, cand)) < best_cost:
                        best_n, best_cost = cand, c
            out = (best_cost, best_n)
        self._best_structures[corners] = out
        return out

    def _corner_walk(self, corners: tuple[int, ...], n: int) -> tuple[float, tuple[int, ...], int]:
        corners = self._valid(corners)
        cost, best_n = self._count_walk(corners, n)
        if math.isfinite(cost):
            self._tighten(best_n)
        pool = self._valid(tuple(int(c) for c in self.model.candidates))
        for _ in range(4):
            changed = False
            for c in list(corners):  # drop corners that do not pay
                trial = tuple(x for x in corners if x != c)
                t_cost, t_n = self._count_walk(trial, best_n)
                if t_cost <= cost:
                    corners, cost, best_n, changed = trial, t_cost, t_n, True
                    self._tighten(best_n)
            for c in pool:  # add candidates that do
                if c in corners:
                    continue
                trial = self._valid(tuple(sorted(corners + (c,))))
                if c not in trial:
                    continue
                t_cost, t_n = self._count_walk(trial, best_n)
                if t_cost < cost:
                    corners, cost, best_n, changed = trial, t_cost, t_n, True
                    self._tighten(best_n)
            if not changed:
                break
        return cost, corners, best_n

    def _tighten(self, total: int) -> None:
        if self.limit is not None:
            self.model.upto = total if self.model.upto is None else min(self.model.upto, total)

    def perturb(self, gene: genome_mod.Op, rng: np.random.Generator) -> genome_mod.Op:
        return curve_ops.perturb_op(gene, rng, 0.02 * self.diag)

    # --- histories ---------------------------------------------------------------------------------
    def result_template(self, ctrl: np.ndarray) -> curve_ops.Polygon:
        """The template with its box grown (if needed) to hold every final control point; an open template's
        end points are the curve's (the data's first and last point, or their least-squares estimates on noisy
        data: ops never move the ends)."""
        t = self.template
        lo = np.minimum(self.lo, ctrl.min(axis=0))
        hi = np.maximum(self.hi, ctrl.max(axis=0))
        pts = np.array(t.points, dtype=np.float64)
        if not t.closed:
            pts[[0, -1]] = ctrl[[0, -1]]
        return curve_ops.Polygon(pts, tuple(lo.tolist()), tuple(hi.tolist()), t.closed, (), t.degree)

    def history(self, ctrl: np.ndarray, corners: tuple[int, ...], template: curve_ops.Polygon) -> tuple:
        """A clean op history that builds ``ctrl`` with ``corners`` from ``template``.

        Open: the points between the template's second and third are inserted at their positions, the two
        free template points moved onto theirs. Closed: the points after the first are inserted, then every
        template point is moved. Corners come last.
        """
        n, t = len(ctrl), template.points
        fl = curve_ops._floats
        if self.closed:
            adds = tuple(curve_ops.AddPoint(i, fl(ctrl[i])) for i in range(1, n - 3))
            pairs = [(0, 0), (n - 3, 1), (n - 2, 2), (n - 1, 3)]
        else:
            adds = tuple(curve_ops.AddPoint(i, fl(ctrl[i])) for i in range(2, n - 2))
            pairs = [(1, 1), (n - 2, 2)]
        moves = tuple(curve_ops.MovePoint(i, fl(ctrl[i] - t[j])) for i, j in pairs if np.any(ctrl[i] != t[j]))
        return adds + moves + tuple(curve_ops.Corner(c) for c in corners)

    def threshold(self) -> float | None:
        """Stop threshold in cost units: explicit, automatic (< 0: the paper's mean index distance
        of 1e-4 of the diagonal, summed), or none (0)."""
        t = self.config.threshold
        if t > 0:
            return t
        if t < 0 and not self.config.polish:
            return 1e-4 * self.diag * self.m
        return None

    # --- the winner --------------------------------------------------------------------------------
    def final(self, genome: tuple, hurry: bool = False
              ) -> tuple[np.ndarray, tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
        """Control points, their corners, and the structure (search corners, counts) of the winner.

        Without a limit the placement is refined to convergence. With one, the curve is checked on all points
        (both ways) and segments that miss get more control points (5 %, doubling each round), or, once at their
        most, are fitted to the data's model instead of the points; a segment that still misses (or that more
        points made worse) is cut in two where it misses most, so each part gets its own knot spacing (up to
        twelve rounds; the best round is kept). ``hurry``: the search's placement as it is (no refinement, no
        check)."""
        corners, n = self.structure(genome)
        counts = self.model.allocation(corners, n)
        if counts is None:  # the genome's count does not fit its corners: their fewest, else no corners
            self.model.upto = None
            low = self.model.minimum_total(corners)
            counts = self.model.allocation(corners, low) if low is not None else None
            if counts is None:
                corners = ()
                counts = self.model.allocation((), self.model.minimum_total(()))
        if self.config.max_distance is None or hurry:
            self.sampling = None if hurry or corners else self.model.sampling(self.model.segments(())[0], n)
            if self.sampling is not None:  # a noisy open curve: the count its sampling supports, free ends
                return self.sampling.fit.ctrl, (), corners, (self.sampling.count,)
            ctrl, idx = self.model.assemble(corners, counts, refine=not hurry)
            return ctrl, idx, corners, counts
        full = self.prepared.points
        tree = cKDTree(full)
        data_corners = self.prepared.candidates  # the data's model is the data's: sharp at every candidate
        limit = self.config.max_distance * self.diag
        keys = self.model.segments(corners)
        grown, best = dict(zip(keys, counts)), None
        last_err: dict = {}
        last_count: dict = {}
        frozen: set = set()
        for rnd in range(12):
            counts = tuple(grown[k] for k in keys)
            ctrl, idx = self.model.assemble(corners, counts)
            spline = bspline.make_spline(ctrl, self.degree, self.closed, idx)
            there, back, samples = two_sided(spline, full, self.closed, per_span=32, corners=data_corners,
                                             with_samples=True)
            worst = max(float(there.max()), float(back.max()))
            if best is None or worst < best[0]:  # growing can make an out-of-reach fit worse: keep the best
                best = (worst, ctrl, idx, corners, counts)
            bad = np.flatnonzero(there > limit)
            far = back > limit
            if not bad.size and not far.any():
                break
            where = np.concatenate([bad, tree.query(samples[far])[1]]).astype(np.int64)
            errors = np.concatenate([there[bad], back[far]])
            site = np.searchsorted(self.prepared.search, where).clip(0, self.m - 1)  # search index of each miss
            seg_err, seg_site = np.zeros(len(keys)), np.zeros(len(keys), dtype=np.int64)
            for owner in self._owners(keys):  # a miss at a joint counts for both segments that meet there
                for j in np.argsort(errors):  # ascending: each segment ends with its worst miss
                    o = owner[site[j]]
                    if errors[j] >= seg_err[o]:
                        seg_err[o], seg_site[o] = errors[j], site[j]
            changed, splits = False, {}
            for i in np.flatnonzero(seg_err > limit):
                key = keys[i]
                top = self.model.max_count(key)
                if key in frozen:
                    splits[key] = int(seg_site[i])
                    continue
                if seg_err[i] > last_err.get(key, 0.0) > 0.0:  # its growth made it worse (an overfit): back
                    grown[key] = last_count[key]
                    frozen.add(key)
                    splits[key] = int(seg_site[i])
                    changed = True
                    continue
                last_err[key], last_count[key] = seg_err[i], grown[key]
                if self.model.use_all(key):  # the search's subsample misses between its points: fit them all
                    self.model.bound(key, grown[key])
                    grown[key] = self.model.need(key, self.limit)
                    changed = True
                elif grown[key] < top:
                    grown[key] = min(top, grown[key] + max(1, grown[key] // 20) * min(2 ** rnd, 4))  # faster if it persists
                    changed = True
                elif self.model.densify(key):
                    grown[key] = self.model.need(key, self.limit)
                    changed = True
                else:
                    splits[key] = int(seg_site[i])
            split = self._split(corners, splits)
            if split != corners:  # uniform knots cannot follow this segment: cut it where it misses most
                corners, keys, changed = split, self.model.segments(split), True
                for key in keys:
                    if key not in grown:
                        grown[key] = self.model.need(key, self.limit)
            if not changed:
                break
        _, ctrl, idx, corners, counts = best
        return ctrl, idx, corners, counts

    def _owners(self, keys: list) -> tuple[np.ndarray, np.ndarray]:
        """The segment (index into ``keys``) of each search point: the one starting at a joint, and the one ending
        there (the same inside a segment)."""
        owners = []
        for order in (range(len(keys)), range(len(keys) - 1, -1, -1)):
            owner = np.zeros(self.m, dtype=np.int64)
            for i in order:
                a, b = keys[i]
                if (a, b) != (-1, -1):
                    owner[np.arange(a, b + 1) % self.m] = i
            owners.append(owner)
        return owners[0], owners[1]

    def _split(self, corners: tuple[int, ...], splits: dict) -> tuple[int, ...]:
        """``corners`` with each segment of ``splits`` cut (a C0 joint) at its search point, kept at least one
        point inside it: the paper's segmentation at the points a single uniform-knot piece cannot follow."""
        out = set(corners)
        for (a, b), at in splits.items():
            if (a, b) == (-1, -1):
                out.add(int(at))
                continue
            if b - a < 2:
                continue
            rel = int(np.clip(np.mod(at - a, self.m), 1, b - a - 1))
            out.add((a + rel) % self.m)
        return tuple(sorted(out))


def curve_metrics(ctrl: np.ndarray, target: CurveTarget | np.ndarray, degree: int, closed: bool = False,
                  corners: tuple[int, ...] = (), max_distance: float | None = None,
                  data_corners: np.ndarray | None = None) -> dict[str, Any]:
    """Distances between data and curve both ways, normalized by the data's bounding-box diagonal.

    ``data_to_fit_*``: each data point to the curve; ``fit_to_data_*``: curve samples (32 per knot span) to
    the data's local model (:func:`~gsr_cad.geometry.distance.data_model`, sharp at ``data_corners``; closed
    data with their closing piece). ``tolerance_met`` when ``max_distance`` is given: both maxima within it.
    The older keys (``mean_distance``, ``max_distance``, ...) are data -> curve.
    """
    pts = target.points if isinstance(target, CurveTarget) else np.asarray(target, dtype=np.float64)
    diag = float(np.linalg.norm(np.ptp(pts, axis=0)))
    spline = bspline.make_spline(ctrl, degree, closed, corners)
    geo, back = two_sided(spline, pts, closed, per_span=32, corners=data_corners)
    idx = index_wise(spline(np.linspace(0.0, 1.0, len(pts), endpoint=not closed)), pts)
    out: dict[str, Any] = {
        "mean_distance": float(geo.mean() / diag),
        "max_distance": float(geo.max() / diag),
        "rms_distance": float(np.sqrt(np.mean(geo ** 2)) / diag),
        "index_mean_distance": float(idx.mean() / diag),
        "index_max_distance": float(idx.max() / diag),
        "data_to_fit_mean": float(geo.mean() / diag),
        "data_to_fit_max": float(geo.max() / diag),
        "fit_to_data_mean": float(back.mean() / diag),
        "fit_to_data_max": float(back.max() / diag),
        "n_control_points": int(len(ctrl)),
        "n_corners": len(corners),
        "closed": bool(closed),
    }
    if max_distance is not None:
        out["tolerance_met"] = bool(max(out["data_to_fit_max"], out["fit_to_data_max"]) <= max_distance)
    return out


def _ga_config(config: CurveConfig, problem: CurveProblem) -> GAConfig:
    stall = config.tolerance_stall_generations
    if isinstance(stall, bool) or not isinstance(stall, int) or stall < 0:
        raise ConfigError(f"tolerance-stall-generations must be a whole number >= 0, not {stall!r}")
    if config.max_distance is not None and config.polish and stall:
        stall = min(stall, config.stall_generations) if config.stall_generations else stall
    else:
        stall = config.stall_generations
    return GAConfig(
        scheme="steady_state",
        initial_population=config.initial_population,
        population=config.population,
        min_initial_genes=config.min_initial_ops,
        max_initial_genes=config.max_initial_ops,
        mutation_rate=config.mutation_rate,
        delete_rate=config.delete_rate,
        append_rate=config.append_rate,
        elite_fraction=config.elite_fraction,
        generations=config.generations,
        threshold=problem.threshold() or 0.0,
        stall_generations=stall or None,
        max_seconds=config.max_seconds or None,
        local_search_every=1 if config.polish else 0,
    )


def _worst(metrics: dict) -> float:
    return max(metrics["data_to_fit_max"], metrics["fit_to_data_max"])


def reconstruct_curve(points: np.ndarray | str | CurveTarget, *, scheme: str | None = None, preset: str = "default",
                      seed: int | None = None, config: CurveConfig | None = None,
                      progress: Callable[[GenerationReport], None] | None = None,
                      evaluator: Callable | None = None, should_stop: Callable[[], bool] | None = None,
                      checkpoint: str | os.PathLike[str] | None = None, **overrides: Any) -> Result:
    """Reconstruct a B-spline (or Chaikin) control polygon - open or closed, with corners - and its op history.

    ``points``: an ``(n, 2)`` or ``(n, 3)`` array of ordered points, a path to a CSV/TXT/NPY file or a
    :class:`~gsr_cad.reconstruct.inputs.CurveTarget`. ``overrides`` are :class:`CurveConfig` fields.
    The result's ``config`` records ``closed`` (a periodic control polygon) and ``corners`` (control point
    indices with knot multiplicity = degree); :func:`gsr_cad.geometry.bspline.clamped_form` turns them into
    an exact clamped knot vector. ``metrics["tolerance_met"]`` says whether ``max_distance`` was met both
    ways on all points (a :class:`CurveWarning` is issued when not). Ctrl-C during the search keeps the best
    genome found so far (``result.interrupted``), as does ``should_stop()`` turning true (the final refinement
    and check are then skipped). With ``checkpoint`` the search state is saved there every generation and, if
    that file exists, the run continues from it (same seed, same result as an uninterrupted run). Raises :class:`~gsr_cad.errors.InputError` /
    ``ConfigError`` on bad input (including points that are not in curve order and cannot be ordered).
    """
    started = time.perf_counter()
    target = curve_target(points)
    if scheme is not None:
        overrides["scheme"] = scheme
    config = (CurveConfig.preset(preset, **overrides) if config is None
              else dataclasses.replace(config, **overrides).validated())
    problem = CurveProblem(target, config)
    tag = fingerprint("curve", target.points, config.to_json(), preset, seed)
    engine = start_or_resume(problem, _ga_config(config, problem), seed, evaluator, checkpoint, tag)
    run: RunResult = engine.run(on_generation=progress, should_stop=should_stop, checkpoint=checkpoint)
    best = tuple(run.best_genome)
    hurry = should_stop is not None and should_stop()
    corners: tuple[int, ...] = ()
    template = problem.template
    data_corners = problem.prepared.candidates if config.polish else None
    if config.polish:
        fitted, corners, _, _ = problem.final(best, hurry)
        template = problem.result_template(fitted)
        final = problem.history(fitted, corners, template)
    else:
        final = best
    ctrl = genome_mod.replay(template, final).points
    prep = problem.prepared
    metrics = curve_metrics(ctrl, prep.points, problem.degree, problem.closed, corners, config.max_distance,
                            data_corners)
    metrics.update({
        "fitness": float(problem.cost(best)),
        "fitness_kind": "penalised least-squares error" if config.polish else f"sum of {config.fitness} distances",
        "seconds": time.perf_counter() - started,
        "generations": run.generations,
        "evaluations": run.evaluations,
        "stop_reason": run.stop_reason,
        "n_ops": len(final),
        "reordered": prep.reordered,
        "search_points": int(problem.m),
    })
    if problem.sampling is not None:
        choice = problem.sampling
        metrics["sampling"] = {"evenly_spaced": choice.accepted, "p_value": choice.p_value,
                               "f_statistic": choice.f_stat, "warp_terms": choice.terms,
                               "free_model_count": choice.free_count}
    if metrics.get("tolerance_met") is False and not run.interrupted and not hurry:
        # A limit below the data's noise drives the search to ever more points that chase it; the fit chosen
        # without a limit (the information criterion's) is then often closer both ways: keep the closer one.
        plain = reconstruct_curve(target, config=dataclasses.replace(config, max_distance=None), preset=preset,
                                  seed=run.seed, evaluator=evaluator, should_stop=should_stop)
        alt = curve_metrics(plain.control_points, prep.points, problem.degree, problem.closed,
                            tuple(plain.config["corners"]), config.max_distance, data_corners)
        if _worst(alt) < _worst(metrics):
            final, ctrl, corners = plain.genome, plain.control_points, tuple(plain.config["corners"])
            template = plain.template
            metrics.update(alt)
            metrics.update(n_ops=len(final), fitness=plain.metrics["fitness"], unmet_limit_fallback=True)
    if metrics.get("tolerance_met") is False:
        worst = _worst(metrics)
        warnings.warn(f"max distance {worst:.3g} of the diagonal misses the requested {config.max_distance:g}",
                      CurveWarning, stacklevel=2)
    cfg = config.to_json()
    cfg.update({
        "preset": preset,
        "template": np.asarray(template.points).tolist(),
        "bounds": [list(template.lo), list(template.hi)],
        "closed": bool(problem.closed),
        "corners": [int(c) for c in corners],
        "target": {"name": target.name, "n_points": len(target), "diagonal": target.diagonal},
    })
    return Result(kind="curve", config=cfg, seed=run.seed, genome=final, metrics=metrics, history=run.history,
                  control_points=np.array(ctrl), interrupted=run.interrupted)
