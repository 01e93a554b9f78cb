"""A result's modelling history replayed prefix by prefix, for the reports (the paper's Figures 3 and 6).

Shared by :mod:`gsr_cad.plots` (report.png) and :mod:`gsr_cad.html_report` (report.html); numpy only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import genome as genome_mod
from .errors import GsrError
from .ops import curve as curve_ops
from .reconstruct.result import Result


def curve_template(result: Result, target_points: np.ndarray) -> curve_ops.Polygon:
    """The template the curve genome starts from: the one stored in the config, else the paper's template
    of ``target_points`` with the run's box margin (what :func:`reconstruct_curve` builds)."""
    cfg = result.config or {}
    if "template" in cfg and cfg.get("bounds"):
        lo, hi = cfg["bounds"]
        return curve_ops.Polygon(np.asarray(cfg["template"], dtype=float), tuple(lo), tuple(hi))
    return curve_ops.template(target_points, margin=float(cfg.get("bounds_margin", 1.0)))


def surface_template(result: Result) -> Any:
    """The surface genome's template: the in-memory one, else the one stored in the config, else None."""
    from .reconstruct.surface import template_from_config

    template = getattr(result, "template", None)
    if template is not None:
        return template
    try:
        return template_from_config(result.config or {})
    except GsrError:
        return None


def replayed(template: Any, genome: tuple) -> list[Any] | None:
    """The template and the state after each op, or None when the genome does not replay on it."""
    if template is None:
        return None
    try:
        return genome_mod.replay_states(template, genome)
    except GsrError:
        return None


def step_indices(n_ops: int, max_steps: int) -> list[int]:
    """Up to ``max_steps`` prefix lengths from 0 (the template) to ``n_ops`` (the result), evenly spread."""
    count = min(max_steps, n_ops + 1)
    return sorted({int(k) for k in np.round(np.linspace(0, n_ops, count))})


def op_label(op: Any) -> str:
    """A short label of one op: its letter (surfaces) or name (curves)."""
    return getattr(op, "letter", "") or getattr(op, "name", type(op).__name__)


def op_text(op: Any) -> str:
    """A sentence for one op (its ``describe()``, else its label)."""
    try:
        return str(op.describe())
    except (AttributeError, NotImplementedError):
        return op_label(op)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-300), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def curve_op_sizes(states: list[curve_ops.Polygon], genome: tuple) -> np.ndarray:
    """Per curve op, how much it changes the polygon, in model units: a move its distance, an insertion
    the new point's distance from the edge it splits (0: a point on the edge, the curve barely changes)."""
    sizes = np.zeros(len(genome))
    for k, op in enumerate(genome):
        if op.name == "move_point":
            sizes[k] = float(np.linalg.norm(np.asarray(op.delta, dtype=float)))
        elif op.name == "add_point":
            pts = states[k].points
            sizes[k] = _segment_distance(np.asarray(op.position, dtype=float), pts[op.index - 1], pts[op.index])
    return sizes
