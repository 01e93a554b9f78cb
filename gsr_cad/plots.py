"""Figures of reconstruction results (``report.png``), laid out like the paper's Figures 3, 5 and 6 (planar
and space curves, surfaces).

Lengths are drawn in the result's model units (``config["units"]``), with percent of the target's
bounding-box diagonal on a second axis, as in the summary and ``report.html``. matplotlib is imported
inside the functions and drives an Agg canvas directly (no pyplot, no global backend switch), so importing
gsr_cad stays cheap and plotting works headless and from threads.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import history as hist
from .atomic import atomic_path
from .errors import InputError
from .reconstruct.result import Result
from .reconstruct.summary import STOP_REASONS, distance_lines, headline, run_length, tolerance_status, units
from .reconstruct.units import unit_label

__all__ = ["ADD_COLOUR", "CURVE_SAMPLES", "MOVE_COLOUR", "curve_figure", "curve_report", "curve_form", "deviation_along_curve", "sample_curve",
           "run_length", "surface_figure", "surface_report", "target_feet"]

if TYPE_CHECKING:
    from matplotlib.figure import Figure

ADD_COLOUR = "#f2b705"   # the paper's yellow bars: vertex insertion
MOVE_COLOUR = "#d62728"  # the paper's red bars: vertex movement, height = distance moved
OTHER_COLOUR = "#8c8c8c"
CURVE_SAMPLES = 1200     # points of the result curve drawn and measured
STRIP_STEPS = 8          # panels of the op-history strip
SPACE_ASPECT = 0.75      # height / width of a 3D curve panel
TOLERANCE_COLOUR = "#2ca02c"



def _plain(text: str) -> str:
    """``text`` (a file name, a title) drawn as written: its dollar signs escaped, so matplotlib's mathtext,
    which the axes' own labels need, never parses user text."""
    return str(text).replace("$", r"\$")

def _points(a: Any, what: str, dim: int | None = None) -> np.ndarray:
    """``a`` as at least 2 finite rows of x, y or x, y, z (of ``dim`` columns when given), else InputError."""
    pts = np.asarray(a, dtype=float)
    dims = (2, 3) if dim is None else (dim,)
    if pts.ndim != 2 or pts.shape[1] not in dims or len(pts) < 2 or not np.all(np.isfinite(pts)):
        rows = " or ".join({2: "x, y", 3: "x, y, z"}[d] for d in dims)
        like = " (the target points' dimension)" if dim is not None else ""
        raise InputError(f"{what} must be at least 2 finite {rows} rows{like}, got an array of shape {pts.shape}")
    return pts


def curve_form(result: Result) -> tuple[bool, tuple[int, ...]]:
    """A curve result's form: whether it is closed (periodic) and its corner control points."""
    cfg = result.config or {}
    return bool(cfg.get("closed", False)), tuple(int(i) for i in cfg.get("corners", ()) or ())


def sample_curve(ctrl: np.ndarray, n: int, degree: int, closed: bool = False, corners=()) -> np.ndarray:
    """``n`` curve points at evenly spaced parameters of the curve form (a closed curve ends where it starts)."""
    from .geometry.bspline import make_spline, sample_uniform

    if not closed and not corners:
        return sample_uniform(ctrl, n, degree)
    return make_spline(ctrl, degree, closed, corners)(np.linspace(0.0, 1.0, n))


def deviation_along_curve(ctrl: np.ndarray, target: np.ndarray, degree: int, n: int = CURVE_SAMPLES,
                          closed: bool = False, corners=()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` evenly spaced curve points, the target's deviation there, and each target point's distance.

    Each target point is projected onto the curve (foot point); its distance is carried to the curve at
    the foot's parameter and interpolated between feet. This is the distance the metrics report, so the
    colour bar's top equals the max distance, and an exact fit shows as zero even for sparse data (the
    chords between sparse points would show their sag as error).
    """
    from .geometry.distance import point_to_polyline

    if len(ctrl) <= degree:  # too few points for a curve: the polygon stands in for it
        return ctrl, point_to_polyline(ctrl, target), point_to_polyline(target, ctrl)
    curve = sample_curve(ctrl, n, degree, closed, corners)
    params, dist = target_feet(ctrl, target, degree, curve, closed, corners)
    order = np.argsort(params, kind="stable")
    return curve, np.interp(np.linspace(0.0, 1.0, n), params[order], dist[order]), dist


def target_feet(ctrl: np.ndarray, target: np.ndarray, degree: int, curve: np.ndarray | None = None,
                closed: bool = False, corners=()) -> tuple[np.ndarray, np.ndarray]:
    """Each target point's foot parameter on the curve (in [0, 1]) and its distance to the curve."""
    from scipy.spatial import cKDTree

    from .geometry.bspline import make_spline
    from .geometry.distance import spline_foot_points

    curve = sample_curve(ctrl, CURVE_SAMPLES, degree, closed, corners) if curve is None else curve
    _, nearest = cKDTree(curve).query(target)
    spline = make_spline(ctrl, degree, closed, corners)
    return spline_foot_points(spline, np.asarray(target, dtype=float), nearest / (len(curve) - 1), periodic=closed)


def _fmt(x: float) -> str:
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e4 or x == 0 else f"{x:.2e}"


def _subtitle(result: Result) -> str:
    """The summary's headline and distances (both ways, model units and %), one per line."""
    return "\n".join([headline(result), *(line.strip() for line in distance_lines(result))])


def _percent_axis(ax, diag: float, which: str = "y", label: str = "% of diagonal") -> None:
    """A second axis on ``ax`` giving its model-unit lengths in percent of ``diag``."""
    def to_pct(v):
        return 100.0 * np.asarray(v) / diag

    def from_pct(v):
        return np.asarray(v) * diag / 100.0

    side = "right" if which == "y" else "top"
    axis = (ax.secondary_yaxis if which == "y" else ax.secondary_xaxis)(side, functions=(to_pct, from_pct))
    axis.set_ylabel(label, fontsize=8) if which == "y" else axis.set_xlabel(label, fontsize=8)
    axis.tick_params(labelsize=7)


def _draw_genome(ax, genome: Sequence[Any], sizes: np.ndarray | None, unit: str) -> None:
    """One bar per op in order: yellow insertions, red moves; height = how much the op changes the polygon
    (:func:`gsr_cad.history.curve_op_sizes`; moves only, when the genome cannot be replayed)."""
    from matplotlib.patches import Patch

    ax.set_title(f"genome: {len(genome)} operations, applied left to right; height: how far each moves the "
                 "polygon", loc="left", fontsize=10)
    if not genome:
        ax.text(0.5, 0.5, "empty genome (template only)", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    names = [getattr(op, "name", type(op).__name__) for op in genome]
    if sizes is None:
        moves = [float(np.linalg.norm(np.asarray(op.delta, float))) if n == "move_point" else np.nan
                 for op, n in zip(genome, names)]
        top = np.nanmax(moves) if np.any(np.isfinite(moves)) else 1.0
        sizes = np.where(np.isfinite(moves), moves, top)
    top = float(np.max(sizes)) if len(sizes) and np.max(sizes) > 0 else 1.0
    x = np.arange(1, len(names) + 1)
    colours = [MOVE_COLOUR if k == "move_point" else ADD_COLOUR if k == "add_point" else OTHER_COLOUR for k in names]
    ax.bar(x, sizes, width=0.8 if len(names) < 150 else 1.0, color=colours, linewidth=0)
    ax.set_xlim(0.4, max(len(names), 12) + 0.6)  # short genomes keep bar-like bars
    ax.set_ylim(0, top * 1.25)
    ax.set_ylabel(f"change, {unit}", fontsize=9)
    ax.set_xlabel("operation")
    ax.xaxis.get_major_locator().set_params(integer=True)
    counts = {k: names.count(k) for k in set(names)}
    handles = [Patch(color=ADD_COLOUR, label=f"add_point ({counts.get('add_point', 0)}): off its edge"),
               Patch(color=MOVE_COLOUR, label=f"move_point ({counts.get('move_point', 0)}): distance moved")]
    others = sum(v for k, v in counts.items() if k not in ("add_point", "move_point"))
    if others:
        handles.append(Patch(color=OTHER_COLOUR, label=f"other ({others})"))
    ax.legend(handles=handles, loc="upper right", fontsize=8, ncols=len(handles), framealpha=0.9)


def _search_story(history: Sequence[dict[str, Any]], interrupted: bool, metrics: dict[str, Any]) -> str:
    """Two short lines: how long the search ran and why it stopped, then what came after it."""
    gens = metrics.get("generations", len(history))
    first = [f"{gens} generations"]
    if isinstance(metrics.get("evaluations"), (int, float)):
        first.append(f"{int(metrics['evaluations'])} evaluations")
    seconds = history[-1].get("seconds") if history else None
    if isinstance(seconds, (int, float)):
        first.append(f"{seconds:.1f} s")
    reason = metrics.get("stop_reason")
    line = "convergence: " + ", ".join(first)
    if interrupted:
        line += " (interrupted): best so far"
    elif isinstance(reason, str):
        line += f"; stopped: {STOP_REASONS.get(reason, reason)}"
    after = [f"{label} {metrics[key]:.1f} s" for key, label in (("polish_seconds", "final polish"),
                                                                 ("simplify_seconds", "history rewrite"))
             if isinstance(metrics.get(key), (int, float))]
    return line + ("\nthen " + ", ".join(after) if after else "")


def _draw_convergence(ax, history: Sequence[dict[str, Any]], interrupted: bool, metrics: dict[str, Any]) -> None:
    gens, best, mean = [], [], []
    for i, h in enumerate(history):
        gens.append(h.get("generation", i))
        best.append(h.get("best_fitness", math.nan))
        mean.append(h.get("mean_fitness", math.nan))
    gens_a, best_a, mean_a = (np.asarray(v, dtype=float) for v in (gens, best, mean))
    ax.set_title(_search_story(history, interrupted, metrics), loc="left", fontsize=9)
    ax.set_xlabel("generation")
    ax.set_ylabel("cost (lower is better)", fontsize=9)
    finite = np.concatenate([best_a[np.isfinite(best_a)], mean_a[np.isfinite(mean_a)]])
    if finite.size == 0:
        ax.text(0.5, 0.5, "no generation completed", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    log = bool(np.all(finite > 0))
    style = dict(marker="o", markersize=3) if len(history) < 30 else {}
    ax.plot(gens_a, mean_a, color="#1f77b4", linestyle="--", label="population mean", **style)
    ax.plot(gens_a, best_a, color="black", label="best", **style)
    better = np.flatnonzero(np.diff(best_a) < 0) + 1
    if better.size:
        ax.scatter(gens_a[better], best_a[better], s=22, color=MOVE_COLOUR, zorder=4,
                   label=f"best improved ({better.size}x)")
    ax.xaxis.get_major_locator().set_params(integer=True)
    if log:
        ax.set_yscale("log")
        if finite.max() / finite.min() < 30:  # under ~1.5 decades: a few plain-number ticks, no crowding
            from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

            lo, hi = float(finite.min()), float(finite.max())
            ticks = np.geomspace(lo, hi, 4) if hi > lo else np.array([lo])
            ax.yaxis.set_major_locator(FixedLocator(ticks))
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: _fmt(v)))
            ax.yaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, which="major", alpha=0.3)
    kind = metrics.get("fitness_kind")
    legend = ax.legend(loc="upper right", fontsize=8, title=str(kind) if isinstance(kind, str) else None)
    if legend.get_title():
        legend.get_title().set_fontsize(7)


def _save(fig: Figure, path: str | os.PathLike[str], dpi: int) -> Path:
    """Write ``fig`` to ``path`` atomically, in the format its suffix names (PNG without one)."""
    target_path = Path(path)
    with atomic_path(target_path) as tmp:
        fig.savefig(tmp, format=target_path.suffix.lstrip(".").lower() or "png", dpi=dpi)
    return target_path


def curve_report(result: Result, target_points: np.ndarray, path: str | os.PathLike[str],
                 truth: np.ndarray | None = None, *, title: str | None = None, dpi: int = 110) -> Path:
    """Write :func:`curve_figure` to ``path`` atomically (format from the suffix, PNG by default); returns it."""
    return _save(curve_figure(result, target_points, truth, title=title), path, dpi)


def curve_figure(result: Result, target_points: np.ndarray, truth: np.ndarray | None = None, *,
                 title: str | None = None) -> Figure:
    """The paper's Figure 3 for one curve result, as a matplotlib Figure on an Agg canvas; a space curve's
    geometry rows (1, 2 and 4) are 3D views at equal scale on x, y and z, with its three orthographic
    projections (top, front, side) after row 2.

    Rows: (1) result curve over the target points, coloured by the target's distance to it
    (:func:`deviation_along_curve`) in model units (red near, blue far, as in the paper), the worst point
    marked; (2) the result control polygon over the ground-truth polygon when given; (3) the deviation along
    the curve with the requested tolerance and the worst point; (4) the polygon after a few prefixes of the
    genome (the op history); (5) the genome as bars in order (yellow add_point, red move_point; height = how
    far the op moves the polygon); (6) best and mean fitness per generation. Works for interrupted results,
    empty histories and genomes of any length.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    if result.kind != "curve" or result.control_points is None:
        raise InputError("a curve report needs a curve result with control points")
    target = _points(target_points, "target points")
    space = target.shape[1] == 3
    ctrl = _points(result.control_points, "result control points", target.shape[1])
    truth_pts = None if truth is None else _points(truth, "ground-truth control points", target.shape[1])
    degree = result.degree
    closed, corners = curve_form(result)
    diag = float(np.linalg.norm(np.ptp(target, axis=0))) or 1.0
    info = result.config.get("target") if isinstance(result.config.get("target"), dict) else {}
    if "diagonal" not in info:  # a hand-made result: its lengths are the target's
        result = dataclasses.replace(result, config={**result.config, "target": {**info, "diagonal": diag}})
    unit = unit_label(units(result))
    curve, dist, per_target = deviation_along_curve(ctrl, target, degree, closed=closed, corners=corners)
    worst = int(np.argmax(per_target))
    target_info = result.config.get("target")
    name = _plain(title or (target_info.get("name") if isinstance(target_info, dict) else None) or "curve")
    genome = tuple(result.genome)
    states = hist.replayed(_curve_template(result, target), genome)
    steps = hist.step_indices(len(genome), STRIP_STEPS) if states is not None else []

    # Equal-aspect rows sized to the data, so the drawings fill the page whatever the shape. The layout
    # is fixed in inches (a constraint solver would cost more than the drawing).
    everything = np.vstack([target, ctrl] + ([truth_pts] if truth_pts is not None else []))
    span = np.ptp(everything, axis=0)
    if space:  # a 3D view: a box a little wider than high, whatever the data
        aspect = SPACE_ASPECT
    else:
        aspect = float(np.clip(span[1] / span[0], 0.3, 1.0)) if span[0] > 0 else 1.0
    subtitle = _subtitle(result)
    left, plot_w, bar_gap, bar_w = 0.85, 6.25, 0.12, 0.16
    width = 8.0
    shape_h = plot_w * 0.9 * aspect
    strip_w = (plot_w + 0.6) / max(len(steps), 1)
    head = 0.35 + 0.2 * (subtitle.count("\n") + 2)
    proj_h = (plot_w - 2 * PROJECTION_GAP) / 3 / 0.86 if space else 0.0
    rows = [(shape_h, 0.35), (shape_h, 0.35), (proj_h, 0.55), (1.6, 0.6), (strip_w * aspect if steps else 0.0, 0.2),
            (1.5, 0.55), (1.9, 0.55)]  # (axes height, space below)
    height = head + sum(0.3 + h + below for h, below in rows if h)
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    axes, top = [], height - head
    for row, (h, below) in enumerate(rows):
        if not h:
            axes.append(None)
            continue
        top -= 0.3  # room for the row's title
        axes.append(fig.add_axes((left / width, (top - h) / height, plot_w / width, h / height),
                                 projection="3d" if space and row < 2 else None))
        top -= h + below
    ax_curve, ax_poly, ax_proj, ax_dev, ax_strip, ax_genome, ax_conv = axes
    cax = fig.add_axes(((left + plot_w + bar_gap) / width, ax_curve.get_position().y0, bar_w / width,
                        shape_h / height))
    fig.suptitle(f"{name}  ({result.config.get('scheme', 'bspline')}, degree {degree})\n{subtitle}",
                 fontsize=10, y=1.0 - 0.12 / height, va="top")

    # (1) curve over targets, coloured by distance (as in the paper: red = near, blue = far)
    seg_d = 0.5 * (dist[1:] + dist[:-1])
    vmax = max(float(per_target.max()), float(seg_d.max()), 1e-12 * diag)  # bar top = max distance
    segments = np.stack([curve[:-1], curve[1:]], axis=1)
    lc = (Line3DCollection if space else LineCollection)(segments, cmap="turbo_r", linewidths=2.0, zorder=3)
    lc.set_array(seg_d)
    lc.set_clim(0.0, vmax)
    flat = {"depthshade": False} if space else {}
    if space:  # draw in the order given (the curve over the points), as in 2D
        ax_curve.computed_zorder = ax_poly.computed_zorder = False
    ax_curve.scatter(*target.T, s=(14 if len(target) < 400 else 5) / (3 if space else 1), color="black", linewidths=0, zorder=2,
                     label=f"target ({len(target)} points)", **flat)
    ax_curve.add_collection3d(lc) if space else ax_curve.add_collection(lc)
    ax_curve.scatter(*target[[worst]].T, s=90, marker="x", color=MOVE_COLOUR, linewidths=2, zorder=5,
                     label=f"worst point: {_fmt(per_target[worst])} {unit}", **flat)
    ax_curve.set_title("result curve over the target points, coloured by the target's distance to it",
                       loc="left", fontsize=10)
    ax_curve.legend(loc="best", fontsize=8, markerscale=1)
    cbar = fig.colorbar(lc, cax=cax)
    cbar.set_label(f"target distance, {unit} (top: {100 * vmax / diag:.3g} % of the diagonal)", fontsize=8)
    cbar.ax.tick_params(labelsize=7)

    # (2) control polygons
    ax_poly.plot(*target.T, ".", color="0.8", markersize=3, zorder=1)
    if truth_pts is not None:
        ax_poly.plot(*truth_pts.T, "s--", color="black", markersize=5, linewidth=1.0, zorder=2,
                     label=f"ground truth ({len(truth_pts)} points)")
    ax_poly.plot(*ctrl.T, "o-", color=MOVE_COLOUR, markersize=4, linewidth=1.4, zorder=3,
                 label=f"result ({len(ctrl)} points)")
    poly_title = "result control polygon" + (" over the ground-truth polygon" if truth_pts is not None else "")
    if truth_pts is not None and len(truth_pts) == len(ctrl):
        dev = float(np.max(np.linalg.norm(ctrl - truth_pts, axis=1)))
        poly_title += f"; max point deviation {_fmt(dev)} {unit} ({100 * dev / diag:.2g} %)"
    ax_poly.set_title(poly_title, loc="left", fontsize=10)
    ax_poly.legend(loc="best", fontsize=8)
    for ax in (ax_curve, ax_poly):
        if space:
            _frame_space(ax, everything, unit)
            continue
        ax.update_datalim(everything)
        ax.autoscale_view()
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=8)
        ax.margins(0.04)

    # (3) deviation along the curve, (4) op history, (5) genome, (6) convergence
    if ax_proj is not None:
        _draw_projections(fig, ax_proj, segments, lc, ctrl, target, unit)
    _draw_deviation(ax_dev, result, ctrl, target, curve, dist, per_target, diag, unit)
    if ax_strip is not None:
        _draw_curve_strip(fig, ax_strip, states, genome, steps, target, degree)
    sizes = hist.curve_op_sizes(states, genome) if states is not None else None
    _draw_genome(ax_genome, genome, sizes, unit)
    _draw_convergence(ax_conv, result.history, result.interrupted, result.metrics or {})
    return fig


def _frame_space(ax, points: np.ndarray, unit: str | None = None) -> None:
    """A 3D panel around ``points`` at equal scale on x, y and z (the box's sides in the data's proportions,
    padded, so a flat curve keeps a sliver), seen from the oblique view; axes labelled in ``unit``, or none."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = 0.04 * max(float((hi - lo).max()), 1e-300)
    lo, hi = lo - pad, hi + pad
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(hi - lo), zoom=0.95)
    ax.view_init(elev=VIEWS[0][1], azim=VIEWS[0][2])
    if unit is None:
        ax.set_axis_off()
        return
    for name, axis in zip("xyz", (ax.xaxis, ax.yaxis, ax.zaxis)):
        axis.set_label_text(f"{name}, {unit}", fontsize=8)
    ax.tick_params(labelsize=7)


PROJECTIONS = (("top", 0, 1), ("front", 0, 2), ("side", 1, 2))
"""The orthographic projections of a space curve's report: (name, horizontal axis, vertical axis)."""
PROJECTION_GAP = 0.55  # inches between two projection panels


def _draw_projections(fig, ax, segments: np.ndarray, coloured, ctrl: np.ndarray, target: np.ndarray,
                      unit: str) -> None:
    """A space curve in three orthographic views at equal scale, side by side: the target points, the
    curve coloured as ``coloured`` (its values, colour map and limits) and the control polygon."""
    from matplotlib.collections import LineCollection

    box = ax.get_position()
    ax.set_axis_off()
    ax.set_title("orthographic projections: the curve (coloured by distance) and its control polygon", loc="left",
                 fontsize=10)
    gap = PROJECTION_GAP / fig.get_figwidth()
    w = (box.width - 2 * gap) / 3
    everything = np.vstack([target, ctrl])
    for i, (name, a, b) in enumerate(PROJECTIONS):
        sub = fig.add_axes((box.x0 + i * (w + gap), box.y0, w, 0.86 * box.height))  # room for its title
        sub.plot(target[:, a], target[:, b], ".", color="0.75", markersize=2, zorder=1)
        lc = LineCollection(segments[:, :, [a, b]], cmap=coloured.get_cmap(), linewidths=1.6, zorder=3)
        lc.set_array(coloured.get_array())
        lc.set_clim(*coloured.get_clim())
        sub.add_collection(lc)
        sub.plot(ctrl[:, a], ctrl[:, b], "o-", color=MOVE_COLOUR, markersize=2.5, linewidth=0.8, zorder=2)
        sub.update_datalim(everything[:, [a, b]])
        sub.autoscale_view()
        sub.set_aspect("equal", adjustable="datalim")
        sub.margins(0.05)
        sub.set_xlabel(f"{'xyz'[a]}, {unit}", fontsize=8)
        sub.set_ylabel(f"{'xyz'[b]}, {unit}", fontsize=8, labelpad=1)
        sub.tick_params(labelsize=7)
        sub.set_title(f"{name} ({'xyz'[a]}, {'xyz'[b]})", fontsize=9)


def _curve_template(result: Result, target: np.ndarray) -> Any:
    try:
        return hist.curve_template(result, target)
    except (InputError, ValueError, TypeError):
        return None


def _draw_deviation(ax, result: Result, ctrl: np.ndarray, target: np.ndarray, curve: np.ndarray, dist: np.ndarray,
                    per_target: np.ndarray, diag: float, unit: str) -> None:
    """The target's distance to the curve along its parameter, the tolerance line and the worst point."""
    along = np.linspace(0.0, 100.0, len(dist))
    ax.plot(along, dist, color="#1f77b4", linewidth=1.2, label="deviation (between target points)")
    if len(ctrl) > result.degree:
        params = 100.0 * target_feet(ctrl, target, result.degree, curve, *curve_form(result))[0]
        ax.scatter(params, per_target, s=6, color="black", zorder=3, label="target points")
    else:
        params = np.linspace(0.0, 100.0, len(per_target))
    worst = int(np.argmax(per_target))
    ax.scatter([params[worst]], [per_target[worst]], s=80, marker="x", color=MOVE_COLOUR, linewidths=2, zorder=4,
               label=f"worst: {_fmt(per_target[worst])} {unit} ({100 * per_target[worst] / diag:.3g} %)")
    status = tolerance_status(result)
    top = float(per_target.max())
    if status is not None:
        limit = status[0] * diag
        ax.axhline(limit, color=TOLERANCE_COLOUR, linestyle="--", linewidth=1.2,
                   label=f"tolerance {_fmt(limit)} {unit}: {'met' if status[1] else 'MISSED'}")
        top = max(top, limit)
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 1.3 * top if top > 0 else 1.0)
    ax.set_title("deviation along the curve (target point to curve)", loc="left", fontsize=10)
    ax.set_xlabel("position along the curve, % of its parameter", fontsize=9)
    ax.set_ylabel(f"distance, {unit}", fontsize=9)
    ax.tick_params(labelsize=8)
    _percent_axis(ax, diag)
    ax.legend(loc="upper left", fontsize=7, ncols=2, framealpha=0.9)


def _draw_curve_strip(fig, ax, states: list, genome: tuple, steps: list[int], target: np.ndarray,
                      degree: int) -> None:
    """The control polygon and its curve after a few prefixes of the genome, left to right (Figure 3 top)."""

    box = ax.get_position()
    ax.set_axis_off()
    ax.set_title(f"op history: the control polygon (red) and its curve after 0 to {len(genome)} ops", loc="left",
                 fontsize=10)
    lo, hi = target.min(axis=0), target.max(axis=0)
    pts_all = np.vstack([target] + [states[k].points for k in steps])
    lo, hi = np.minimum(lo, pts_all.min(axis=0)), np.maximum(hi, pts_all.max(axis=0))
    w = box.width / len(steps)
    space = target.shape[1] == 3
    for i, k in enumerate(steps):
        sub = fig.add_axes((box.x0 + i * w, box.y0, w * 0.94, box.height), projection="3d" if space else None)
        sub.plot(*target.T, ".", color="0.8", markersize=1.5)
        sub.plot(*states[k].points.T, "o-", color=MOVE_COLOUR, markersize=2, linewidth=0.8)
        if len(states[k].points) > degree:
            sub.plot(*sample_curve(states[k].points, 200, degree, states[k].closed, states[k].corners).T,
                     color="black", linewidth=1.0)
        label = "template" if k == 0 else f"{k}: {hist.op_label(genome[k - 1])}"
        if space:  # a 3D panel has no x label to write under: the label goes in the panel's own text
            _frame_space(sub, np.array([lo, hi]))
            sub.text2D(0.5, 0.0, label, transform=sub.transAxes, ha="center", va="top", fontsize=7)
            continue
        sub.update_datalim(np.array([lo, hi]))
        sub.autoscale_view()
        sub.set_aspect("equal", adjustable="datalim")
        sub.set_xticks([])
        sub.set_yticks([])
        sub.set_xlabel(label, fontsize=7, labelpad=2)


# --- surfaces ------------------------------------------------------------------------------------------------

def _limit_distances(control, target, levels: int, boundary: str) -> tuple[Any, np.ndarray, np.ndarray]:
    """``(limit mesh, its triangles, distance of each limit vertex to the target)``; the distances are all
    zero when no target is known."""
    from .geometry.subdivision import get_catmull_clark

    cc = get_catmull_clark(control, levels, boundary)
    limit = cc.limit(control.vertices)
    tris = cc.triangles
    return limit, tris, np.zeros(limit.n_vertices) if target is None else target.closest(limit.vertices)[0]


VIEWS = (("oblique", 22, -58), ("front", 0, -90), ("top", 90, -90))
"""The three views of the surface report: (name, elevation, azimuth) in degrees."""
MAX_DRAWN_TRIANGLES = 20_000  # a larger target mesh is drawn as its vertices
MAX_DRAWN_POINTS = 6_000


def _frame(ax, box: tuple[np.ndarray, np.ndarray], view: tuple[str, float, float]) -> None:
    """One cube around ``box`` seen from ``view``, no axes (every panel of a row alike)."""
    lo, hi = box
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-12)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=view[1], azim=view[2])
    ax.set_axis_off()


def _draw_surface(ax, control, limit, tris: np.ndarray, dist: np.ndarray | None, norm, cmap) -> None:
    """The limit surface (coloured by ``dist`` in model units, grey without) and its control cage."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    v = limit.vertices
    colours = cmap(norm(dist[tris].mean(axis=1))) if dist is not None else "#c6c6c6"
    ax.add_collection3d(Poly3DCollection(v[tris], facecolors=colours, edgecolors="none", linewidths=0, alpha=0.95))
    edges = control.topology.edges
    ax.add_collection3d(Line3DCollection(control.vertices[edges], colors="black", linewidths=0.7))
    ax.scatter(*control.vertices.T, s=3, color="black", depthshade=False)


def _draw_target(ax, target) -> None:
    """A mesh target as shaded triangles, a point cloud (or a huge mesh) as points."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    pts = np.asarray(target.points)
    if target.faces is not None and len(target.faces) <= MAX_DRAWN_TRIANGLES:
        tri = pts[np.asarray(target.faces)]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        shade = 0.55 + 0.45 * np.abs(normal @ np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]))
        colours = np.clip(np.outer(shade, [0.55, 0.7, 0.85]), 0, 1)
        ax.add_collection3d(Poly3DCollection(tri, facecolors=colours, edgecolors="none", linewidths=0))
        return
    if len(pts) > MAX_DRAWN_POINTS:
        pts = pts[np.random.default_rng(0).choice(len(pts), MAX_DRAWN_POINTS, replace=False)]
    ax.scatter(*pts.T, s=1.5, color="#3182bd", depthshade=False, linewidths=0)


def surface_figure(result: Result, target=None, snapshots: Sequence[Any] | None = None, *,
                   title: str | None = None) -> Figure:
    """The surface report: the target beside the result from three views (the result's limit surface
    coloured by its distance to the target in model units, red near, blue far, one colour bar), the op
    history as a strip of control meshes and limit surfaces after each prefix of the genome (the paper's
    Figure 6), and the best and mean fitness per generation (the generations of ``snapshots`` marked).

    ``target`` (a :class:`~gsr_cad.reconstruct.inputs.SurfaceTarget`) and ``snapshots`` (objects with a
    ``generation``) default to those a :func:`reconstruct_surface` result carries; a result read back from
    ``result.json`` has neither, and shows its result uncoloured.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3d projection)

    if result.kind != "surface" or result.control_mesh is None:
        raise InputError("surface_report needs a surface result with a control mesh")
    target = target if target is not None else getattr(result, "target", None)
    snapshots = list(snapshots if snapshots is not None else getattr(result, "snapshots", []) or [])
    cfg = result.config or {}
    levels, boundary = int(cfg.get("levels", 2)), str(cfg.get("boundary", "all"))
    m = result.metrics or {}
    unit = unit_label(units(result))
    diag = float(target.diagonal) if target is not None else _config_diagonal(result)
    limit, tris, dist = _limit_distances(result.control_mesh, target, levels, boundary)
    genome = tuple(result.genome)
    states = hist.replayed(hist.surface_template(result), genome)
    steps = hist.step_indices(len(genome), STRIP_STEPS) if states is not None else []
    strip = [(k, states[k], *_limit_distances(states[k], target, levels, boundary)) for k in steps]
    # the result's range (earlier steps may exceed it): its reported max distance to the target, which the exact
    # limit surface reaches between the level-k vertices drawn here
    top = max(float(dist.max()), float(m.get("max_distance_to_target", 0.0)) * diag) if target is not None else 0.0
    norm = Normalize(0.0, top if top > 0 else 1e-12 * diag, clip=True)
    cmap = colormaps["turbo_r"]
    shown = [limit.vertices, result.control_mesh.vertices] + ([np.asarray(target.points)] if target is not None
                                                               else [])
    box = (np.min([a.min(axis=0) for a in shown], axis=0), np.max([a.max(axis=0) for a in shown], axis=0))

    n_strip = max(len(strip), 1)
    fig = Figure(figsize=(10.0, 15.5 if strip else 13.8), layout="constrained")
    FigureCanvasAgg(fig)
    heights = [1.0, 1.0, 1.0] + ([0.62] if strip else []) + [0.85]
    outer = fig.add_gridspec(len(heights), 1, height_ratios=heights)
    views = outer[0:3].subgridspec(3, 3, width_ratios=[1, 1, 0.05])
    for row, view in enumerate(VIEWS):
        ax_t = fig.add_subplot(views[row, 0], projection="3d")
        if target is not None:
            _draw_target(ax_t, target)
        else:
            ax_t.text2D(0.5, 0.5, "target not stored in result.json", ha="center", va="center",
                        transform=ax_t.transAxes, fontsize=9)
        _frame(ax_t, box, view)
        ax_r = fig.add_subplot(views[row, 1], projection="3d")
        _draw_surface(ax_r, result.control_mesh, limit, tris, dist if target is not None else None, norm, cmap)
        _frame(ax_r, box, view)
        ax_t.set_title(f"target ({target.kind}, {len(target.points)} points), {view[0]}" if target is not None
                       else f"target, {view[0]}", fontsize=9)
        ax_r.set_title(f"result: level-{levels} limit surface and control mesh, {view[0]}", fontsize=9)
    if target is not None:
        cbar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=fig.add_subplot(views[:, 2]), extend="max")
        cbar.set_label(f"distance to target, {unit} (top: {100 * top / diag:.3g} % of the diagonal)", fontsize=9)
        cbar.ax.tick_params(labelsize=8)
    if strip:
        cells = outer[3].subgridspec(1, n_strip)
        for i, (k, control, s_limit, s_tris, s_dist) in enumerate(strip):
            ax = fig.add_subplot(cells[0, i], projection="3d")
            _draw_surface(ax, control, s_limit, s_tris, s_dist if target is not None else None, norm, cmap)
            _frame(ax, box, VIEWS[0])
            ax.set_title("template" if k == 0 else f"{k}: {hist.op_label(genome[k - 1])}", fontsize=8)
    ax_conv = fig.add_subplot(outer[-1])
    _draw_convergence(ax_conv, result.history, result.interrupted, m)
    for snap in snapshots:
        ax_conv.axvline(snap.generation, color="0.6", linewidth=0.8, linestyle=":")
    target_info = cfg.get("target")
    name = _plain(title or (target_info.get("name") if isinstance(target_info, dict) else None) or "surface")
    fig.suptitle(f"{name}  (Catmull-Clark, level-{levels} limit)"
                 + (f"; op history left to right: {len(genome)} ops" if strip else "") + f"\n{_subtitle(result)}",
                 fontsize=10)
    return fig


def _config_diagonal(result: Result) -> float:
    from .reconstruct.summary import diagonal

    return diagonal(result)


def surface_report(result: Result, path: str | os.PathLike[str], target=None, snapshots: Sequence[Any] | None = None,
                   *, title: str | None = None, dpi: int = 110) -> Path:
    """Write :func:`surface_figure` to ``path`` atomically (format from its suffix) and return the path."""
    return _save(surface_figure(result, target, snapshots, title=title), path, dpi)
