"""Stopping criteria and progress in 0..1 (for an ETA): each criterion reports how far along it is.

Threshold progress runs on a log scale from the first best cost to the threshold, because costs fall by
orders of magnitude; overall progress is the maximum over the active criteria.
"""

from __future__ import annotations

import dataclasses
import math

from .config import GAConfig


@dataclasses.dataclass(frozen=True)
class RunState:
    """What the criteria look at after a completed generation."""

    generation: int
    best_cost: float
    first_best_cost: float
    seconds: float
    stalled_generations: int


def threshold_progress(first_best: float, best: float, threshold: float) -> float:
    """Share of the way from ``first_best`` down to ``threshold`` on a log scale, in [0, 1]."""
    if best <= threshold:
        return 1.0
    if not (math.isfinite(best) and math.isfinite(first_best)) or threshold <= 0 or first_best <= threshold:
        return 0.0
    done = math.log(first_best / best) / math.log(first_best / threshold)
    return min(1.0, max(0.0, done))


def progress(config: GAConfig, state: RunState) -> float:
    """Overall progress: the furthest-along criterion (generations, threshold, time, stall)."""
    parts = [state.generation / config.generations,
             threshold_progress(state.first_best_cost, state.best_cost, config.threshold)]
    if config.max_seconds is not None:
        parts.append(state.seconds / config.max_seconds)
    if config.stall_generations is not None:
        parts.append(state.stalled_generations / config.stall_generations)
    return min(1.0, max(0.0, max(parts)))


def stop_reason(config: GAConfig, state: RunState) -> str | None:
    """``"threshold"``, ``"generations"``, ``"max_seconds"`` or ``"stall"`` once a criterion is met, else None."""
    if state.best_cost <= config.threshold:
        return "threshold"
    if state.generation >= config.generations:
        return "generations"
    if config.max_seconds is not None and state.seconds >= config.max_seconds:
        return "max_seconds"
    if config.stall_generations is not None and state.stalled_generations >= config.stall_generations:
        return "stall"
    return None
