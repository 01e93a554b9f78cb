"""Problem-agnostic genetic algorithm engine: genes are opaque hashable items, genomes tuples of them.

The engine minimises ``problem.cost`` and imports no geometry, ops or genome module.
"""

from .config import SCHEMES, GAConfig
from .engine import GenerationReport, GeneticAlgorithm, RunResult, fingerprint, start_or_resume
from .evaluators import DaskEvaluator, Evaluator, ProcessPoolEvaluator, serial_evaluator
from .problem import Gene, GenomeT, LocalSearch, Niche, Problem, SeedGenomes
from .selection import roulette_select, roulette_weights
from .termination import progress, stop_reason, threshold_progress
from .variation import mutate, offspring, perturb_one, random_genome, single_point_crossover

__all__ = [
    "SCHEMES", "GAConfig", "GenerationReport", "GeneticAlgorithm", "RunResult", "DaskEvaluator", "Evaluator",
    "ProcessPoolEvaluator", "serial_evaluator", "Gene", "GenomeT", "LocalSearch", "Niche", "Problem", "SeedGenomes",
    "roulette_select", "roulette_weights", "progress", "stop_reason", "threshold_progress", "mutate",
    "offspring", "perturb_one", "random_genome", "single_point_crossover",
    "fingerprint", "start_or_resume",
]
