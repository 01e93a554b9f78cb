"""What the GA engine needs from a problem; the engine knows nothing else of it.

Genes are opaque hashable items and a genome is a tuple of genes. The engine *minimises* ``cost``
(an error >= 0); roulette weights are the paper's inverse, ``1 / cost``.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any, Protocol, runtime_checkable

import numpy as np

Gene = Hashable
GenomeT = tuple[Gene, ...]


@runtime_checkable
class Problem(Protocol):
    """A search problem over variable-length gene sequences."""

    def random_gene(self, rng: np.random.Generator, prefix: GenomeT) -> Gene:
        """A random gene meant to apply after ``prefix`` (it may still turn out invalid)."""

    def repair(self, genome: GenomeT, rng: np.random.Generator) -> GenomeT:
        """Drop genes that cannot apply; top the genome up to the problem's minimum length."""

    def cost(self, genome: GenomeT) -> float:
        """Error of a repaired genome, >= 0, lower is better. Must be a pure function (memoised)."""

    def perturb(self, gene: Gene, rng: np.random.Generator) -> Gene:
        """The same kind of gene with its parameters nudged slightly (surface GA's specific mutation)."""


@runtime_checkable
class LocalSearch(Protocol):
    """Optional hook: a memetic polish of the best genome (e.g. least-squares moves appended as genes).

    Used every ``GAConfig.local_search_every`` generations; the engine repairs and evaluates the result
    and keeps it only if its cost is lower.
    """

    def local_search(self, genome: GenomeT) -> GenomeT:
        """A genome expected to cost no more than ``genome``."""


@runtime_checkable
class Niche(Protocol):
    """Optional hook: a hashable key grouping genomes of one kind (e.g. one mesh connectivity), so that
    ``GAConfig.local_search_count`` polishes the best genome of each of the best few kinds."""

    def niche(self, genome: GenomeT) -> Any:
        """The key of ``genome``'s niche."""


@runtime_checkable
class SeedGenomes(Protocol):
    """Optional hook: known-good genomes (repaired by the engine) put into the first population."""

    def seed_genomes(self) -> list[GenomeT]:
        """Genomes to include in the first population."""
