"""Curve reconstruction: ordered 2D points -> control polygon + the op history that builds it.

The GA (paper, section 3) evolves genomes of ``add_point``/``move_point`` ops on the paper's 4-point
template. Two evaluations are offered:

* ``preset="paper"``: the paper exactly - the genome's own positions, fitness = sum of index-wise
  distances between the target and as many evenly spaced curve samples.
* ``preset="default"`` (Lamarckian): curve points are linear in the control points, so each genome is
  scored after the least-squares placement of its control points (geometric, foot-point corrected
  distances); the score depends on the genome only through its number of points ``n`` and is cached per
  ``n``. The cost ``exp(2 n ln m / m) * max(rms / diag, tolerance)^2`` is the exponential of a BIC per
  sample: exact data get their exact count back, noisy data are not over-fitted, and smooth data use the
  fewest points that reach the tolerance. The winner's placement is written back into its history
  (insertions at their final positions, then ``move_point`` ops for the template's free points), so the
  saved genome replays exactly to the result.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import genome as genome_mod
from ..errors import OpError
from ..ga import GAConfig, GenerationReport, RunResult, fingerprint, start_or_resume
from ..geometry import bspline
from ..geometry.curvefit import CurveFit, fit_curve, minimax_refine
from ..geometry.distance import chord_length_params, foot_points, index_wise, point_to_curve
from ..ops import curve as curve_ops
from .config import CurveConfig
from .inputs import CurveTarget, curve_target
from .result import Result


class CurveProblem:
    """The GA problem for one target: random ops, repair, and the cost of a genome."""

    def __init__(self, target: CurveTarget, config: CurveConfig):
        self.target = target
        self.config = config
        self.points = target.points
        self.m = len(target.points)
        self.diag = target.diagonal
        self.degree = 2 if config.scheme == "chaikin" else 3
        self.template = curve_ops.template(self.points, margin=config.bounds_margin)
        self.lo = np.asarray(self.template.lo, dtype=np.float64)
        self.hi = np.asarray(self.template.hi, dtype=np.float64)
        cap = config.max_control_points or min(max(4, self.m // 2), 200)
        self.max_ctrl = max(4, min(cap, self.m))
        self._fits: dict[int, tuple[CurveFit, float, float]] = {}
        self._chord = chord_length_params(self.points)
        self._states: dict[tuple, curve_ops.Polygon] = {}

    # --- GA protocol -------------------------------------------------------------------------------
    def _state(self, prefix: tuple) -> curve_ops.Polygon:
        """The polygon after ``prefix`` with invalid ops skipped (repair semantics), cached by prefix.

        Genomes grow and are rebuilt gene by gene, so each state is one op applied to a cached parent.
        """
        state = self._states.get(prefix)
        if state is None:
            if not prefix:
                return self.template
            parent = self._state(prefix[:-1])
            try:
                state = prefix[-1].apply(parent)
            except OpError:
                state = parent
            if len(self._states) >= 200_000:
                self._states.clear()
            self._states[prefix] = state
        return state

    def random_gene(self, rng: np.random.Generator, prefix: tuple) -> genome_mod.Op:
        poly = self._state(prefix)
        p_add = self.config.p_add if poly.n < self.max_ctrl else 0.0
        return curve_ops.random_op(rng, poly, p_add=p_add, move_scale=self.config.move_scale,
                                   local_add=self.config.local_add)

    def repair(self, genome: tuple, rng: np.random.Generator) -> tuple:
        kept: list = []
        state = self.template
        for op in genome:
            if isinstance(op, curve_ops.AddPoint) and state.n >= self.max_ctrl:
                continue
            try:
                state = op.apply(state)
            except OpError:
                continue
            kept.append(op)
        while len(kept) < self.config.min_ops:
            op = self.random_gene(rng, tuple(kept))
            try:
                state = op.apply(state)
            except OpError:
                continue
            kept.append(op)
        return tuple(kept)

    def cost(self, genome: tuple) -> float:
        poly = self._state(tuple(genome))
        if self.config.polish:
            return self.structure_cost(poly.n)
        if self.config.fitness == "index":
            samples = bspline.sample_uniform(poly.points, self.m, self.degree)
            return float(index_wise(samples, self.points).sum())
        _, dist = foot_points(poly.points, self.points, self._chord, degree=self.degree)
        return float(dist.sum())

    def local_search(self, genome: tuple) -> tuple:
        """Memetic step on the best genome (Lamarckian mode only): walk the number of points.

        The cost depends on the genome only through its point count, so trying counts near the current
        one is a handful of cached look-ups; the walk moves to the first better count among
        +1..+3 and -1..-2 (insertions appended at the middle of the longest polygon edge, or the last
        insertions dropped) until none is better.
        """
        if not self.config.polish:
            return genome
        best, best_cost = tuple(genome), self.cost(genome)
        for _ in range(self.max_ctrl):
            for step in (1, 2, 3, -1, -2):
                candidate = self._resized(best, step)
                if candidate is not None and (cost := self.cost(candidate)) < best_cost:
                    best, best_cost = candidate, cost
                    break
            else:
                break
        return best

    def _resized(self, genome: tuple, step: int) -> tuple | None:
        """``genome`` with ``step`` insertions appended (> 0) or its last ``-step`` insertions removed."""
        if step < 0:
            adds = [i for i, op in enumerate(genome) if isinstance(op, curve_ops.AddPoint)]
            if len(adds) < -step:
                return None
            drop = set(adds[step:])
            kept = genome_mod.repair(self.template, (op for i, op in enumerate(genome) if i not in drop))[0]
            return kept if len(kept) >= self.config.min_ops else None
        out = list(genome)
        poly = self._state(tuple(out))
        for _ in range(step):
            if poly.n >= self.max_ctrl:
                return None
            seg = np.linalg.norm(np.diff(poly.points, axis=0), axis=1)
            i = int(np.argmax(seg))
            mid = 0.5 * (poly.points[i] + poly.points[i + 1])
            op = curve_ops.AddPoint(i + 1, (float(mid[0]), float(mid[1])))
            try:
                poly = op.apply(poly)
            except OpError:
                return None
            out.append(op)
        return tuple(out)

    def perturb(self, gene: genome_mod.Op, rng: np.random.Generator) -> genome_mod.Op:
        return curve_ops.perturb_op(gene, rng, 0.02 * self.diag)

    # --- Lamarckian evaluation ---------------------------------------------------------------------
    def fit(self, n: int) -> tuple[CurveFit, float, float]:
        """Least-squares control polygon of ``n`` points with its relative RMS and max distance (cached)."""
        if n not in self._fits:
            # Warm-start from the fit with one point fewer: deterministic whatever order the GA asks in.
            warm = self.fit(n - 1)[0].params if n > 4 and self.config.fitness == "geometric" else None
            fit = fit_curve(self.points, n, self.degree, parametrization=self.config.fitness,
                            iterations=self.config.fit_iterations, lo=self.lo, hi=self.hi, warm_params=warm)
            limit = self.config.max_distance
            if limit is not None and limit < fit.distances.max() / self.diag < 3 * limit:
                # A CAD tolerance is a maximum: near misses get a minimax placement before being judged.
                fit = minimax_refine(self.points, fit, self.degree, lo=self.lo, hi=self.hi)
            self._fits[n] = (fit, fit.rms / self.diag, float(fit.distances.max()) / self.diag)
        return self._fits[n]

    def final_fit(self, n: int, hurry: bool = False) -> CurveFit:
        """The search's fit of ``n`` points refined to convergence (done once, for the winner).

        With a max-distance limit, placements that meet it win over those that do not; then the lower
        RMS wins (a converged least-squares fit beats a minimax one whenever both meet the limit).
        """
        quick = self.fit(n)[0]
        if self.config.fitness != "geometric" or hurry:
            return quick
        fit = fit_curve(self.points, n, self.degree, parametrization="geometric", iterations=400, lo=self.lo,
                        hi=self.hi, rtol=1e-7, warm_params=quick.params)
        limit = self.config.max_distance

        def rank(f: CurveFit) -> tuple[bool, float]:
            misses = limit is not None and float(f.distances.max()) / self.diag > limit
            return misses, f.rms

        return min((fit, quick), key=rank)

    def structure_cost(self, n: int) -> float:
        _, rms_rel, max_rel = self.fit(n)
        cost = math.exp(2.0 * n * math.log(self.m) / self.m) * max(rms_rel, self.config.tolerance) ** 2
        if self.config.max_distance is not None and max_rel > self.config.max_distance:
            cost *= 1e6 * (max_rel / self.config.max_distance) ** 2  # infeasible: worse, and graded by the miss
        return cost

    def polished(self, genome: tuple, hurry: bool = False) -> tuple:
        """The genome rewritten onto the least-squares placement, as a clean modelling history.

        The genome's insertions are kept in order (same indices) but each inserts its point where the
        placement puts it; the template's free points then get one ``move_point`` each. Replaying the
        result gives the placement exactly (up to the rounding of ``template + delta``).
        """
        adds = [op for op in genome if isinstance(op, curve_ops.AddPoint)]
        ids = list(range(self.template.n))
        for k, op in enumerate(adds):
            ids.insert(op.index, self.template.n + k)
        fitted = self.final_fit(len(ids), hurry).ctrl
        where = {point_id: fitted[i] for i, point_id in enumerate(ids)}
        placed = tuple(curve_ops.AddPoint(op.index, tuple(float(v) for v in where[self.template.n + k]))
                       for k, op in enumerate(adds))
        poly = genome_mod.replay(self.template, placed)
        moves = []
        for i in range(1, poly.n - 1):
            delta = fitted[i] - poly.points[i]
            if np.any(delta != 0.0):
                moves.append(curve_ops.MovePoint(i, (float(delta[0]), float(delta[1]))))
        return placed + tuple(moves)

    def threshold(self) -> float | None:
        """Stop threshold in cost units: explicit, automatic (< 0: the paper's mean index distance
        of 1e-4 of the diagonal, summed), or none (0)."""
        t = self.config.threshold
        if t > 0:
            return t
        if t < 0 and not self.config.polish:
            return 1e-4 * self.diag * self.m
        return None


def curve_metrics(ctrl: np.ndarray, target: CurveTarget, degree: int) -> dict[str, float]:
    """Distances of the target to a curve, normalized by the target's bounding-box diagonal."""
    diag = target.diagonal
    geo = point_to_curve(ctrl, target.points, degree=degree)
    idx = index_wise(bspline.sample_uniform(ctrl, len(target), degree), target.points)
    return {
        "mean_distance": float(geo.mean() / diag),
        "max_distance": float(geo.max() / diag),
        "rms_distance": float(np.sqrt(np.mean(geo ** 2)) / diag),
        "index_mean_distance": float(idx.mean() / diag),
        "index_max_distance": float(idx.max() / diag),
        "n_control_points": int(len(ctrl)),
    }


def _ga_config(config: CurveConfig, problem: CurveProblem) -> GAConfig:
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
        stall_generations=config.stall_generations or None,
        max_seconds=config.max_seconds or None,
        local_search_every=1 if config.polish else 0,
    )


def reconstruct_curve(points: np.ndarray | str | CurveTarget, *, scheme: str | None = None, preset: str = "default",
                      seed: int | None = None, config: CurveConfig | None = None,
                      progress: Callable[[GenerationReport], None] | None = None,
                      evaluator: Callable | None = None, should_stop: Callable[[], bool] | None = None,
                      checkpoint: str | os.PathLike[str] | None = None, **overrides: Any) -> Result:
    """Reconstruct a clamped uniform B-spline (or Chaikin) control polygon and its op history.

    ``points``: an ``(n, 2)`` array of ordered points, a path to a CSV/TXT/NPY file or a
    :class:`~gsr_cad.reconstruct.inputs.CurveTarget`. ``overrides`` are
    :class:`CurveConfig` fields. Ctrl-C during the search keeps the best genome found so far
    (``result.interrupted``), as does ``should_stop()`` turning true (the final refinement is then
    skipped). With ``checkpoint`` the search state is saved there every generation and, if that file
    exists, the run continues from it (same seed, same result as an uninterrupted run).
    Raises :class:`~gsr_cad.errors.InputError` / ``ConfigError`` on bad input.
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
    final = problem.polished(best, hurry=hurry) if config.polish else best
    ctrl = genome_mod.replay(problem.template, final).points
    metrics = curve_metrics(ctrl, target, problem.degree)
    metrics.update({
        "fitness": float(problem.cost(final)),
        "fitness_kind": "penalised least-squares error" if config.polish else f"sum of {config.fitness} distances",
        "seconds": time.perf_counter() - started,
        "generations": run.generations,
        "evaluations": run.evaluations,
        "stop_reason": run.stop_reason,
        "n_ops": len(final),
    })
    cfg = config.to_json()
    cfg.update({
        "preset": preset,
        "template": np.asarray(problem.template.points).tolist(),
        "bounds": [list(problem.template.lo), list(problem.template.hi)],
        "target": {"name": target.name, "n_points": len(target), "diagonal": target.diagonal},
    })
    return Result(kind="curve", config=cfg, seed=run.seed, genome=final, metrics=metrics, history=run.history,
                  control_points=np.array(ctrl), interrupted=run.interrupted)
