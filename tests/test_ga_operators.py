"""Selection, variation and termination of the GA engine, each on its own: measured against the
distributions they promise (binomial / chi-square bounds) and as hypothesis properties."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from gsr_cad.ga import (GAConfig, mutate, perturb_one, random_genome, roulette_select, roulette_weights,
                        single_point_crossover, threshold_progress)
from gsr_cad.ga import progress as overall_progress
from gsr_cad.ga import stop_reason
from gsr_cad.ga.termination import RunState

ALPHA = 1e-6  # two-sided tail mass allowed for every statistical bound below


def binomial_bounds(n: int, p: float) -> tuple[int, int]:
    lo, hi = stats.binom.interval(1 - ALPHA, n, p)
    return int(lo), int(hi)


class Tagged:
    """A problem whose random genes record the prefix they were drawn for: ("new", len(prefix))."""

    def __init__(self) -> None:
        self.repairs = 0

    def random_gene(self, rng, prefix):
        return ("new", len(prefix))

    def repair(self, genome, rng):
        self.repairs += 1
        return tuple(genome)

    def cost(self, genome):
        return float(len(genome))

    def perturb(self, gene, rng):
        return ("perturbed", gene)


# ---------------------------------------------------------------- crossover
@settings(max_examples=200, deadline=None)
@given(la=st.integers(0, 12), lb=st.integers(0, 12), seed=st.integers(0, 2**32 - 1))
def test_crossover_takes_a_prefix_of_a_and_the_rest_of_b(la, lb, seed):
    a = tuple(("a", i) for i in range(la))
    b = tuple(("b", i) for i in range(lb))
    child = single_point_crossover(a, b, np.random.default_rng(seed))
    cut = sum(1 for g in child if g[0] == "a")
    assert child == a[:cut] + b[cut:]
    assert len(child) == lb
    m = min(la, lb)
    assert (1 <= cut <= m - 1) if m >= 2 else (0 <= cut <= m)


def test_crossover_cut_is_uniform_within_the_shorter_parent():
    rng = np.random.default_rng(3)
    a, b = tuple(("a", i) for i in range(5)), tuple(("b", i) for i in range(9))
    cuts = [sum(g[0] == "a" for g in single_point_crossover(a, b, rng)) for _ in range(8000)]
    counts = np.bincount(cuts, minlength=5)
    assert counts[0] == 0 and counts[5:].sum() == 0
    assert stats.chisquare(counts[1:5]).pvalue > ALPHA


# ---------------------------------------------------------------- mutation
def mutate_many(n, length, rng, **rates):
    problem = Tagged()
    genome = tuple(("old", i) for i in range(length))
    return [mutate(genome, problem, rng, **rates) for _ in range(n)], problem


def test_mutation_and_deletion_rates_of_the_paper_are_binomial():
    rng = np.random.default_rng(11)
    n, length = 5000, 40
    outs, problem = mutate_many(n, length, rng, mutation_rate=0.05, delete_rate=0.01, append_rate=0.0)
    deleted = sum(length - len(g) for g in outs)
    replaced = sum(1 for g in outs for gene in g if gene[0] == "new")
    genes = n * length
    lo, hi = binomial_bounds(genes, 0.05 * 0.01)
    assert lo <= deleted <= hi
    lo, hi = binomial_bounds(genes, 0.05 * 0.99)
    assert lo <= replaced <= hi
    assert problem.repairs == 0  # mutate alone never repairs


def test_deletion_is_conditional_on_mutation_and_prefix_is_the_mutated_genome():
    rng = np.random.default_rng(12)
    n, length = 2000, 10
    outs, _ = mutate_many(n, length, rng, mutation_rate=1.0, delete_rate=0.3, append_rate=0.0)
    deleted = sum(length - len(g) for g in outs)
    lo, hi = binomial_bounds(n * length, 0.3)
    assert lo <= deleted <= hi
    for g in outs:  # every gene was replaced, each drawn for the genome built so far
        assert all(gene == ("new", i) for i, gene in enumerate(g))


def test_untouched_genes_keep_order_and_append_rate_is_binomial():
    rng = np.random.default_rng(13)
    n, length = 4000, 6
    outs, _ = mutate_many(n, length, rng, mutation_rate=0.0, delete_rate=0.5, append_rate=0.25)
    appended = 0
    for g in outs:
        assert g[:length] == tuple(("old", i) for i in range(length))
        assert len(g) in (length, length + 1)
        if len(g) == length + 1:
            assert g[-1] == ("new", length)
            appended += 1
    lo, hi = binomial_bounds(n, 0.25)
    assert lo <= appended <= hi


def test_random_genome_length_range_and_repair():
    rng = np.random.default_rng(14)
    problem = Tagged()
    lengths = [len(random_genome(problem, rng, 4, 8)) for _ in range(3000)]
    assert problem.repairs == 3000
    counts = np.bincount(lengths, minlength=9)
    assert counts[:4].sum() == 0 and counts[4:9].sum() == 3000
    assert stats.chisquare(counts[4:9]).pvalue > ALPHA


def test_perturb_one_changes_exactly_one_gene():
    rng = np.random.default_rng(15)
    problem = Tagged()
    genome = tuple(("old", i) for i in range(7))
    hits = np.zeros(7, int)
    for _ in range(2100):
        out = perturb_one(genome, problem, rng)
        diff = [i for i in range(7) if out[i] != genome[i]]
        assert len(out) == 7 and len(diff) == 1
        assert out[diff[0]] == ("perturbed", genome[diff[0]])
        hits[diff[0]] += 1
    assert problem.repairs == 2100
    assert stats.chisquare(hits).pvalue > ALPHA


# ---------------------------------------------------------------- roulette
def test_roulette_draws_are_proportional_to_inverse_cost():
    costs = np.array([0.5, 1.0, 2.0, 4.0, 8.0, 3.0])
    rng = np.random.default_rng(21)
    picks = roulette_select(costs, 30000, rng)
    counts = np.bincount(picks, minlength=costs.size)
    expected = (1 / costs) / (1 / costs).sum() * picks.size
    assert stats.chisquare(counts, expected).pvalue > ALPHA


def test_roulette_zero_cost_is_certain_and_bad_costs_are_worst():
    rng = np.random.default_rng(22)
    assert set(roulette_select([3.0, 0.0, 1.0], 500, rng)) == {1}
    both = roulette_select([0.0, 5.0, 0.0, 1e-320], 4000, rng)  # 1/1e-320 overflows: as certain as 0
    counts = np.bincount(both, minlength=4)
    assert counts[1] == 0 and min(counts[0], counts[2], counts[3]) > 1000
    picks = roulette_select([np.inf, 2.0, np.nan, 4.0], 3000, rng)
    assert set(picks) <= {1, 3}
    lo, hi = binomial_bounds(3000, 2 / 3)
    assert lo <= np.sum(picks == 1) <= hi
    uniform = roulette_select([np.inf, np.nan, np.inf], 3000, rng)
    assert stats.chisquare(np.bincount(uniform, minlength=3)).pvalue > ALPHA


def test_roulette_without_replacement_is_sequential_weighted_sampling():
    costs = np.array([1.0, 2.0, 4.0, np.inf, 0.5])
    rng = np.random.default_rng(23)
    firsts, seconds = [], []
    for _ in range(6000):
        order = roulette_select(costs, 5, rng, replace=False)
        assert sorted(order.tolist()) == [0, 1, 2, 3, 4]
        assert order[-1] == 3  # weight 0 comes last
        firsts.append(order[0])
        seconds.append(order[1])
    w = 1 / costs
    live = w > 0
    expected = w / w.sum() * 6000
    assert stats.chisquare(np.bincount(firsts, minlength=5)[live], expected[live]).pvalue > ALPHA
    # second pick: sum over first picks i of P(i) * w_j / (W - w_i)
    W = w.sum()
    p2 = np.array([sum(w[i] / W * w[j] / (W - w[i]) for i in range(5) if i != j) for j in range(5)])
    assert stats.chisquare(np.bincount(seconds, minlength=5)[live], p2[live] * 6000).pvalue > ALPHA
    with pytest.raises(ValueError):
        roulette_select(costs, 6, rng, replace=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.floats(0, 1e300), st.just(math.inf), st.just(math.nan)), min_size=1, max_size=30))
def test_roulette_weights_are_a_distribution_favouring_lower_costs(costs):
    p = roulette_weights(costs)
    assert p.shape == (len(costs),)
    assert np.all(p >= 0) and math.isclose(p.sum(), 1.0, rel_tol=1e-9)
    c = np.where(np.isnan(costs), np.inf, costs)
    for i in range(len(c)):
        for j in range(len(c)):
            if c[i] < c[j]:
                assert p[i] >= p[j]


def test_roulette_weights_of_costs_near_the_smallest_float_favour_them_without_overflow():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = roulette_weights([1e-308, 2e-308, 1.0, float("nan")])
    np.testing.assert_allclose(p, [2 / 3, 1 / 3, 0.0, 0.0], atol=1e-300)


# ---------------------------------------------------------------- termination
def test_threshold_progress_is_logarithmic():
    assert threshold_progress(100.0, 10.0, 1.0) == pytest.approx(0.5)
    assert threshold_progress(100.0, 100.0, 1.0) == 0.0
    assert threshold_progress(100.0, 0.5, 1.0) == 1.0
    assert threshold_progress(100.0, 5.0, 0.0) == 0.0
    assert threshold_progress(100.0, 0.0, 0.0) == 1.0


def test_progress_is_the_furthest_criterion_and_stop_reasons():
    cfg = GAConfig(generations=10, threshold=1.0, max_seconds=100.0, stall_generations=4)
    state = RunState(generation=2, best_cost=10.0, first_best_cost=100.0, seconds=30.0, stalled_generations=1)
    assert overall_progress(cfg, state) == pytest.approx(0.5)
    assert stop_reason(cfg, state) is None
    assert stop_reason(cfg, RunState(2, 1.0, 100.0, 30.0, 1)) == "threshold"
    assert stop_reason(cfg, RunState(10, 2.0, 100.0, 30.0, 1)) == "generations"
    assert stop_reason(cfg, RunState(3, 2.0, 100.0, 100.0, 1)) == "max_seconds"
    assert stop_reason(cfg, RunState(3, 2.0, 100.0, 1.0, 4)) == "stall"
    assert overall_progress(cfg, RunState(3, 2.0, 100.0, 1.0, 4)) == 1.0
