"""GA settings: every number of the paper's two schemes is a field (DESIGN.md "The paper's settings").

``steady_state`` is the paper's curve scheme (section 3), ``plus`` its surface scheme (section 5).
Fields that a scheme does not use are ignored by it, so one config type serves both and the CLI.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from ..errors import ConfigError

SCHEMES = ("steady_state", "plus")
SURVIVALS = ("cost", "nsga2")
"""How the plus scheme picks its next population: the lowest costs, or NSGA-II's rank and crowding on (cost,
the problem's ``complexity``, else the genome's length)."""

_INT_FIELDS = ("initial_population", "population", "min_initial_genes", "max_initial_genes", "generations",
               "n_parents", "max_children", "n_perturb", "n_newcomers", "max_duplicates", "local_search_every",
               "local_search_count")
_RATE_FIELDS = ("mutation_rate", "delete_rate", "append_rate")


@dataclasses.dataclass(frozen=True)
class GAConfig:
    """Settings of one GA run; defaults are the paper's curve settings (see :meth:`paper_curves`).

    ``delete_rate`` is conditional: the chance that a gene *chosen for mutation* is deleted rather than
    replaced. ``append_rate`` (a chance per offspring) is not given in the paper. ``threshold`` is a cost:
    the run stops once the best cost is at or below it (0 means: only on a perfect fit).
    ``local_search_every`` = k > 0 polishes the best individual every k generations when the problem has a
    ``local_search`` hook; ``local_search_count`` = n polishes the best of each of the n best niches
    instead (niches by the problem's optional ``niche`` hook, else one per genome), so that a structure
    that needs a few polishes to show its worth is not starved by the incumbent. ``survival`` (plus scheme):
    ``"cost"`` keeps the lowest costs, ``"nsga2"`` NSGA-II's survival on (cost, complexity): a spread of the
    accuracy/complexity front rather than only the most accurate. ``stall_gain`` = g: a generation counts as
    an improvement for ``stall_generations`` only when it lowers the best cost below (1 - g) times the best at
    the last improvement, so that a search creeping by fractions of a percent is stalled too (0: any gain).
    """

    scheme: str = "steady_state"
    initial_population: int = 1000
    population: int = 100
    min_initial_genes: int = 4
    max_initial_genes: int = 8
    generations: int = 200
    elite_fraction: float = 0.2
    mutation_rate: float = 0.05
    delete_rate: float = 0.01
    append_rate: float = 0.1
    n_parents: int = 20
    max_children: int = 10
    n_perturb: int = 10
    n_newcomers: int = 10
    max_duplicates: int = 3
    threshold: float = 0.0
    max_seconds: float | None = None
    stall_generations: int | None = None
    stall_gain: float = 0.0
    local_search_every: int = 0
    local_search_count: int = 1
    survival: str = "cost"

    @classmethod
    def paper_curves(cls, **overrides: Any) -> GAConfig:
        """Section 3: 1000 genomes of 4..8 genes cut to 100, 20 % elite, 5 % mutation (1 % of it deletes)."""
        return cls.from_dict({"scheme": "steady_state", "initial_population": 1000, "population": 100,
                              "min_initial_genes": 4, "max_initial_genes": 8, **overrides})

    @classmethod
    def paper_surfaces(cls, **overrides: Any) -> GAConfig:
        """Section 5: 100 individuals, 200 generations, 20 parents -> up to 10 children, the 10 best perturbed,
        10 newcomers of 1..2 genes, at most 3 copies of a genome."""
        return cls.from_dict({"scheme": "plus", "initial_population": 100, "population": 100,
                              "min_initial_genes": 1, "max_initial_genes": 2, "generations": 200,
                              "n_parents": 20, "max_children": 10, "n_perturb": 10, "n_newcomers": 10,
                              "max_duplicates": 3, **overrides})

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GAConfig:
        """Build and validate a config from a mapping (e.g. ``result.json``'s config); unknown keys raise."""
        if not isinstance(data, dict):
            raise ConfigError("GA config must be a mapping of field names to values")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(f"unknown GA setting(s): {', '.join(unknown)}")
        return cls(**data).validate()

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able form (inverse of :meth:`from_dict`)."""
        return dataclasses.asdict(self)

    @property
    def n_elite(self) -> int:
        """How many of the best individuals the steady-state scheme keeps unchanged."""
        return int(round(self.elite_fraction * self.population))

    @property
    def n_children(self) -> int:
        """How many children the plus scheme breeds per generation (one per pair of parents)."""
        return min(self.max_children, self.n_parents // 2)

    def validate(self) -> GAConfig:
        """Return self, or raise ConfigError naming the first absurd value."""
        if self.scheme not in SCHEMES:
            raise ConfigError(f"scheme must be one of {', '.join(SCHEMES)}, not {self.scheme!r}")
        if self.survival not in SURVIVALS:
            raise ConfigError(f"survival must be one of {', '.join(SURVIVALS)}, not {self.survival!r}")
        if self.survival != "cost" and self.scheme != "plus":
            raise ConfigError(f"survival {self.survival!r} needs the plus scheme")
        for name in _INT_FIELDS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral):
                raise ConfigError(f"{name} must be an integer, not {value!r}")
        for name in ("elite_fraction", "threshold", "stall_gain", *_RATE_FIELDS):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
                raise ConfigError(f"{name} must be a finite number, not {value!r}")
        _at_least(self, "population", 2)
        _at_least(self, "initial_population", 1)
        _at_least(self, "min_initial_genes", 1)
        _at_least(self, "max_initial_genes", self.min_initial_genes)
        _at_least(self, "generations", 1)
        _at_least(self, "local_search_every", 0)
        _at_least(self, "local_search_count", 1)
        for name in _RATE_FIELDS:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"{name} must lie in [0, 1], not {getattr(self, name)}")
        if self.threshold < 0:
            raise ConfigError(f"threshold must be >= 0, not {self.threshold}")
        if self.max_seconds is not None and (isinstance(self.max_seconds, bool)
                                             or not isinstance(self.max_seconds, numbers.Real)
                                             or not self.max_seconds > 0):
            raise ConfigError(f"max_seconds must be a positive number or None, not {self.max_seconds!r}")
        if self.stall_generations is not None and (isinstance(self.stall_generations, bool)
                                                   or not isinstance(self.stall_generations, numbers.Integral)
                                                   or self.stall_generations < 1):
            raise ConfigError(f"stall_generations must be a positive integer or None, not {self.stall_generations!r}")
        if not 0.0 <= self.stall_gain < 1.0:
            raise ConfigError(f"stall_gain must lie in [0, 1), not {self.stall_gain}")
        if self.scheme == "steady_state":
            if not 0.0 < self.elite_fraction < 1.0 or self.n_elite < 1:
                raise ConfigError(f"elite_fraction {self.elite_fraction} keeps nobody of a population of "
                                  f"{self.population}")
            if self.n_elite >= self.population:
                raise ConfigError(f"elite_fraction {self.elite_fraction} leaves no room for offspring")
        else:
            _at_least(self, "n_parents", 2)
            _at_least(self, "max_children", 0)
            _at_least(self, "n_perturb", 0)
            _at_least(self, "n_newcomers", 0)
            _at_least(self, "max_duplicates", 1)
            if self.n_parents > self.population:
                raise ConfigError(f"n_parents ({self.n_parents}) exceeds the population ({self.population})")
            if self.n_perturb > self.population:
                raise ConfigError(f"n_perturb ({self.n_perturb}) exceeds the population ({self.population})")
            if self.n_children + self.n_perturb + self.n_newcomers == 0:
                raise ConfigError("the plus scheme needs children, perturbed individuals or newcomers")
        return self


def _at_least(config: GAConfig, name: str, low: int) -> None:
    value = getattr(config, name)
    if value < low:
        raise ConfigError(f"{name} must be >= {low}, not {value}")
