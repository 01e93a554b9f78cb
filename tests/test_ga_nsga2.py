"""NSGA-II survival in the plus scheme: rank and crowding on (cost, complexity), deterministic with the seed,
and the accuracy/complexity front of a surface run stays non-dominated."""

from __future__ import annotations

import numpy as np
import pytest

from gsr_cad.errors import ConfigError
from gsr_cad.ga import GAConfig, GeneticAlgorithm
from gsr_cad.ga.pareto import crowding, fronts, has_pymoo, non_dominated, nsga2_order
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import reconstruct_surface
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


class Sums:
    """Genes 1..9; the cost is how far the genome's sum is from 40 (longer genomes get closer); complexity
    is the length, so accuracy and complexity conflict."""

    def random_gene(self, rng, prefix):
        return int(rng.integers(1, 10))

    def repair(self, genome, rng):
        return tuple(genome[:12]) or (int(rng.integers(1, 10)),)

    def cost(self, genome):
        return abs(sum(genome) - 40) / 40 + 1e-3

    def perturb(self, gene, rng):
        return int(np.clip(gene + rng.integers(-1, 2), 1, 9))


def _run(survival: str, seed: int):
    config = GAConfig(scheme="plus", initial_population=30, population=30, min_initial_genes=1, max_initial_genes=3,
                      generations=15, n_parents=10, max_children=5, n_perturb=5, n_newcomers=5, survival=survival)
    return GeneticAlgorithm(Sums(), config, seed=seed)


def test_fronts_rank_and_crowding():
    F = np.array([[1, 5], [2, 3], [3, 1], [2, 4], [3, 3], [4, 4], [np.inf, 0]], dtype=float)
    ranks = fronts(F)
    assert [list(f) for f in ranks] == [[0, 1, 2], [3, 4], [5], [6]]
    d = crowding(F[[0, 1, 2]])
    assert np.isinf(d[0]) and np.isinf(d[2]) and np.isfinite(d[1])
    assert list(nsga2_order(F)[:3]) == [0, 2, 1]  # the front's extremes first
    if has_pymoo():
        rng = np.random.default_rng(4)
        G = np.c_[rng.integers(1, 20, 60), rng.random(60)]
        assert np.array_equal(fronts(G)[0], non_dominated(G, use_pymoo=False))


def test_nsga2_keeps_a_spread_of_the_front_and_is_deterministic():
    a, b = _run("nsga2", 3), _run("nsga2", 3)
    ra, rb = a.run(), b.run()
    assert a.population == b.population and ra.best_genome == rb.best_genome
    F = np.c_[a.costs, [len(g) for g in a.population]]
    first = non_dominated(F)
    assert len({len(a.population[i]) for i in first}) >= 3  # several complexities on the kept front
    costs = _run("cost", 3)
    costs.run()
    assert len({len(g) for g in a.population}) >= len({len(g) for g in costs.population}) - 1


def test_nsga2_needs_the_plus_scheme():
    with pytest.raises(ConfigError):
        GAConfig(scheme="steady_state", survival="nsga2").validate()
    with pytest.raises(ConfigError):
        GAConfig(scheme="plus", survival="spea2").validate()


def test_a_surface_run_with_nsga2_survival_has_a_non_dominated_front_and_repeats():
    target = surface_target(SURFACE_SAMPLES["inset_extrude"]().target, "ie")
    small = dict(population=10, initial_population=10, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
                 generations=2, final_polish_rounds=4, simplify_history=False, refine=False, survival="nsga2")
    one = reconstruct_surface(target, seed=5, **small)
    two = reconstruct_surface(target, seed=5, **small)
    assert one.genome == two.genome and one.metrics["front"] == two.metrics["front"]
    points = one.metrics["front"]
    assert points
    for p in points:
        assert not any(q is not p and q["vertices"] <= p["vertices"] and q["distance"] < p["distance"]
                       for q in points)
