"""Cooperative stop of the GA engine: ``should_stop`` is polled before every in-process evaluation and while
a process pool works, so a run asked to stop returns its best so far within moments; checkpoints are
written every generation and refused when they belong to another run."""

from __future__ import annotations

import time

import pytest

from gsr_cad.errors import InputError
from gsr_cad.ga import GAConfig, GeneticAlgorithm, ProcessPoolEvaluator, fingerprint, start_or_resume


class Slow:
    """Genes 0..9, cost = distance to a target sequence; every evaluation sleeps ``delay`` seconds."""

    target = (3, 1, 4, 1, 5, 9, 2, 6)

    def __init__(self, delay: float = 0.05) -> None:
        self.delay = delay

    def random_gene(self, rng, prefix):
        return int(rng.integers(10))

    def repair(self, genome, rng):
        return tuple(genome) if len(genome) >= 1 else (int(rng.integers(10)),)

    def cost(self, genome):
        time.sleep(self.delay)
        return float(sum(abs(a - b) for a, b in zip(genome, self.target)) + 10 * abs(len(genome) - 8))

    def perturb(self, gene, rng):
        return (gene + 1) % 10


CONFIG = GAConfig(population=40, initial_population=40, generations=1000, threshold=0.0)


def _stop_in(seconds: float):
    end = time.monotonic() + seconds
    return lambda: time.monotonic() > end


def test_serial_run_stops_within_one_evaluation():
    ga = GeneticAlgorithm(Slow(), CONFIG, seed=1)
    started = time.monotonic()
    run = ga.run(should_stop=_stop_in(0.5))
    assert run.interrupted and run.stop_reason == "interrupted"
    assert time.monotonic() - started < 0.5 + 0.5
    assert run.best_genome and run.evaluations > 0


def test_process_pool_run_stops_while_the_pool_works():
    with ProcessPoolEvaluator(max_workers=2) as pool:
        ga = GeneticAlgorithm(Slow(0.2), CONFIG, seed=1, evaluator=pool)
        started = time.monotonic()
        run = ga.run(should_stop=_stop_in(1.0))
        took = time.monotonic() - started
    assert run.interrupted
    assert took < 1.0 + 1.5, took


def test_checkpoint_every_generation_and_tag(tmp_path):
    ck = tmp_path / "ga.ckpt"
    tag = fingerprint("seq", (1, 2, 3))
    ga = GeneticAlgorithm(Slow(0.0), GAConfig(population=10, initial_population=10, generations=4), seed=2, tag=tag)
    seen = []
    ga.run(on_generation=lambda r: seen.append(ck.stat().st_mtime_ns), checkpoint=ck)
    assert len(seen) == 5 and ck.exists()
    again = start_or_resume(Slow(0.0), GAConfig(population=10, initial_population=10, generations=4), None, None,
                            ck, tag)
    assert again.generation == 4 and again.best == ga.best
    with pytest.raises(InputError, match="another run"):
        start_or_resume(Slow(0.0), GAConfig(population=10, initial_population=10, generations=4), None, None, ck,
                        fingerprint("other"))
    assert fingerprint("a", 1) == fingerprint("a", 1) != fingerprint("a", 2)
