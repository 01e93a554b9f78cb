"""The GA engine on toy problems: both schemes, elitism, duplicates, memo, termination, progress,
reproducibility (also across evaluators), Ctrl-C, checkpoints, hooks and config validation."""

from __future__ import annotations

import ast
import collections
import dataclasses
import math
import pickle
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gsr_cad.ga
from gsr_cad.errors import ConfigError, InputError
from gsr_cad.ga import (DaskEvaluator, GAConfig, GenerationReport, GeneticAlgorithm, ProcessPoolEvaluator,
                        serial_evaluator)

TARGET = (1, 5, 2, 8, 3, 9, 0, 4)


class Seq:
    """Genes are ints 0..k-1, valid only if unequal to the previous gene; at least 3 genes.

    cost = index-wise |difference| to a target sequence + 10 per missing or extra gene. ``cost`` checks
    that it only ever sees repaired genomes.
    """

    def __init__(self, target=TARGET, k=10, offset=0.0):
        self.target, self.k, self.offset = tuple(target), k, offset
        self.repaired: set = set()
        self.n_repairs = 0
        self.n_perturbs = 0
        self.calls: list = []

    @staticmethod
    def valid(genome):
        return len(genome) >= 3 and all(a != b for a, b in zip(genome, genome[1:]))

    def random_gene(self, rng, prefix):
        return int(rng.integers(self.k))

    def repair(self, genome, rng):
        out: list = []
        for g in genome:
            if not out or out[-1] != g:
                out.append(g)
        while len(out) < 3:
            g = int(rng.integers(self.k))
            if out[-1:] != [g]:
                out.append(g)
        self.repaired.add(tuple(out))
        self.n_repairs += 1
        return tuple(out)

    def cost(self, genome):
        if not self.valid(genome):
            raise AssertionError(f"unrepaired genome evaluated: {genome}")
        self.calls.append(genome)
        return self.offset + float(sum(abs(a - b) for a, b in zip(genome, self.target))
                                   + 10 * abs(len(genome) - len(self.target)))

    def perturb(self, gene, rng):
        self.n_perturbs += 1
        return (gene + int(rng.choice((-1, 1)))) % self.k


class Interrupting(Seq):
    """Raises KeyboardInterrupt at the (n+1)-th cost call, as Ctrl-C would."""

    def __init__(self, n, **kw):
        super().__init__(**kw)
        self.n = n

    def cost(self, genome):
        if len(self.calls) == self.n:
            raise KeyboardInterrupt
        return super().cost(genome)


class Polished(Seq):
    """Genes from a large alphabet (the GA alone is hopeless); ``local_search`` returns the target."""

    def __init__(self, answer, **kw):
        super().__init__(**kw)
        self.answer = answer
        self.polish_calls = 0

    def local_search(self, genome):
        self.polish_calls += 1
        return self.answer


class Seeded(Seq):
    def seed_genomes(self):
        return [list(self.target)]


def small(scheme="steady_state", **kw):
    base = dict(initial_population=60, population=20, generations=15) if scheme == "steady_state" else \
        dict(initial_population=20, population=20, generations=15, min_initial_genes=1, max_initial_genes=2,
             n_parents=8, max_children=4, n_perturb=4, n_newcomers=4)
    return GAConfig(scheme=scheme, **{**base, **kw})


def snapshots(ga):
    seen = []
    return seen, lambda rep: seen.append((rep, list(ga.population), ga.costs.copy()))


def strip_seconds(history):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in history]


# ---------------------------------------------------------------- the schemes
def test_steady_state_cuts_a_tenth_keeps_elite_and_converges():
    problem = Seq()
    ga = GeneticAlgorithm(problem, GAConfig.paper_curves(generations=60), seed=1)
    seen, cb = snapshots(ga)
    result = ga.run(cb)
    rep0, pop0, costs0 = seen[0]
    assert rep0.generation == 0 and len(pop0) == 100
    first = problem.calls[:rep0.evaluations]
    assert set(pop0) <= set(first)
    all_first = np.array([Seq().cost(g) for g in first])
    assert costs0.mean() < all_first.mean()  # the roulette cut favours low costs
    for (_, prev, prev_c), (_, nxt, nxt_c) in zip(seen, seen[1:]):
        assert len(nxt) == 100
        assert list(prev_c) == sorted(prev_c)
        elite = collections.Counter(prev[:20])
        assert not elite - collections.Counter(nxt)  # the top 20 % survive unchanged
    assert result.stop_reason == "threshold" and result.best_cost == 0.0
    assert result.best_genome == TARGET
    assert len(result.history) == result.generations + 1


def test_plus_scheme_limits_duplicates_and_keeps_the_best():
    problem = Seq(target=(0, 1, 2, 1, 0, 2), k=3)  # three gene values: duplicates are everywhere
    ga = GeneticAlgorithm(problem, GAConfig.paper_surfaces(generations=30, threshold=0.0), seed=2)
    seen, cb = snapshots(ga)
    result = ga.run(cb)
    peak = 0
    for rep, pop, costs in seen:
        counts = collections.Counter(pop)
        assert max(counts.values()) <= 3
        peak = max(peak, max(counts.values()))
        assert len(pop) <= 100 and list(costs) == sorted(costs)
    assert peak == 3  # the limit was binding
    for (_, prev, prev_c), (_, nxt, nxt_c) in zip(seen, seen[1:]):
        assert nxt_c[0] <= prev_c[0]  # plus selection never loses the best
        new = len(set(nxt) - set(prev))
        assert new <= 10 + 10 + 10
    assert result.best_cost == 0.0 and result.best_genome == (0, 1, 2, 1, 0, 2)


def test_first_population_is_a_tenth_of_the_initial_one():
    problem = Seq(offset=0.5)
    seen = []
    ga = GeneticAlgorithm(problem, GAConfig.paper_curves(generations=1), seed=3)
    ga.run(lambda rep: seen.append((rep.generation, problem.n_repairs, len(ga.population))))
    assert seen[0] == (0, 1000, 100)  # 1000 random genomes, each repaired once, cut to 100
    assert seen[1] == (1, 1080, 100)  # then 80 offspring per generation


def test_plus_scheme_breeds_children_perturbations_and_newcomers():
    problem = Seq(offset=0.5)
    batches: list[int] = []

    def counting(fn, items):
        batches.append(len(items))
        return serial_evaluator(fn, items)

    ga = GeneticAlgorithm(problem, small("plus", generations=1), seed=3, evaluator=counting)
    seen = []
    ga.run(lambda rep: seen.append((problem.n_repairs, problem.n_perturbs)))
    assert seen[0] == (20, 0)  # 20 random genomes of 1..2 genes
    assert seen[1] == (20 + 4 + 4 + 4, 4)  # 4 children, the 4 best perturbed, 4 newcomers
    assert len(batches) == 2 and 1 <= batches[1] <= 12


def test_only_repaired_genomes_are_evaluated_and_each_once():
    problem = Seq()
    result = GeneticAlgorithm(problem, small(generations=20, threshold=0.0), seed=4).run()
    assert problem.calls and set(problem.calls) <= problem.repaired
    counts = collections.Counter(problem.calls)
    assert max(counts.values()) == 1  # the memo never re-evaluates
    assert result.evaluations == len(problem.calls)


def test_nan_cost_is_worst_and_negative_cost_is_an_error():
    class NanOdd(Seq):
        def cost(self, genome):
            return math.nan if genome[0] % 2 else super().cost(genome)

    result = GeneticAlgorithm(NanOdd(), small(generations=5), seed=5).run()
    assert math.isfinite(result.best_cost) and result.best_genome[0] % 2 == 0
    with pytest.raises(InputError, match=">= 0"):
        GeneticAlgorithm(Seq(offset=-100.0), small(), seed=5).run()


@settings(max_examples=25, deadline=None)
@given(scheme=st.sampled_from(["steady_state", "plus"]), population=st.integers(2, 30),
       extra=st.integers(0, 40), elite=st.floats(0.05, 0.95), genes=st.tuples(st.integers(1, 4), st.integers(0, 4)),
       rates=st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)), seed=st.integers(0, 2**32))
def test_invariants_hold_for_any_sane_config(scheme, population, extra, elite, genes, rates, seed):
    cfg = GAConfig(scheme=scheme, population=population, initial_population=population + extra, generations=4,
                   elite_fraction=elite, min_initial_genes=genes[0], max_initial_genes=genes[0] + genes[1],
                   mutation_rate=rates[0], delete_rate=rates[1], append_rate=rates[2],
                   n_parents=min(population, 6), n_perturb=min(population, 3), n_newcomers=3, max_children=3)
    try:
        cfg.validate()
    except ConfigError:
        return  # e.g. an elite fraction that rounds to nobody for this population
    problem = Seq(offset=0.5)
    ga = GeneticAlgorithm(problem, cfg, seed=seed)
    seen, cb = snapshots(ga)
    result = ga.run(cb)
    assert result.generations == 4 and len(result.history) == 5
    for rep, pop, costs in seen:
        assert list(costs) == sorted(costs) and all(Seq.valid(g) for g in pop)
        assert [ga.memo[g] for g in pop] == list(costs)
        assert len(pop) == population if scheme == "steady_state" else 1 <= len(pop) <= population
        assert rep.best_cost <= costs[0] and ga.memo[rep.best_genome] == rep.best_cost
    assert collections.Counter(problem.calls).most_common(1)[0][1] == 1


# ---------------------------------------------------------------- termination and progress
def test_generation_limit_and_progress_monotone():
    problem = Seq(offset=0.5)  # never reaches threshold 0
    reports: list[GenerationReport] = []
    result = GeneticAlgorithm(problem, small(generations=12), seed=6).run(reports.append)
    assert result.stop_reason == "generations" and result.generations == 12
    assert [r.generation for r in reports] == list(range(13))
    progress = [r.progress for r in reports]
    assert all(0.0 <= p <= 1.0 for p in progress) and progress == sorted(progress) and progress[-1] == 1.0
    best = [r.best_cost for r in reports]
    assert best == sorted(best, reverse=True)
    assert [h["best_fitness"] for h in result.history] == best
    assert all(r.evaluations <= s.evaluations for r, s in zip(reports, reports[1:]))


def test_threshold_stall_and_time_limits():
    r = GeneticAlgorithm(Seq(), small(generations=500, threshold=4.0), seed=7).run()
    assert r.stop_reason == "threshold" and r.best_cost <= 4.0 and r.generations < 500

    class Flat(Seq):
        def cost(self, genome):
            super().cost(genome)
            return 1.0

    reports = []
    r = GeneticAlgorithm(Flat(), small(generations=500, stall_generations=6), seed=7).run(reports.append)
    assert r.stop_reason == "stall" and r.generations == 6 and reports[-1].progress == 1.0
    r = GeneticAlgorithm(Seq(), small(generations=500, max_seconds=1e-9), seed=7).run()
    assert r.stop_reason == "max_seconds" and r.generations == 0


def test_stall_gain_stops_a_creeping_search():
    """Each generation's best is 0.5 % below the last: any gain resets the stall count, a 5 % gain rule ends
    the run once a window of generations gained less than 5 % together."""

    class Creep(Seq):
        def __init__(self):
            super().__init__()
            self.generation = 0

        def cost(self, genome):
            super().cost(genome)
            return 0.995 ** self.generation * (1.0 + 1e-3 * sum(genome) / (len(genome) * self.k))

    def run(**kwargs):
        problem = Creep()
        reports: list[GenerationReport] = []

        def on_generation(report):
            reports.append(report)
            problem.generation = report.generation + 1
            ga.memo.clear()  # the landscape moved on: remembered costs are stale

        ga = GeneticAlgorithm(problem, small(generations=60, stall_generations=4, **kwargs), seed=3)
        return ga.run(on_generation), reports

    plain, _ = run()
    assert plain.stop_reason == "generations"
    gained, reports = run(stall_gain=0.05)
    assert gained.stop_reason == "stall"
    best = [r.best_cost for r in reports]
    # the last improvement that counted was more than 5 %, every later one less in total
    assert best[-5] * 0.95 <= best[-1] < best[-5]
    assert gained.generations < plain.generations


# ---------------------------------------------------------------- reproducibility, interrupt, checkpoint
class Slow(Seq):
    """Each cost takes 20 ms: a first population of 60 would take 1.2 s."""

    def cost(self, genome):
        time.sleep(0.02)
        return super().cost(genome)


def test_time_budget_ends_a_slow_first_population_and_keeps_its_best():
    problem = Slow()
    started = time.perf_counter()
    r = GeneticAlgorithm(problem, small(generations=500, max_seconds=0.2), seed=7).run()
    assert time.perf_counter() - started < 0.8
    assert r.stop_reason == "max_seconds" and not r.interrupted
    calls = list(problem.calls)
    assert 1 <= len(calls) < 60
    assert r.best_cost == min(Seq().cost(g) for g in calls)


def run_history(seed, evaluator=None, scheme="steady_state"):
    with_pool = GeneticAlgorithm(Seq(offset=0.25), small(scheme, generations=10), seed=seed, evaluator=evaluator)
    result = with_pool.run()
    return strip_seconds(result.history), result.best_genome, result.best_cost, result.evaluations


@pytest.mark.parametrize("scheme", ["steady_state", "plus"])
def test_same_seed_same_run(scheme):
    assert run_history(8, scheme=scheme) == run_history(8, scheme=scheme)
    assert run_history(8, scheme=scheme) != run_history(9, scheme=scheme)


def test_seed_is_drawn_and_reported_when_not_given():
    ga = GeneticAlgorithm(Seq(offset=0.25), small(generations=3))
    result = ga.run()
    assert result.seed == ga.seed and isinstance(ga.seed, int)
    again = GeneticAlgorithm(Seq(offset=0.25), small(generations=3), seed=ga.seed).run()
    assert strip_seconds(again.history) == strip_seconds(result.history)


@pytest.mark.parametrize("context", [None, "spawn"])
def test_process_pool_matches_serial(context):
    with ProcessPoolEvaluator(max_workers=2, mp_context=context) as pool:
        assert run_history(10, pool) == run_history(10, serial_evaluator)
        assert run_history(11, pool, "plus") == run_history(11, None, "plus")


def test_process_pool_failure_propagates_and_pool_recovers():
    with ProcessPoolEvaluator(max_workers=2) as pool:
        with pytest.raises(AssertionError, match="unrepaired"):
            pool(Seq().cost, [(1, 1, 1)])
        assert pool(Seq().cost, [TARGET, (1, 2, 3)]) == [0.0, Seq().cost((1, 2, 3))]


def test_interrupt_returns_best_so_far_and_run_continues():
    problem = Interrupting(350)  # inside the first population of 1000
    ga = GeneticAlgorithm(problem, GAConfig.paper_curves(generations=5), seed=12)
    result = ga.run()
    assert result.interrupted and result.stop_reason == "interrupted"
    assert len(problem.calls) == 350 == result.evaluations
    costs = [Seq().cost(g) for g in problem.calls]
    assert result.best_cost == min(costs) and result.best_genome == problem.calls[int(np.argmin(costs))]
    problem.n = -1  # Ctrl-C no more
    done = ga.run()
    assert not done.interrupted and done.stop_reason in ("generations", "threshold")
    assert done.best_cost <= result.best_cost


def test_interrupt_in_a_later_generation_and_in_the_callback():
    problem = Interrupting(1200)
    result = GeneticAlgorithm(problem, GAConfig.paper_curves(generations=50, threshold=0.0), seed=13).run()
    assert result.interrupted and len(result.history) >= 1
    assert result.best_cost == min(Seq().cost(g) for g in problem.calls)

    def stop_at_3(rep):
        if rep.generation == 3:
            raise KeyboardInterrupt

    result = GeneticAlgorithm(Seq(offset=1), small(generations=50), seed=13).run(stop_at_3)
    assert result.interrupted and result.generations == 3 and len(result.history) == 4


@pytest.mark.parametrize("scheme", ["steady_state", "plus"])
def test_checkpoint_resume_continues_identically(tmp_path, scheme):
    path = tmp_path / "run.ckpt"
    ga = GeneticAlgorithm(Seq(offset=0.25), small(scheme, generations=12), seed=14)
    full = ga.run(lambda rep: ga.checkpoint(path) if rep.generation == 5 else None)
    resumed = GeneticAlgorithm.resume(path, Seq(offset=0.25))
    assert resumed.generation == 5 and resumed.seed == 14 and len(resumed.history) == 6
    tail = resumed.run()
    assert strip_seconds(tail.history) == strip_seconds(full.history)
    assert (tail.best_genome, tail.best_cost, tail.evaluations) == (full.best_genome, full.best_cost, full.evaluations)
    assert tail.generations == 12 and not list(tmp_path.glob(".*.tmp"))
    longer = GeneticAlgorithm.resume(path, Seq(offset=0.25), config=small(scheme, generations=20)).run()
    assert longer.generations == 20


def test_resume_rejects_missing_or_foreign_files(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        GeneticAlgorithm.resume(tmp_path / "nope.ckpt", Seq())
    junk = tmp_path / "junk.ckpt"
    junk.write_bytes(b"not a pickle at all")
    with pytest.raises(InputError, match="not a gsr_cad GA checkpoint"):
        GeneticAlgorithm.resume(junk, Seq())
    other = tmp_path / "other.ckpt"
    other.write_bytes(pickle.dumps({"some": "dict"}))
    with pytest.raises(InputError, match="not a gsr_cad GA checkpoint"):
        GeneticAlgorithm.resume(other, Seq())


# ---------------------------------------------------------------- hooks
def test_local_search_is_applied_every_k_generations_when_better():
    answer = (17, 400, 3, 999, 250, 61)
    problem = Polished(answer, target=answer, k=1000)
    result = GeneticAlgorithm(problem, small(generations=30, local_search_every=1), seed=15).run()
    assert result.stop_reason == "threshold" and result.generations == 0 and result.best_genome == answer

    worse = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)
    problem = Polished(worse, target=answer, k=1000, offset=0.5)
    ga = GeneticAlgorithm(problem, small(generations=6, local_search_every=2), seed=15)
    seen, cb = snapshots(ga)
    ga.run(cb)
    assert problem.polish_calls == 4  # generations 0, 2, 4, 6
    assert worse in ga.memo and all(worse not in pop for _, pop, _ in seen)

    off = Polished(answer, target=answer, k=1000)
    GeneticAlgorithm(off, small(generations=2), seed=15).run()
    assert off.polish_calls == 0


class Niched(Seq):
    """Niches by genome length; ``local_search`` records what it was given and returns it unchanged."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.polished = []

    def niche(self, genome):
        return len(genome)

    def local_search(self, genome):
        self.polished.append(genome)
        return genome


def test_local_search_count_polishes_the_best_of_each_of_the_best_niches():
    problem = Niched()
    ga = GeneticAlgorithm(problem, small(generations=1, local_search_every=1, local_search_count=3), seed=4)
    seen, cb = snapshots(ga)
    ga.run(cb)
    assert len(seen) == 2 and len(problem.polished) == 6
    for generation, (_, pop, _) in enumerate(seen):
        calls = problem.polished[3 * generation: 3 * generation + 3]
        lengths = []
        for g in pop:  # the first genome of each of the first three lengths, in cost order
            if len(g) not in lengths:
                lengths.append(len(g))
        assert [len(g) for g in calls] == lengths[:3]
        assert calls[0] == pop[0]
    with pytest.raises(ConfigError, match="local_search_count"):
        small(local_search_count=0).validate()


def test_seed_genomes_join_the_first_population():
    problem = Seeded()
    ga = GeneticAlgorithm(problem, small(generations=3), seed=16)
    seen, cb = snapshots(ga)
    result = ga.run(cb)
    assert TARGET in seen[0][1] and result.best_cost == 0.0 and result.stop_reason == "threshold"


# ---------------------------------------------------------------- configuration and evaluators
def test_paper_presets():
    c = GAConfig.paper_curves()
    assert (c.scheme, c.initial_population, c.population, c.min_initial_genes, c.max_initial_genes,
            c.elite_fraction, c.mutation_rate, c.delete_rate, c.n_elite) == \
        ("steady_state", 1000, 100, 4, 8, 0.2, 0.05, 0.01, 20)
    s = GAConfig.paper_surfaces()
    assert (s.scheme, s.population, s.generations, s.n_parents, s.max_children, s.n_perturb, s.n_newcomers,
            s.max_duplicates, s.min_initial_genes, s.max_initial_genes) == \
        ("plus", 100, 200, 20, 10, 10, 10, 3, 1, 2)
    assert GAConfig.from_dict(s.to_dict()) == s
    assert GAConfig.paper_surfaces(generations=1000, max_duplicates=10).max_duplicates == 10


@pytest.mark.parametrize("bad", [
    dict(population=0), dict(population=-5), dict(population=1), dict(generations=0), dict(initial_population=0),
    dict(mutation_rate=1.5), dict(delete_rate=-0.1), dict(append_rate=2), dict(elite_fraction=0.001),
    dict(elite_fraction=1.0), dict(elite_fraction=0.999), dict(threshold=-1.0), dict(threshold=math.nan),
    dict(min_initial_genes=0), dict(min_initial_genes=5, max_initial_genes=4), dict(scheme="genetic"),
    dict(population=10.5), dict(generations=True), dict(max_seconds=0), dict(stall_generations=0),
    dict(stall_gain=1.0), dict(stall_gain=-0.1), dict(stall_gain=math.nan),
    dict(local_search_every=-1), dict(mutation_rate="0.05"),
    dict(scheme="plus", n_parents=1), dict(scheme="plus", n_parents=200), dict(scheme="plus", max_duplicates=0),
    dict(scheme="plus", max_children=0, n_perturb=0, n_newcomers=0), dict(scheme="plus", n_perturb=101),
])
def test_absurd_configs_raise_config_error(bad):
    with pytest.raises(ConfigError):
        GAConfig(**bad).validate()
    with pytest.raises(ConfigError):
        GeneticAlgorithm(Seq(), GAConfig(**bad))


def test_bad_problem_seed_keys_and_evaluator():
    with pytest.raises(ConfigError, match="lacks .*cost"):
        GeneticAlgorithm(object.__new__(type("NoCost", (), {"random_gene": 1})), GAConfig())
    with pytest.raises(ConfigError, match="seed"):
        GeneticAlgorithm(Seq(), small(), seed=-3)
    with pytest.raises(ConfigError, match="unknown GA setting"):
        GAConfig.from_dict({"populaton": 10})
    with pytest.raises(ConfigError, match="evaluator returned"):
        GeneticAlgorithm(Seq(), small(), seed=1, evaluator=lambda fn, items: [0.0]).run()
    with pytest.raises(ConfigError, match="max_workers"):
        ProcessPoolEvaluator(max_workers=0)


def test_dask_evaluator_without_dask_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)
    with pytest.raises(ConfigError, match=r"gsr-cad\[dask\]"):
        DaskEvaluator()


def test_dask_evaluator_matches_serial():
    pytest.importorskip("dask.distributed")
    with DaskEvaluator(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as ev:
        assert run_history(17, ev) == run_history(17)


def test_engine_imports_nothing_of_geometry_ops_or_genome():
    forbidden = ("geometry", "ops", "genome", "reconstruct", "exporters", "cli", "plots")
    for path in Path(gsr_cad.ga.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + ([a.name for a in node.names] if node.level == 2 and not node.module
                                              else [])
                if node.level == 2:
                    assert not any(n.split(".")[0] in forbidden for n in names), (path.name, names)
                elif node.level == 0:
                    assert not (node.module or "").startswith("gsr_cad."), (path.name, node.module)
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("gsr_cad") for a in node.names), path.name


def test_report_and_result_fields():
    assert [f.name for f in dataclasses.fields(GenerationReport)] == [
        "generation", "best_cost", "mean_cost", "best_genome", "evaluations", "seconds", "progress"]
    result = GeneticAlgorithm(Seq(offset=0.25), small(generations=2), seed=18).run()
    assert set(result.history[0]) == {"generation", "best_fitness", "mean_fitness", "seconds"}
    assert result.seconds >= result.history[-1]["seconds"] >= result.history[0]["seconds"] >= 0


def test_a_batch_ends_at_its_first_cost_within_the_threshold():
    # the target first in the initial population: the rest of it is never evaluated, and a pool (which
    # computes the whole batch) gives the same run
    problem = Seeded()
    result = GeneticAlgorithm(problem, small("plus", threshold=0.0), seed=3).run()
    assert result.stop_reason == "threshold" and result.best_genome == TARGET
    assert problem.calls == [TARGET] and result.evaluations == 1 and len(result.history) == 1
    with ProcessPoolEvaluator(max_workers=2) as pool:
        pooled = GeneticAlgorithm(Seeded(), small("plus", threshold=0.0), seed=3, evaluator=pool).run()
    assert pooled.evaluations == 1 and strip_seconds(pooled.history) == strip_seconds(result.history)
    # a threshold met later in a batch: the steady-state population keeps its size
    seen_problem = Seq()
    ga = GeneticAlgorithm(seen_problem, small(threshold=4.0, generations=200), seed=7)
    seen, cb = snapshots(ga)
    r = ga.run(cb)
    assert r.stop_reason == "threshold" and r.best_cost <= 4.0
    assert all(len(pop) == 20 for _, pop, _ in seen)
    assert seen_problem.calls[-1] == r.best_genome  # nothing evaluated after the genome that met it


class SeededNear(Seq):
    """Its start is good, not perfect: one gene off the target (cost 1, where random genomes cost 10-40)."""

    def seed_genomes(self):
        return [list(self.target[:-1]) + [(self.target[-1] + 1) % self.k]]


@pytest.mark.parametrize("seed", range(12))
def test_seed_genomes_survive_the_cut_of_the_first_population(seed):
    """The large first population is cut by roulette; a start the problem gave keeps its place (a roulette
    over 60 genomes into 20 places drops an individual of 5x the mean weight often enough)."""
    problem = SeededNear(offset=5.0)  # flattens the roulette's weights: 1 / (5 + cost)
    start = tuple(problem.seed_genomes()[0])
    ga = GeneticAlgorithm(problem, small(generations=1, initial_population=200, population=10), seed=seed)
    seen, cb = snapshots(ga)
    ga.run(cb)
    assert start in seen[0][1]
