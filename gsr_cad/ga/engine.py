"""The GA loop for both of the paper's schemes, with a fitness memo, progress, Ctrl-C and checkpoints.

Everything random comes from one ``np.random.Generator`` seeded once, and evaluation order never touches
it, so a seed fixes the run whichever evaluator computes the costs. Costs are memoised by genome (genomes
are tuples of hashable genes): an identical genome is never evaluated twice, and ``evaluations`` counts
the memo. The population is kept sorted by cost (stable, so ties keep their order).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import pickle
import secrets
import stat
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_bytes
from ..errors import ConfigError, InputError
from . import termination
from .config import GAConfig
from .evaluators import Evaluator, serial_evaluator
from .pareto import nsga2_order
from .problem import GenomeT, Problem
from .selection import roulette_select
from .variation import offspring, perturb_one, random_genome

CHECKPOINT_FORMAT = "gsr_cad.ga.checkpoint"
CHECKPOINT_VERSION = 1


@dataclasses.dataclass(frozen=True)
class GenerationReport:
    """Passed to ``on_generation`` after each completed generation (0 = the first population)."""

    generation: int
    best_cost: float
    mean_cost: float
    best_genome: GenomeT
    evaluations: int
    seconds: float
    progress: float


@dataclasses.dataclass
class RunResult:
    """Outcome of :meth:`GeneticAlgorithm.run`: the best genome ever evaluated and how the run went.

    ``history`` rows are ``{generation, best_fitness, mean_fitness, seconds}`` where the "fitness" values
    are costs (lower is better): the best ever and the population mean. ``generations`` counts completed
    generations after the first population. ``stop_reason`` is "threshold", "generations",
    "max_seconds", "stall" or "interrupted". If Ctrl-C came before any cost was known, ``best_genome``
    is empty and ``best_cost`` is inf.
    """

    best_genome: GenomeT
    best_cost: float
    history: list[dict[str, float]]
    generations: int
    evaluations: int
    seconds: float
    interrupted: bool
    stop_reason: str
    seed: int | None = None


def fingerprint(*parts: Any) -> str:
    """A short digest of ``parts`` (arrays by their bytes, anything else by its repr): a checkpoint's tag."""
    h = hashlib.sha256()
    for part in parts:
        h.update(np.ascontiguousarray(part).tobytes() if isinstance(part, np.ndarray) else repr(part).encode())
        h.update(b"\0")
    return h.hexdigest()[:32]


def _clean_cost(value: Any) -> float:
    """A cost as a float; nan counts as the worst (inf), a negative cost breaks the problem's contract."""
    c = float(value)
    if math.isnan(c):
        return math.inf
    if c < 0:
        raise InputError(f"problem cost must be >= 0, got {c}")
    return c


class _OutOfTime(Exception):
    """The time budget ran out inside a batch of evaluations (raised between items, in-process only)."""


class _Reached(Exception):
    """A cost at or below the threshold came in a batch of evaluations (raised after it, in-process only)."""


class _CostFn:
    """Picklable ``problem.cost`` wrapper; in the engine's own process it also records each result as it
    comes, so costs computed before a Ctrl-C are not lost, and it ends a batch once the time budget is spent
    (after at least one finite cost is known), so a slow first population cannot overrun ``max_seconds``, and as soon
    as a cost reaches ``threshold`` (the rest of the batch would not be kept, :meth:`GeneticAlgorithm._evaluate`)."""

    def __init__(self, problem: Problem, sink: dict[GenomeT, float]) -> None:
        self.problem = problem
        self.sink = sink
        self.owner = os.getpid()
        self.should_stop: Callable[[], bool] | None = None
        self.out_of_time: Callable[[], bool] | None = None
        self.threshold: float | None = None
        self.finite = False  # whether a finite cost is known (only then may the time budget end a batch)

    def stopping(self) -> bool:
        """Whether the run was asked to stop (polled by in-process evaluators between items)."""
        return self.should_stop is not None and os.getpid() == self.owner and bool(self.should_stop())

    def __call__(self, genome: GenomeT) -> float:
        if self.stopping():
            raise KeyboardInterrupt
        if self.out_of_time is not None and self.finite and os.getpid() == self.owner and self.out_of_time():
            raise _OutOfTime
        c = _clean_cost(self.problem.cost(genome))
        if self.sink is not None and os.getpid() == self.owner:
            self.sink[genome] = c
            self.finite = self.finite or math.isfinite(c)
            if self.threshold is not None and c <= self.threshold:
                raise _Reached
        return c

    def __getstate__(self) -> dict[str, Any]:
        return {"problem": self.problem, "sink": None, "owner": self.owner, "should_stop": None, "out_of_time": None,
                "threshold": None, "finite": False}


class GeneticAlgorithm:
    """Evolve genomes of ``problem`` under ``config`` (the paper's "steady_state" or "plus" scheme).

    ``evaluator`` is any ``(fn, items) -> list`` (default: serial in this process). ``seed=None`` draws a
    seed, kept in ``self.seed`` so the run can be repeated. Read-only views of the state: ``population``
    (sorted by cost) and ``costs``, ``memo`` (genome -> cost), ``history``, ``generation`` (-1 before the
    first population).
    """

    def __init__(self, problem: Problem, config: GAConfig | None = None, seed: int | None = None,
                 evaluator: Evaluator | None = None, tag: str | None = None) -> None:
        missing = [m for m in ("random_gene", "repair", "cost", "perturb") if not callable(getattr(problem, m, None))]
        if missing:
            raise ConfigError(f"{type(problem).__name__} is not a GA problem: it lacks {', '.join(missing)}")
        config = GAConfig() if config is None else config
        if not isinstance(config, GAConfig):
            raise ConfigError(f"config must be a GAConfig, not {type(config).__name__}")
        self.config = config.validate()
        if seed is None:
            seed = secrets.randbits(63)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ConfigError(f"seed must be a non-negative integer, not {seed!r}")
        self.seed = int(seed)
        self.tag = tag
        self.problem = problem
        self.evaluator: Evaluator = serial_evaluator if evaluator is None else evaluator
        self.memo: dict[GenomeT, float] = {}
        self._cost_fn = _CostFn(problem, self.memo)
        self._rng = np.random.default_rng(self.seed)
        self.population: list[GenomeT] = []
        self.costs = np.empty(0)
        self.history: list[dict[str, float]] = []
        self.generation = -1
        self._best: tuple[GenomeT, float] | None = None
        self._first_best = math.inf
        self._last_best = math.inf
        self._stalled = 0
        self._seconds = 0.0
        self._progress = 0.0
        self._clock: float | None = None
        self._stop: str | None = None

    # ------------------------------------------------------------------ public
    @property
    def evaluations(self) -> int:
        """How many genomes have been evaluated (each at most once)."""
        return len(self.memo)

    @property
    def best(self) -> tuple[GenomeT, float]:
        """The best genome evaluated so far and its cost (``((), inf)`` before any evaluation)."""
        return self._best if self._best is not None else ((), math.inf)

    @property
    def progress(self) -> float:
        """Overall progress in [0, 1]; never decreases."""
        return self._progress

    def run(self, on_generation: Callable[[GenerationReport], None] | None = None,
            should_stop: Callable[[], bool] | None = None,
            checkpoint: str | os.PathLike[str] | None = None) -> RunResult:
        """Evolve until a stopping criterion holds or Ctrl-C; call ``on_generation`` after each generation.

        Ctrl-C, or ``should_stop()`` turning true (polled before every in-process evaluation and between
        generations), returns the best genome so far with ``interrupted=True``; costs of an unfinished
        batch count when computed in this process (an out-of-process evaluator loses them). With
        ``checkpoint``, the state after every completed generation is saved there (atomically), so that
        :meth:`resume` continues exactly. A second call continues the same run (after an interrupt, or after
        :meth:`resume` with a longer config); a finished run returns at once.
        """
        self._clock = time.perf_counter()
        self._cost_fn.should_stop = should_stop
        budget = self.config.max_seconds
        self._cost_fn.out_of_time = None if budget is None else (lambda: self._elapsed() >= budget)
        self._cost_fn.threshold = self.config.threshold
        self._cost_fn.finite = any(math.isfinite(c) for c in self.memo.values())
        interrupted = False
        if checkpoint is not None:
            inner = on_generation

            def on_generation(report: GenerationReport) -> None:
                self.checkpoint(checkpoint)
                if inner is not None:
                    inner(report)
        try:
            if self.generation < 0:
                self._first_generation()
                self._finish_generation(on_generation)
            else:
                self._stop = termination.stop_reason(self.config, self._state())
            while self._stop is None:
                if self._cost_fn.stopping():
                    raise KeyboardInterrupt
                self._next_generation()
                self._finish_generation(on_generation)
        except KeyboardInterrupt:
            interrupted = True
            self._best_from_memo()
        except _OutOfTime:
            self._stop = "max_seconds"
            self._best_from_memo()
        finally:
            self._seconds = self._elapsed()
            self._clock = None
            self._cost_fn.should_stop = None
            self._cost_fn.out_of_time = None
            self._cost_fn.threshold = None
        best_genome, best_cost = self.best
        return RunResult(best_genome=best_genome, best_cost=best_cost, history=list(self.history),
                         generations=max(self.generation, 0), evaluations=self.evaluations,
                         seconds=self._seconds, interrupted=interrupted,
                         stop_reason="interrupted" if interrupted else str(self._stop), seed=self.seed)

    def checkpoint(self, path: str | os.PathLike[str]) -> Path:
        """Pickle the whole run state (config, population, rng, memo, history) atomically to ``path``."""
        state = {
            "format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "config": self.config.to_dict(),
            "seed": self.seed, "rng": self._rng.bit_generator.state, "population": self.population,
            "costs": self.costs.tolist(), "memo": self.memo, "history": self.history,
            "generation": self.generation, "best": self._best, "first_best": self._first_best,
            "last_best": self._last_best, "stalled": self._stalled, "seconds": self._elapsed(),
            "progress": self._progress, "tag": self.tag,
        }
        return write_bytes(path, pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL))

    @classmethod
    def resume(cls, path: str | os.PathLike[str], problem: Problem, evaluator: Evaluator | None = None,
               config: GAConfig | None = None, tag: str | None = None) -> GeneticAlgorithm:
        """Rebuild a run from :meth:`checkpoint` (trusted files only: it is a pickle); ``run()`` continues it
        exactly (same RNG state, population, memo and counters: the same genomes as an uninterrupted run).
        ``config`` may replace the saved one, e.g. to allow more generations. A ``tag`` (e.g. a fingerprint of
        the target and settings) must match the one the checkpoint was written with."""
        try:
            st = os.stat(path)
            if not stat.S_ISREG(st.st_mode):
                raise InputError(f"checkpoint {path} is not a regular file")
            data = pickle.loads(Path(path).read_bytes())
        except OSError as exc:
            raise InputError(f"cannot read checkpoint {path}: {exc.strerror or exc}") from None
        except InputError:
            raise
        except Exception:
            raise InputError(f"{path} is not a gsr_cad GA checkpoint") from None
        if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
            raise InputError(f"{path} is not a gsr_cad GA checkpoint")
        if data.get("version") != CHECKPOINT_VERSION:
            raise InputError(f"checkpoint {path} has version {data.get('version')!r}; "
                             f"this gsr_cad reads version {CHECKPOINT_VERSION}")
        if tag is not None and data.get("tag") != tag:
            raise InputError(f"checkpoint {path} belongs to another run (a different target, settings or seed)")
        try:
            ga = cls(problem, config if config is not None else GAConfig.from_dict(data["config"]),
                     seed=data["seed"], evaluator=evaluator, tag=data.get("tag"))
            ga._rng.bit_generator.state = data["rng"]
            ga.population = list(data["population"])
            ga.costs = np.asarray(data["costs"], dtype=float)
            ga.memo.update(data["memo"])
            ga.history = list(data["history"])
            ga.generation = data["generation"]
            ga._best = data["best"]
            ga._first_best = data["first_best"]
            ga._last_best = data["last_best"]
            ga._stalled = data["stalled"]
            ga._seconds = data["seconds"]
            ga._progress = data["progress"]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"checkpoint {path} is damaged ({type(exc).__name__}: {exc})") from None
        return ga

    # ------------------------------------------------------------------ generations
    def _first_generation(self) -> None:
        cfg, rng = self.config, self._rng
        size = max(cfg.initial_population, cfg.population)
        seeds: list[GenomeT] = []
        hook = getattr(self.problem, "seed_genomes", None)
        if callable(hook):
            seeds = [tuple(self.problem.repair(tuple(g), rng)) for g in hook()][:size]
        genomes = seeds + [random_genome(self.problem, rng, cfg.min_initial_genes, cfg.max_initial_genes)
                           for _ in range(size - len(seeds))]
        costs = self._evaluate(genomes)
        genomes, costs = self._scored(genomes, costs)
        if size > cfg.population and len(genomes) > cfg.population:
            # the problem's own starts survive the cut (a roulette drew a fitted lead start out of 1,000 random
            # genomes it beat 5x); the others are drawn for the places left, as before when there are none
            chosen = set(seeds)
            fixed = [i for i, g in enumerate(genomes) if g in chosen and np.isfinite(costs[i])][:cfg.population]
            rest = [i for i in range(len(genomes)) if i not in set(fixed)]
            drawn = roulette_select(costs[rest], cfg.population - len(fixed), rng, replace=False)
            keep = fixed + [rest[j] for j in drawn]
            genomes, costs = [genomes[i] for i in keep], costs[keep]
        if cfg.scheme == "plus":
            genomes, costs = self._limit_duplicates(genomes, costs)
        self._commit(0, genomes, costs)
        self._first_best = self.best[1]

    def _next_generation(self) -> None:
        cfg, rng, pop, costs = self.config, self._rng, self.population, self.costs
        rates = (cfg.mutation_rate, cfg.delete_rate, cfg.append_rate)
        if cfg.scheme == "steady_state":
            n_elite = min(cfg.n_elite, len(pop))
            n_off = cfg.population - n_elite
            parents = roulette_select(costs, 2 * n_off, rng)
            children = [offspring(pop[parents[2 * i]], pop[parents[2 * i + 1]], self.problem, rng, *rates)
                        for i in range(n_off)]
            genomes = pop[:n_elite] + children
            all_costs = np.concatenate([costs[:n_elite], self._evaluate(children)])
            genomes, all_costs = self._scored(genomes, all_costs)
            if len(genomes) < cfg.population:  # a batch cut at the threshold: the next survivors fill in
                fill = slice(n_elite, n_elite + cfg.population - len(genomes))
                genomes, all_costs = genomes + pop[fill], np.concatenate([all_costs, costs[fill]])
        else:
            n_par = min(cfg.n_parents, len(pop))
            parents = roulette_select(costs, n_par, rng, replace=False)
            new = [offspring(pop[parents[2 * i]], pop[parents[2 * i + 1]], self.problem, rng, *rates)
                   for i in range(min(cfg.max_children, n_par // 2))]
            new += [perturb_one(pop[i], self.problem, rng) for i in range(min(cfg.n_perturb, len(pop)))]
            new += [random_genome(self.problem, rng, cfg.min_initial_genes, cfg.max_initial_genes)
                    for _ in range(cfg.n_newcomers)]
            all_costs = np.concatenate([costs, self._evaluate(new)])
            genomes, all_costs = self._limit_duplicates(*self._scored(pop + new, all_costs))
        self._commit(self.generation + 1, genomes, all_costs)

    def _commit(self, generation: int, genomes: list[GenomeT], costs: np.ndarray) -> None:
        """Install the next population (sorted), after the optional memetic polish of its best (skipped once the
        best is within the threshold: the run ends with this generation)."""
        order = np.argsort(costs, kind="stable")
        genomes, costs = [genomes[i] for i in order], np.asarray(costs, dtype=float)[order]
        k = self.config.local_search_every
        if (k > 0 and generation % k == 0 and genomes and not costs[0] <= self.config.threshold
                and self._local_search(genomes, costs)):
            order = np.argsort(costs, kind="stable")
            genomes, costs = [genomes[i] for i in order], costs[order]
        self.population, self.costs, self.generation = genomes, costs, generation

    def _local_search(self, genomes: list[GenomeT], costs: np.ndarray) -> bool:
        """Polish, in place, the first genome of each of the ``local_search_count`` first niches of the sorted
        ``genomes`` (the first genome if no cost is finite); whether any improved."""
        hook = getattr(self.problem, "local_search", None)
        if not callable(hook):
            return False
        niche = getattr(self.problem, "niche", None)
        picked: dict[Any, int] = {}
        for i, g in enumerate(genomes):
            if not math.isfinite(costs[i]) or len(picked) == self.config.local_search_count:
                break
            picked.setdefault(niche(g) if callable(niche) else g, i)
        improved = False
        for i in picked.values() or [0]:
            polished = tuple(self.problem.repair(tuple(hook(genomes[i])), self._rng))
            c = self._evaluate([polished])[0]
            if c < costs[i]:
                genomes[i], costs[i], improved = polished, c, True
        return improved

    def _limit_duplicates(self, genomes: list[GenomeT], costs: np.ndarray) -> tuple[list[GenomeT], np.ndarray]:
        """The best ``population`` individuals (by cost, or by NSGA-II's order with ``survival="nsga2"``) with at
        most ``max_duplicates`` copies of any genome."""
        seen: dict[GenomeT, int] = {}
        keep: list[int] = []
        order = np.argsort(costs, kind="stable")
        if self.config.survival == "nsga2":
            order = nsga2_order(np.c_[np.asarray(costs, dtype=float), [self._complexity(g) for g in genomes]])
        for i in order:
            g = genomes[i]
            if seen.get(g, 0) < self.config.max_duplicates:
                seen[g] = seen.get(g, 0) + 1
                keep.append(int(i))
                if len(keep) == self.config.population:
                    break
        return [genomes[i] for i in keep], np.asarray(costs, dtype=float)[keep]

    def _complexity(self, genome: GenomeT) -> float:
        """The problem's ``complexity`` of ``genome`` (NSGA-II's second objective), else its length."""
        hook = getattr(self.problem, "complexity", None)
        return float(hook(genome)) if callable(hook) else float(len(genome))

    def _finish_generation(self, on_generation: Callable[[GenerationReport], None] | None) -> None:
        best_genome, best_cost = self.best
        if best_cost < self._last_best * (1.0 - self.config.stall_gain):
            self._stalled = 0
            self._last_best = best_cost  # the reference the next improvement is measured from
        elif self.generation > 0:
            self._stalled += 1
        state = self._state()
        self._stop = termination.stop_reason(self.config, state)
        self._progress = 1.0 if self._stop else max(self._progress, termination.progress(self.config, state))
        finite = self.costs[np.isfinite(self.costs)]
        mean = float(finite.mean()) if finite.size else math.inf
        self.history.append({"generation": self.generation, "best_fitness": best_cost, "mean_fitness": mean,
                             "seconds": state.seconds})
        if on_generation is not None:
            on_generation(GenerationReport(self.generation, best_cost, mean, best_genome, self.evaluations,
                                           state.seconds, self._progress))

    # ------------------------------------------------------------------ helpers
    def _evaluate(self, genomes: Sequence[GenomeT]) -> np.ndarray:
        """Costs of ``genomes``; only the ones not in the memo go to the evaluator (once each). The batch ends at
        its first cost at or below the threshold: computed serially in this process, the rest is not computed;
        from worker processes, the rest is dropped, so the run is the same. The genomes after it get inf and
        stay out of the memo (:meth:`_scored` leaves them out of the generation)."""
        todo = list(dict.fromkeys(g for g in genomes if g not in self.memo))
        if todo:
            try:
                results = list(self.evaluator(self._cost_fn, todo))
            except _Reached:
                todo = [g for g in todo if g in self.memo]
                results = [self.memo[g] for g in todo]
            else:
                if len(results) != len(todo):
                    raise ConfigError(f"evaluator returned {len(results)} costs for {len(todo)} genomes")
            hit = next((i for i, value in enumerate(results) if _clean_cost(value) <= self.config.threshold), None)
            if hit is not None:
                for g in todo[hit + 1:]:
                    self.memo.pop(g, None)
                todo, results = todo[:hit + 1], results[:hit + 1]
            best = self._best
            for g, value in zip(todo, results):
                c = _clean_cost(value)
                self.memo[g] = c
                if best is None or c < best[1]:
                    best = (g, c)
            self._best = best
        return np.array([self.memo.get(g, math.inf) for g in genomes], dtype=float)

    def _scored(self, genomes: list[GenomeT], costs: np.ndarray) -> tuple[list[GenomeT], np.ndarray]:
        """``genomes`` and ``costs`` without the genomes left unevaluated (a batch cut at the threshold)."""
        keep = [i for i, g in enumerate(genomes) if g in self.memo]
        if len(keep) == len(genomes):
            return genomes, costs
        return [genomes[i] for i in keep], np.asarray(costs, dtype=float)[keep]

    def _best_from_memo(self) -> None:
        """After an interrupt: include costs recorded during the unfinished batch."""
        best = self._best
        for g, c in self.memo.items():
            if best is None or c < best[1]:
                best = (g, c)
        self._best = best

    def _elapsed(self) -> float:
        return self._seconds + (time.perf_counter() - self._clock if self._clock is not None else 0.0)

    def _state(self) -> termination.RunState:
        return termination.RunState(generation=max(self.generation, 0), best_cost=self.best[1],
                                    first_best_cost=self._first_best, seconds=self._elapsed(),
                                    stalled_generations=self._stalled)


def start_or_resume(problem: Problem, config: GAConfig, seed: int | None = None, evaluator: Evaluator | None = None,
                    checkpoint: str | os.PathLike[str] | None = None, tag: str | None = None) -> GeneticAlgorithm:
    """A new run, or (when the ``checkpoint`` file exists) the run saved there, continued under ``config``."""
    if checkpoint is not None and os.path.lexists(checkpoint):
        return GeneticAlgorithm.resume(checkpoint, problem, evaluator=evaluator, config=config, tag=tag)
    return GeneticAlgorithm(problem, config, seed=seed, evaluator=evaluator, tag=tag)
