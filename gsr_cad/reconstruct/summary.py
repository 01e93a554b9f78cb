"""A result in words, for the CLI summary and the reports: distances both ways in model units and percent of
the diagonal, the requested tolerance met or not, why the search stopped, and the warnings a user needs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .config import REFINE_STALL_GAIN
from .blocks import BLOCK_PATH
from .leads import LEAD_PATH
from .result import Result
from .units import format_length, model_metrics, unit_label

STOP_REASONS = {
    "threshold": "fitness threshold reached",
    "generations": "generation limit reached",
    "max_seconds": "time limit reached",
    "stall": "no improvement for --stall-generations",
    "refine_stall": f"the search gained < {REFINE_STALL_GAIN:.0%} in --refine-stall generations; the refinement "
                    "took over",
    "interrupted": "interrupted (Ctrl-C)",
}

_DIRECTIONS = (("data to fit", "data_to_fit", ("mean_distance", "max_distance")),
               ("fit to data", "fit_to_data", ("mean_distance_to_target", "max_distance_to_target")))


def _real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)


def diagonal(result: Result) -> float:
    """The target's bounding-box diagonal in model units (1 when the result does not record it)."""
    target = (result.config or {}).get("target")
    value = target.get("diagonal") if isinstance(target, dict) else None
    return float(value) if _real(value) and value > 0 else 1.0


def units(result: Result) -> str:
    return str((result.config or {}).get("units") or "model")


def is_cloud(result: Result) -> bool:
    target = (result.config or {}).get("target")
    return isinstance(target, dict) and target.get("kind") == "cloud"


def add_model_units(result: Result) -> None:
    """Add ``units``, ``diagonal`` and ``*_model`` distances to ``result.metrics`` (before it is saved); a
    point-cloud target has no surface to measure the fit against, so its ``mean_distance_to_target`` goes."""
    if is_cloud(result):
        result.metrics.pop("mean_distance_to_target", None)
    result.metrics.update(model_metrics(result.metrics, diagonal(result), units(result)))


def two_sided(metrics: dict[str, Any]) -> list[tuple[str, float | None, float | None]]:
    """``(direction, mean, max)`` as fractions of the diagonal: the two-sided keys when present, else the
    older one-sided ones; None where a direction is not measured."""
    rows = []
    for label, key, (old_mean, old_max) in _DIRECTIONS:
        mean = metrics.get(f"{key}_mean", metrics.get(old_mean))
        top = metrics.get(f"{key}_max", metrics.get(old_max))
        rows.append((label, float(mean) if _real(mean) else None, float(top) if _real(top) else None))
    return rows


def tolerance_status(result: Result) -> tuple[float, bool] | None:
    """``(requested max distance, met)`` when the run asked for one (``--max-distance``), else None."""
    limit = (result.config or {}).get("max_distance")
    if not _real(limit):
        return None
    met = result.metrics.get("tolerance_met")
    if not isinstance(met, bool):
        worst = result.metrics.get("data_to_fit_max", result.metrics.get("max_distance"))
        met = _real(worst) and worst <= limit * (1 + 1e-9)
    return float(limit), bool(met)


def stop_text(result: Result) -> str:
    m = result.metrics
    reason = "interrupted" if result.interrupted else str(m.get("stop_reason", "?"))
    text = STOP_REASONS.get(reason, reason)
    gens, secs = m.get("generations"), m.get("seconds")
    extra = [f"{gens} generations" if _real(gens) else "", f"{secs:.2f} s" if _real(secs) else ""]
    return f"{text} ({', '.join(e for e in extra if e)})" if any(extra) else text


def distance_lines(result: Result) -> list[str]:
    """One line per direction: mean and max in model units and percent of the diagonal."""
    diag, unit = diagonal(result), units(result)
    lines = [f"  lengths in {unit_label(unit)} (and in % of the target's bounding-box diagonal, "
             f"{diag:.4g} {unit_label(unit)})"]
    for label, mean, top in two_sided(result.metrics):
        if mean is None and top is None:
            if is_cloud(result):
                lines.append(f"  {label}: not measured for a point cloud")
            continue
        parts = [f"mean distance {format_length(mean, diag, unit)}" if mean is not None else "",
                 f"max {format_length(top, diag, unit)}" if top is not None else ""]
        lines.append(f"  {label}: " + ", ".join(p for p in parts if p))
    status = tolerance_status(result)
    if status is not None:
        limit, met = status
        lines.append(f"  max-distance tolerance {format_length(limit, diag, unit)}: {'met' if met else 'MISSED'}")
    return lines


def headline(result: Result) -> str:
    """The first summary line: what was built and why the search stopped."""
    m = result.metrics
    if result.kind == "curve":
        built = f"{m.get('n_control_points', len(result.control_points))} control points"
    else:
        built = (f"{m.get('n_control_faces', '?')} control faces, {m.get('n_control_vertices', '?')} vertices, "
                 f"ops {run_length(str(m.get('ops', ''))) or '-'}")
    status = "interrupted: best so far" if result.interrupted else "done"
    return f"{status}: {built} from {len(result.genome)} ops; stopped: {stop_text(result)}"


def summary_lines(result: Result, out: Path | None = None) -> list[str]:
    """The headline (with the output directory), the distances both ways, the paper's measure for surfaces."""
    lines = [headline(result) + (f" -> {out}" if out is not None else ""), *distance_lines(result)]
    mixed = result.metrics.get("mixed_mean_distance")
    if result.kind == "surface" and _real(mixed):
        lines.append(f"  the paper's mixed mean distance: {mixed:.3g} of the diagonal (a pairing measure, not a "
                     "deviation: see README)")
    extra = (genus_line(result.metrics), legs_line(result.metrics), sharp_line(result.metrics))
    return lines + [line for line in extra if line]


def sharp_line(metrics: dict[str, Any]) -> str | None:
    """``sharp edges: ...`` when the result's cage holds creases set along the part's edges (module sharp)."""
    sharp = metrics.get("sharp_edges")
    if not isinstance(sharp, dict) or not sharp.get("creases"):
        return None
    text = f"  sharp edges: {sharp['creases']} control edges creased along the part's edges"
    grown = str(metrics.get("refined_from") or "")
    if (sharp.get("template_creases") and (grown.startswith("template") or grown == "front")
            and _real(sharp.get("template_distance")) and _real(sharp.get("creased_distance"))):
        text += (f" (the placed cube's {sharp['template_creases']}: {sharp['template_distance']:.2g} -> "
                 f"{sharp['creased_distance']:.2g} of the diagonal)")
    return text


def legs_line(metrics: dict[str, Any]) -> str | None:
    """``structure: the body's box with N legs/blocks ...`` when a designer's start (module starts) made the
    result; else None."""
    start = metrics.get("lead_start")
    if not isinstance(start, dict) or metrics.get("refined_from") not in (LEAD_PATH, BLOCK_PATH):
        return None
    sharp = f", {start['creases']} edges along the part's creased" if start.get("creases") else ""
    if metrics["refined_from"] == LEAD_PATH:
        lead = start.get("leads") or {}
        return (f"  structure: the body's box with {lead.get('grown', '?')} legs (an inset and extrusions each) "
                f"for the {lead.get('found', '?')} leads found on the target{sharp} (metrics.lead_start)")
    block = start.get("blocks") or {}
    return (f"  structure: the body's box with {block.get('grown', '?')} blocks (a region extrusion each) of the "
            f"{block.get('found', '?')} found standing on it{sharp} (metrics.lead_start)")


def genus_line(metrics: dict[str, Any]) -> str | None:
    """``genus: control mesh R, target T (method)``, saying DIFFERS when they do; None without genus metrics."""
    if "target_genus" not in metrics:
        return None
    got, want = metrics.get("result_genus"), metrics["target_genus"]
    text = (f"  genus: control mesh {'- (open)' if got is None else got}, target {want} "
            f"({metrics.get('target_genus_method', '?')})")
    return text + (" - DIFFERS: through-holes missing or extra" if metrics.get("genus_warning") else "")


def template_warning(template: Any, target: Any, source: str) -> str | None:
    """A warning when a ``--template`` file sits off the target (it is used where it is, not placed)."""
    if source == "cube" or template is None or target is None:
        return None
    lo, hi = template.vertices.min(axis=0), template.vertices.max(axis=0)
    t_lo, t_hi = np.asarray(target.bbox[0], float), np.asarray(target.bbox[1], float)
    diag = float(np.linalg.norm(t_hi - t_lo)) or 1.0
    offset = float(np.linalg.norm((lo + hi) / 2 - (t_lo + t_hi) / 2))
    ratio = float(np.linalg.norm(hi - lo)) / diag
    if offset <= 0.1 * diag and 0.5 <= ratio <= 2.0:
        return None
    return (f"warning: template {source} is used where it is, not placed on the target: its box centre is "
            f"{offset:.3g} model units ({100 * offset / diag:.3g} % of the diagonal) from the target's and its "
            f"diagonal {ratio:.2g} times the target's")


def warning_lines(result: Result) -> list[str]:
    out = []
    status = tolerance_status(result)
    if status is not None and not status[1]:
        diag, unit = diagonal(result), units(result)
        worst = result.metrics.get("data_to_fit_max", result.metrics.get("max_distance"))
        got = f"max distance {format_length(worst, diag, unit)}" if _real(worst) else "the max distance"
        out.append(f"warning: tolerance missed: {got} > --max-distance {format_length(status[0], diag, unit)}")
    if result.metrics.get("genus_warning"):
        out.append(f"warning: {result.metrics['genus_warning']}")
    return out


def run_length(letters: str) -> str:
    """Op letters with repeats counted: ``LVVVV`` -> ``L V4``; a history stored counted already (a long one's
    ``ops`` in result.json: ``L9 V296``) is returned as it is."""
    if any(c.isdigit() or c.isspace() for c in letters):
        return letters
    out, i = [], 0
    while i < len(letters):
        j = i
        while j < len(letters) and letters[j] == letters[i]:
            j += 1
        out.append(letters[i] + (str(j - i) if j - i > 1 else ""))
        i = j
    return " ".join(out)
