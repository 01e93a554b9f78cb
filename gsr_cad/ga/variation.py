"""Variation operators on genomes (tuples of opaque genes): pure functions of their inputs and the rng.

Only :func:`offspring`, :func:`random_genome` and :func:`perturb_one` call ``problem.repair``; the parts
(:func:`single_point_crossover`, :func:`mutate`) return raw genomes so they can be measured alone.
"""

from __future__ import annotations

import numpy as np

from .problem import GenomeT, Problem


def single_point_crossover(a: GenomeT, b: GenomeT, rng: np.random.Generator) -> GenomeT:
    """``a[:cut] + b[cut:]`` with the cut inside the shorter parent, so parents of any lengths combine.

    The cut lies in ``1 .. m-1`` (m = the shorter length) so the child takes genes from both parents;
    if the shorter parent has fewer than two genes the cut lies in ``0 .. m``. The child has ``len(b)`` genes.
    """
    m = min(len(a), len(b))
    cut = int(rng.integers(1, m)) if m >= 2 else int(rng.integers(0, m + 1))
    return tuple(a[:cut]) + tuple(b[cut:])


def mutate(genome: GenomeT, problem: Problem, rng: np.random.Generator, mutation_rate: float,
           delete_rate: float, append_rate: float) -> GenomeT:
    """The paper's mutation, without repair.

    Each gene mutates with probability ``mutation_rate``; a mutating gene is deleted with probability
    ``delete_rate``, else replaced by ``problem.random_gene(rng, prefix)`` where ``prefix`` is the mutated
    genome built so far. Afterwards one random gene is appended with probability ``append_rate``.
    """
    out: list = []
    draws = rng.random(len(genome))
    for gene, u in zip(genome, draws):
        if u >= mutation_rate:
            out.append(gene)
        elif rng.random() >= delete_rate:
            out.append(problem.random_gene(rng, tuple(out)))
    if rng.random() < append_rate:
        out.append(problem.random_gene(rng, tuple(out)))
    return tuple(out)


def offspring(a: GenomeT, b: GenomeT, problem: Problem, rng: np.random.Generator, mutation_rate: float,
              delete_rate: float, append_rate: float) -> GenomeT:
    """One child of parents ``a`` and ``b``: crossover, mutation, then ``problem.repair``."""
    child = single_point_crossover(a, b, rng)
    child = mutate(child, problem, rng, mutation_rate, delete_rate, append_rate)
    return tuple(problem.repair(child, rng))


def random_genome(problem: Problem, rng: np.random.Generator, min_genes: int, max_genes: int) -> GenomeT:
    """A fresh repaired genome of ``min_genes .. max_genes`` random genes, built gene by gene."""
    n = int(rng.integers(min_genes, max_genes + 1))
    genes: list = []
    for _ in range(n):
        genes.append(problem.random_gene(rng, tuple(genes)))
    return tuple(problem.repair(tuple(genes), rng))


def perturb_one(genome: GenomeT, problem: Problem, rng: np.random.Generator) -> GenomeT:
    """The surface scheme's specific mutation: one random gene replaced by ``problem.perturb(gene)``, repaired."""
    if not genome:
        return tuple(problem.repair((), rng))
    i = int(rng.integers(len(genome)))
    changed = genome[:i] + (problem.perturb(genome[i], rng),) + genome[i + 1:]
    return tuple(problem.repair(changed, rng))
