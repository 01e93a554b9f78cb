"""Figures of reconstruction results (``report.png``), laid out like the paper's Figure 3.

matplotlib is imported inside the functions and drives an Agg canvas directly (no pyplot, no global
backend switch), so importing gsr_cad stays cheap and plotting works headless and from threads.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .atomic import atomic_path
from .errors import InputError
from .reconstruct.result import Result
from .reconstruct.summary import run_length

if TYPE_CHECKING:
    from matplotlib.figure import Figure

ADD_COLOUR = "#f2b705"   # the paper's yellow bars: vertex insertion
MOVE_COLOUR = "#d62728"  # the paper's red bars: vertex movement, height = distance moved
OTHER_COLOUR = "#8c8c8c"
CURVE_SAMPLES = 1200     # points of the result curve drawn and measured


def _points(a: Any, what: str) -> np.ndarray:
    pts = np.asarray(a, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise InputError(f"{what} must be at least 2 finite x, y rows, got an array of shape {pts.shape}")
    return pts


def deviation_along_curve(ctrl: np.ndarray, target: np.ndarray, degree: int, n: int = CURVE_SAMPLES
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` evenly spaced curve points, the target's deviation there, and each target point's distance.

    Each target point is projected onto the curve (foot point); its distance is carried to the curve at
    the foot's parameter and interpolated between feet. This is the distance the metrics report, so the
    colour bar's top equals the max distance, and an exact fit shows as zero even for sparse data (the
    chords between sparse points would show their sag as error).
    """
    from .geometry.bspline import sample_uniform
    from .geometry.distance import point_to_polyline

    if len(ctrl) <= degree:  # too few points for a curve: the polygon stands in for it
        return ctrl, point_to_polyline(ctrl, target), point_to_polyline(target, ctrl)
    curve = sample_uniform(ctrl, n, degree)
    params, dist = target_feet(ctrl, target, degree, curve)
    order = np.argsort(params, kind="stable")
    return curve, np.interp(np.linspace(0.0, 1.0, n), params[order], dist[order]), dist


def target_feet(ctrl: np.ndarray, target: np.ndarray, degree: int, curve: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each target point's foot parameter on the curve (in [0, 1]) and its distance to the curve."""
    from scipy.spatial import cKDTree

    from .geometry.bspline import sample_uniform
    from .geometry.distance import foot_points

    curve = sample_uniform(ctrl, CURVE_SAMPLES, degree) if curve is None else curve
    _, nearest = cKDTree(curve).query(target)
    return foot_points(ctrl, target, nearest / (len(curve) - 1), degree)


def _fmt(x: float) -> str:
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e4 or x == 0 else f"{x:.2e}"


def _subtitle(result: Result, width: int = 80) -> str:
    """The metrics that are present (an interrupted result may lack some), wrapped at separators."""
    m = result.metrics or {}
    parts = []
    if isinstance(m.get("fitness"), (int, float)):
        parts.append(f"fitness {_fmt(m['fitness'])}")
    dist = [f"{k} {100 * m[f'{k}_distance']:.3g} %" for k in ("mean", "max")
            if isinstance(m.get(f"{k}_distance"), (int, float))]
    if dist:
        parts.append(", ".join(dist) + " of bbox diagonal")
    if result.control_points is not None:
        parts.append(f"{len(result.control_points)} control points")
    parts.append(f"{len(result.genome)} ops")
    if isinstance(m.get("seconds"), (int, float)):
        parts.append(f"{m['seconds']:.1f} s")
    if result.interrupted:
        parts.append("INTERRUPTED")
    lines = [parts[0]]
    for part in parts[1:]:
        if len(lines[-1]) + 5 + len(part) > width:
            lines.append(part)
        else:
            lines[-1] += "  |  " + part
    return "\n".join(lines)


def _op_bar(op: Any) -> tuple[str, float | None]:
    """(kind, move distance or None) of one gene for the genome strip."""
    name = getattr(op, "name", type(op).__name__)
    if name == "move_point":
        return name, float(np.linalg.norm(np.asarray(getattr(op, "delta"), dtype=float)))
    return name, None


def _draw_genome(ax, genome: Sequence[Any]) -> None:
    from matplotlib.patches import Patch

    ax.set_title(f"genome: {len(genome)} operations, applied left to right", loc="left", fontsize=10)
    if not genome:
        ax.text(0.5, 0.5, "empty genome (template only)", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    bars = [_op_bar(op) for op in genome]
    moves = [d for _, d in bars if d is not None]
    top = max(moves) if moves and max(moves) > 0 else 1.0
    x = np.arange(1, len(bars) + 1)
    heights = [d if d is not None else top for _, d in bars]
    colours = [MOVE_COLOUR if k == "move_point" else ADD_COLOUR if k == "add_point" else OTHER_COLOUR for k, _ in bars]
    ax.bar(x, heights, width=0.8 if len(bars) < 150 else 1.0, color=colours, linewidth=0)
    ax.set_xlim(0.4, max(len(bars), 12) + 0.6)  # short genomes keep bar-like bars
    ax.set_ylim(0, top * 1.05)
    ax.set_ylabel("move distance")
    if not moves:
        ax.set_yticks([])
    ax.set_xlabel("operation")
    ax.xaxis.get_major_locator().set_params(integer=True)
    counts: dict[str, int] = {}
    for k, _ in bars:
        counts[k] = counts.get(k, 0) + 1
    handles = [Patch(color=ADD_COLOUR, label=f"add_point ({counts.get('add_point', 0)})"),
               Patch(color=MOVE_COLOUR, label=f"move_point ({counts.get('move_point', 0)})")]
    others = sum(v for k, v in counts.items() if k not in ("add_point", "move_point"))
    if others:
        handles.append(Patch(color=OTHER_COLOUR, label=f"other ({others})"))
    ax.legend(handles=handles, loc="upper right", fontsize=8, ncols=len(handles), framealpha=0.9)


def _draw_convergence(ax, history: Sequence[dict[str, Any]], interrupted: bool, metrics: dict[str, Any]) -> None:
    gens, best, mean = [], [], []
    for i, h in enumerate(history):
        gens.append(h.get("generation", i))
        best.append(h.get("best_fitness", math.nan))
        mean.append(h.get("mean_fitness", math.nan))
    gens_a, best_a, mean_a = (np.asarray(v, dtype=float) for v in (gens, best, mean))
    seconds = history[-1].get("seconds") if history else None
    title = f"convergence: {len(history)} generations"
    if isinstance(seconds, (int, float)):
        title += f", {seconds:.1f} s"
    if interrupted:
        title += " (interrupted)"
    elif isinstance(metrics.get("stop_reason"), str):
        title += f"; stopped: {metrics['stop_reason']}"
    ax.set_title(title, loc="left", fontsize=10)
    ax.set_xlabel("generation")
    kind = metrics.get("fitness_kind")
    ax.set_ylabel("fitness" + (f"\n({kind})" if isinstance(kind, str) else ""), fontsize=9)
    finite = np.concatenate([best_a[np.isfinite(best_a)], mean_a[np.isfinite(mean_a)]])
    if finite.size == 0:
        ax.text(0.5, 0.5, "no generation completed", ha="center", va="center", transform=ax.transAxes)
        ax.set_yticks([])
        return
    log = bool(np.all(finite > 0))
    style = dict(marker="o", markersize=3) if len(history) < 30 else {}
    ax.plot(gens_a, mean_a, color="#1f77b4", linestyle="--", label="population mean", **style)
    ax.plot(gens_a, best_a, color="black", label="best", **style)
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
    ax.legend(loc="best", fontsize=8)


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
    """The paper's Figure 3 for one curve result, as a matplotlib Figure on an Agg canvas.

    Rows: (1) result curve over the target points, coloured by the target's distance to it
    (:func:`deviation_along_curve`) in % of the target's bbox diagonal (red near, blue far, as in the paper);
    (2) the result control polygon over the ground-truth polygon when given; (3) the genome as bars in order
    (yellow add_point, red move_point of height = distance moved); (4) best and mean fitness per generation
    (log scale). Works for interrupted results, empty histories and genomes of any length.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    if result.kind != "curve" or result.control_points is None:
        raise InputError("a curve report needs a curve result with control points")
    target = _points(target_points, "target points")
    ctrl = _points(result.control_points, "result control points")
    truth_pts = None if truth is None else _points(truth, "ground-truth control points")
    degree = result.degree
    diag = float(np.linalg.norm(np.ptp(target, axis=0))) or 1.0
    curve, dist, per_target = deviation_along_curve(ctrl, target, degree)
    dist = 100.0 * dist / diag  # percent of the diagonal, as in the title
    target_info = result.config.get("target")
    name = title or (target_info.get("name") if isinstance(target_info, dict) else None) or "curve"

    # Equal-aspect rows sized to the data, so the drawings fill the page whatever the shape. The layout
    # is fixed in inches (a constraint solver would cost more than the drawing).
    everything = np.vstack([target, ctrl] + ([truth_pts] if truth_pts is not None else []))
    span = np.ptp(everything, axis=0)
    aspect = float(np.clip(span[1] / span[0], 0.3, 1.0)) if span[0] > 0 else 1.0
    subtitle = _subtitle(result)
    left, plot_w, bar_gap, bar_w = 0.85, 6.25, 0.12, 0.16
    width = 8.0
    shape_h = plot_w * 0.9 * aspect
    head = 0.35 + 0.2 * (subtitle.count("\n") + 2)
    rows = [(shape_h, 0.35), (shape_h, 0.35), (1.5, 0.55), (1.9, 0.55)]  # (axes height, space below)
    height = head + sum(0.3 + h + below for h, below in rows)
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    axes, top = [], height - head
    for h, below in rows:
        top -= 0.3  # room for the row's title
        axes.append(fig.add_axes((left / width, (top - h) / height, plot_w / width, h / height)))
        top -= h + below
    ax_curve, ax_poly, ax_genome, ax_conv = axes
    cax = fig.add_axes(((left + plot_w + bar_gap) / width, ax_curve.get_position().y0, bar_w / width,
                        shape_h / height))
    fig.suptitle(f"{name}  ({result.config.get('scheme', 'bspline')}, degree {degree})\n{subtitle}",
                 fontsize=11, y=1.0 - 0.12 / height, va="top")

    # (1) curve over targets, coloured by distance (as in the paper: red = near, blue = far)
    seg_d = 0.5 * (dist[1:] + dist[:-1])
    vmax = max(100.0 * float(per_target.max()) / diag, float(seg_d.max()), 1e-12)  # bar top = max distance
    lc = LineCollection(np.stack([curve[:-1], curve[1:]], axis=1), cmap="turbo_r", linewidths=2.0, zorder=3)
    lc.set_array(seg_d)
    lc.set_clim(0.0, vmax)
    ax_curve.scatter(*target.T, s=14 if len(target) < 400 else 5, color="black", linewidths=0, zorder=2,
                     label=f"target ({len(target)} points)")
    ax_curve.add_collection(lc)
    ax_curve.set_title("result curve over the target points, coloured by the target's distance to it",
                       loc="left", fontsize=10)
    ax_curve.legend(loc="best", fontsize=8, markerscale=2)
    cbar = fig.colorbar(lc, cax=cax)
    cbar.set_label("target distance, % of bbox diagonal", fontsize=8)
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
        dev = float(np.max(np.linalg.norm(ctrl - truth_pts, axis=1))) / diag
        poly_title += f"; max point deviation {100 * dev:.2g} % of diagonal"
    ax_poly.set_title(poly_title, loc="left", fontsize=10)
    ax_poly.legend(loc="best", fontsize=8)
    for ax in (ax_curve, ax_poly):
        ax.update_datalim(everything)
        ax.autoscale_view()
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=8)
        ax.margins(0.04)

    # (3) genome, (4) convergence
    _draw_genome(ax_genome, result.genome)
    _draw_convergence(ax_conv, result.history, result.interrupted, result.metrics or {})
    return fig


# --- surfaces ------------------------------------------------------------------------------------------------

def _limit_distances(control, target, levels: int, boundary: str) -> tuple[Any, np.ndarray, np.ndarray]:
    """``(limit mesh, its triangles, distance of each limit vertex to the target)``; the distances are all
    zero when no target is known."""
    from .geometry.subdivision import get_catmull_clark

    cc = get_catmull_clark(control, levels, boundary)
    limit = cc.limit(control.vertices)
    tris = cc.triangles
    return limit, tris, np.zeros(limit.n_vertices) if target is None else target.closest(limit.vertices)[0]


def _draw_surface(ax, control, limit, tris: np.ndarray, dist: np.ndarray, norm, cmap, title: str) -> None:
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    v = limit.vertices
    colours = cmap(norm(dist[tris].mean(axis=1)))
    ax.add_collection3d(Poly3DCollection(v[tris], facecolors=colours, edgecolors="none", linewidths=0, alpha=0.95))
    edges = control.topology.edges
    ax.add_collection3d(Line3DCollection(control.vertices[edges], colors="black", linewidths=0.8))
    ax.scatter(*control.vertices.T, s=4, color="black", depthshade=False)
    everything = np.vstack([v, control.vertices])
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-12)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=22, azim=-58)
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)


def surface_figure(result: Result, target=None, snapshots: Sequence[Any] | None = None, *,
                   title: str | None = None) -> Figure:
    """The paper's Figure 5 for one surface result: the best individual's control mesh and limit surface at a
    few generations and at the end (limit surfaces coloured by distance to the target: red near, blue far,
    over the target's bounding-box diagonal), above the best and mean fitness per generation.

    ``target`` (a :class:`~gsr_cad.reconstruct.inputs.SurfaceTarget`) and ``snapshots`` (objects with
    ``generation``, ``cost`` and ``control``) default to those a :func:`reconstruct_surface` result carries;
    a result read back from ``result.json`` has neither, and shows its final mesh uncoloured.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
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
    final_label = f"result: {m.get('n_control_faces', result.control_mesh.n_faces)} faces, {len(result.genome)} ops"
    panels = [(f"generation {s.generation}: fitness {_fmt(float(s.cost))}", s.control) for s in snapshots[-4:]]
    panels.append((final_label, result.control_mesh))
    drawn = [(label, control, *_limit_distances(control, target, levels, boundary)) for label, control in panels]
    diag = float(target.diagonal) if target is not None else 1.0
    vmax = max(float(d.max()) for *_, d in drawn) / diag
    norm = Normalize(0.0, vmax if vmax > 0 else 1e-12)
    cmap = colormaps["turbo_r"]

    n = len(drawn)
    fig = Figure(figsize=(max(3.2 * n, 8.0), 7.4), layout="constrained")
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(2, n + 1, width_ratios=[1] * n + [0.06], height_ratios=[1.25, 1.0])
    for i, (label, control, limit, tris, dist) in enumerate(drawn):
        _draw_surface(fig.add_subplot(gs[0, i], projection="3d"), control, limit, tris, dist / diag, norm, cmap, label)
    if target is not None:
        from matplotlib.cm import ScalarMappable

        cbar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=fig.add_subplot(gs[0, n]))
        cbar.set_label("distance to target / bbox diagonal", fontsize=8)
        cbar.ax.tick_params(labelsize=7)
    ax_conv = fig.add_subplot(gs[1, :n])
    _draw_convergence(ax_conv, result.history, result.interrupted, m)
    for s in snapshots[-4:]:
        ax_conv.axvline(s.generation, color="0.6", linewidth=0.8, linestyle=":")
    target_info = cfg.get("target")
    name = title or (target_info.get("name") if isinstance(target_info, dict) else None) or "surface"
    ops = m.get("ops") if isinstance(m.get("ops"), str) else ""
    fig.suptitle(f"{name}  (Catmull-Clark, level-{levels} limit; ops {run_length(ops) or '-'})\n"
                 f"{_subtitle(result, 110)}",
                 fontsize=11)
    return fig


def surface_report(result: Result, path: str | os.PathLike[str], target=None, snapshots: Sequence[Any] | None = None,
                   *, title: str | None = None, dpi: int = 110) -> Path:
    """Write :func:`surface_figure` to ``path`` atomically (format from its suffix) and return the path."""
    return _save(surface_figure(result, target, snapshots, title=title), path, dpi)
