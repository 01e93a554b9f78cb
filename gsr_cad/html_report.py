"""Interactive ``report.html`` of a result, built with plotly; plotly.js is embedded inline, so the page opens
offline (no CDN). Lengths are in the result's model units (``config["units"]``) with percent of the target's
bounding-box diagonal beside them, as in the summary and ``report.png``.

Curves (planar, or in space as 3D scenes): the result curve over the target coloured by its deviation, the
control polygon (and the ground truth), the deviation along the curve with the tolerance and the worst point, the op history (a slider over
the polygon after each op), the genome and the convergence. Surfaces: target and result side by side (linked
cameras), the result coloured by its distance to the target, the op history (a slider over the control mesh
and its limit surface after each op) and the convergence.
"""

from __future__ import annotations

import html
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import history as hist
from .atomic import write_text
from .errors import ExportError, InputError
from .reconstruct.result import Result
from .reconstruct.summary import diagonal, run_length, summary_lines, tolerance_status, units
from .reconstruct.units import unit_label

COLOURSCALE = "Turbo_r"  # the paper's colours: red near, blue far (matplotlib's turbo_r in report.png)
MAX_CLOUD_POINTS = 20_000  # target points drawn (a fixed subset of larger clouds)
HISTORY_STEPS = 12


def _plotly() -> Any:
    try:
        import plotly.graph_objects as go
    except ImportError as exc:
        raise ExportError(f"cannot write report.html: plotly is missing ({exc}); pip install plotly") from None
    return go


def _div(fig: Any, div_id: str) -> str:
    return fig.to_html(full_html=False, include_plotlyjs=False, div_id=div_id,
                       config={"displaylogo": False, "responsive": True})


def _page(title: str, lines: Sequence[str], sections: Sequence[tuple[str, str]]) -> str:
    from plotly.offline import get_plotlyjs

    body = "\n".join(f'<section><h2>{html.escape(name)}</h2>\n{div}\n</section>' for name, div in sections)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; color: #222; }}
pre {{ background: #f4f4f4; padding: 0.8em; overflow-x: auto; }}
section {{ margin-top: 1.5em; }}
h2 {{ font-size: 1.1em; margin-bottom: 0.2em; }}
</style>
<script type="text/javascript">{get_plotlyjs()}</script>
</head>
<body>
<h1>{html.escape(title)}</h1>
<pre>{html.escape(chr(10).join(lines))}</pre>
{body}
</body>
</html>
"""


def _write(path: str | os.PathLike[str], text: str) -> Path:
    return write_text(Path(path), text)


def _pct_hover(unit: str) -> str:
    return f"%{{y:.4g}} {unit} (%{{customdata:.3g}} % of the diagonal)<extra>%{{fullData.name}}</extra>"


def _convergence(go: Any, result: Result) -> Any:
    gens = [h.get("generation", i) for i, h in enumerate(result.history)]
    fig = go.Figure()
    for key, name, dash in (("mean_fitness", "population mean", "dash"), ("best_fitness", "best", "solid")):
        fig.add_trace(go.Scatter(x=gens, y=[h.get(key) for h in result.history], name=name, mode="lines+markers",
                                 line={"dash": dash}, marker={"size": 4}))
    ys = [h.get("best_fitness") for h in result.history] + [h.get("mean_fitness") for h in result.history]
    positive = all(isinstance(y, (int, float)) and y > 0 for y in ys) and ys
    kind = (result.metrics or {}).get("fitness_kind", "fitness")
    fig.update_layout(height=320, margin={"t": 30}, xaxis_title="generation", yaxis_title=str(kind),
                      yaxis_type="log" if positive else "linear")
    return fig


def _front(go: Any, result: Result) -> Any | None:
    """The accuracy/complexity front of ``metrics["front"]`` (distance against control vertices), the result's
    own cage marked; None without a front."""
    m = result.metrics or {}
    points = [p for p in m.get("front") or [] if isinstance(p, dict) and "vertices" in p and "distance" in p]
    if not points:
        return None
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=[p["vertices"] for p in points], y=[p["distance"] for p in points], name="front",
                             mode="lines+markers", line={"shape": "hv"}, text=[str(p.get("ops", "")) for p in points],
                             hovertemplate="%{x} control vertices: %{y:.3g} of the diagonal<br>%{text}"))
    chosen = [p for p in points if p["vertices"] == m.get("n_control_vertices")]
    if chosen:
        fig.add_trace(go.Scatter(x=[chosen[0]["vertices"]], y=[chosen[0]["distance"]], name="result", mode="markers",
                                 marker={"size": 12, "symbol": "star"}))
    positive = all(isinstance(p["distance"], (int, float)) and p["distance"] > 0 for p in points)
    fig.update_layout(height=320, margin={"t": 30}, xaxis_title="control vertices",
                      yaxis_title="distance / diagonal", yaxis_type="log" if positive else "linear")
    return fig


def _title(result: Result, title: str | None, default: str) -> str:
    target = (result.config or {}).get("target")
    return title or (target.get("name") if isinstance(target, dict) else None) or default


# --- curves --------------------------------------------------------------------------------------------------

def _line(go: Any, pts: np.ndarray, **kwargs: Any) -> Any:
    """A Scatter of x, y rows or a Scatter3d of x, y, z rows (a 3D marker is half the size of a 2D one)."""
    if pts.shape[1] == 2:
        return go.Scatter(x=pts[:, 0], y=pts[:, 1], **kwargs)
    marker = kwargs.get("marker")
    if isinstance(marker, dict) and "size" in marker:
        kwargs["marker"] = {**marker, "size": max(2, marker["size"] // 2)}
    return go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], **kwargs)


def _scene(unit: str) -> dict[str, Any]:
    """A 3D scene at equal scale (the data's proportions), its axes titled in ``unit``."""
    return {"aspectmode": "data", "xaxis_title": f"x ({unit})", "yaxis_title": f"y ({unit})",
            "zaxis_title": f"z ({unit})"}


def _equal_axes(fig: Any, dim: int, unit: str) -> None:
    """Equal scale on every axis: y anchored to x in 2D, the scene in the data's proportions in 3D."""
    if dim == 2:
        fig.update_layout(yaxis={"scaleanchor": "x", "scaleratio": 1})
    else:
        fig.update_layout(scene=_scene(unit))


def curve_html(result: Result, target_points: np.ndarray, path: str | os.PathLike[str],
               truth: np.ndarray | None = None, *, title: str | None = None) -> Path:
    """Write the interactive curve report to ``path`` atomically and return it."""
    from .plots import _points, curve_form, deviation_along_curve, target_feet

    go = _plotly()
    if result.kind != "curve" or result.control_points is None:
        raise InputError("a curve report needs a curve result with control points")
    target = _points(target_points, "target points")
    dim = target.shape[1]
    ctrl = _points(result.control_points, "result control points", dim)
    truth_pts = None if truth is None else _points(truth, "ground-truth control points", dim)
    diag, unit = diagonal(result), unit_label(units(result))
    closed, corners = curve_form(result)
    curve, dev, per_target = deviation_along_curve(ctrl, target, result.degree, closed=closed, corners=corners)
    worst = int(np.argmax(per_target))

    shape = go.Figure()
    shape.add_trace(_line(go, target, mode="markers", name="target", marker={"color": "black", "size": 4}))
    shape.add_trace(_line(
        go, curve, mode="markers+lines", name="result", line={"color": "#bbbbbb", "width": 1},
        customdata=100 * dev / diag, marker={"color": dev, "colorscale": COLOURSCALE, "size": 5, "cmin": 0,
                                            "colorbar": {"title": f"deviation, {unit}", "tickformat": ".3g"}},
        hovertemplate=f"deviation %{{marker.color:.4g}} {unit} (%{{customdata:.3g}} % of the diagonal)"))
    shape.add_trace(_line(go, ctrl, mode="lines+markers", name="control polygon",
                          line={"color": "#d62728", "dash": "dot"}, marker={"size": 7}))
    if truth_pts is not None:
        shape.add_trace(_line(go, truth_pts, mode="lines+markers", name="ground truth",
                              line={"color": "black", "dash": "dash"}, marker={"symbol": "square", "size": 6}))
    shape.add_trace(_line(go, target[[worst]], mode="markers", name="worst point",
                          marker={"symbol": "x", "size": 12, "color": "#d62728"}))
    shape.update_layout(height=520 if dim == 2 else 640, margin={"t": 30}, legend={"orientation": "h"})
    _equal_axes(shape, dim, unit)

    along = np.linspace(0.0, 100.0, len(dev))
    params = (100.0 * target_feet(ctrl, target, result.degree, curve, closed, corners)[0]
              if len(ctrl) > result.degree else along)
    deviation = go.Figure()
    deviation.add_trace(go.Scatter(x=along, y=dev, mode="lines", name="deviation", customdata=100 * dev / diag,
                                   hovertemplate=_pct_hover(unit), line={"color": "#1f77b4"}))
    if len(params) == len(per_target):
        deviation.add_trace(go.Scatter(x=params, y=per_target, mode="markers", name="target points",
                                       customdata=100 * per_target / diag, hovertemplate=_pct_hover(unit),
                                       marker={"size": 4, "color": "black"}))
        at = params[worst]
    else:
        at = along[int(np.argmax(dev))]
    deviation.add_trace(go.Scatter(x=[at], y=[per_target[worst]], mode="markers+text", name="worst point",
                                   text=[f"max {per_target[worst]:.3g} {unit}"], textposition="top center",
                                   marker={"symbol": "x", "size": 12, "color": "#d62728"}))
    status = tolerance_status(result)
    if status is not None:
        limit = status[0] * diag
        deviation.add_trace(go.Scatter(x=[0, 100], y=[limit, limit], mode="lines", name="tolerance",
                                       line={"color": "#2ca02c", "dash": "dash"}))
    deviation.update_layout(height=320, margin={"t": 30}, xaxis_title="position along the curve, % of its parameter",
                            yaxis_title=f"deviation, {unit}")

    sections = [("result over the target", _div(shape, "shape")), ("deviation along the curve",
                                                                      _div(deviation, "deviation"))]
    states = hist.replayed(hist.curve_template(result, target), tuple(result.genome))
    if states is not None:
        sections.append(("op history (slider: the control polygon after each op)",
                         _div(_curve_history(go, states, result.genome, target, unit), "history")))
        sizes = hist.curve_op_sizes(states, tuple(result.genome))
        names = [op.name for op in result.genome]
        bars = go.Figure(go.Bar(x=list(range(1, len(sizes) + 1)), y=sizes, name="genome",
                                marker={"color": ["#f2b705" if n == "add_point" else "#d62728" for n in names]},
                                hovertext=names))
        bars.update_layout(height=260, margin={"t": 30}, xaxis_title="op (yellow: insert, red: move)",
                           yaxis_title=f"size of the change, {unit}")
        sections.append(("genome", _div(bars, "genome")))
    sections.append(("convergence", _div(_convergence(go, result), "convergence")))
    name = _title(result, title, "curve")
    return _write(path, _page(f"{name}: curve report", summary_lines(result), sections))


def _curve_history(go: Any, states: list, genome: Sequence[Any], target: np.ndarray, unit: str) -> Any:
    steps = hist.step_indices(len(genome), len(genome) + 1 if len(genome) < 60 else 60)
    fig = go.Figure()
    fig.add_trace(_line(go, target, mode="markers", name="target", marker={"color": "#cccccc", "size": 3}))
    for i, k in enumerate(steps):
        fig.add_trace(_line(go, np.asarray(states[k].points), mode="lines+markers", name=f"after {k} ops",
                            visible=i == len(steps) - 1, line={"color": "#d62728"}, marker={"size": 6}))
    slider = [{"label": str(k), "method": "update",
               "args": [{"visible": [True] + [j == i for j in range(len(steps))]},
                        {"title": f"after {k} ops" + (f": {hist.op_label(genome[k - 1])}" if k else " (template)")}]}
              for i, k in enumerate(steps)]
    fig.update_layout(height=460 if target.shape[1] == 2 else 600, margin={"t": 40},
                      sliders=[{"active": len(steps) - 1, "steps": slider, "currentvalue": {"prefix": "ops: "}}],
                      title=f"after {steps[-1]} ops (the result)")
    _equal_axes(fig, target.shape[1], unit)
    return fig


# --- surfaces ------------------------------------------------------------------------------------------------

def _mesh3d(go: Any, vertices: np.ndarray, tris: np.ndarray, name: str, **kwargs: Any) -> Any:
    return go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2], i=tris[:, 0], j=tris[:, 1], k=tris[:, 2],
                     name=name, showlegend=True, flatshading=False, **kwargs)


def _wire(go: Any, mesh: Any, name: str, **kwargs: Any) -> Any:
    edges = mesh.topology.edges
    xyz = np.full((3 * len(edges), 3), np.nan)
    xyz[0::3], xyz[1::3] = mesh.vertices[edges[:, 0]], mesh.vertices[edges[:, 1]]
    return go.Scatter3d(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], mode="lines", name=name,
                        line={"color": "black", "width": 3}, connectgaps=False, **kwargs)


def _target_trace(go: Any, target: Any) -> Any:
    if target.faces is not None:
        return _mesh3d(go, np.asarray(target.points), np.asarray(target.faces), "target", color="#9ecae1",
                       opacity=1.0)
    pts = np.asarray(target.points)
    if len(pts) > MAX_CLOUD_POINTS:
        pts = pts[np.random.default_rng(0).choice(len(pts), MAX_CLOUD_POINTS, replace=False)]
    return go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="markers", name="target",
                        marker={"size": 2, "color": "#3182bd"})


def surface_html(result: Result, path: str | os.PathLike[str], target: Any = None, *,
                 title: str | None = None) -> Path:
    """Write the interactive surface report to ``path`` atomically and return it. ``target`` defaults to the
    one a :func:`reconstruct_surface` result carries; without one only the result is drawn, uncoloured."""
    from plotly.subplots import make_subplots

    from .plots import _limit_distances

    go = _plotly()
    if result.kind != "surface" or result.control_mesh is None:
        raise InputError("surface_html needs a surface result with a control mesh")
    target = target if target is not None else getattr(result, "target", None)
    cfg = result.config or {}
    levels, boundary = int(cfg.get("levels", 2)), str(cfg.get("boundary", "all"))
    diag, unit = diagonal(result), unit_label(units(result))
    limit, tris, dist = _limit_distances(result.control_mesh, target, levels, boundary)
    top = float(dist.max()) if target is not None and dist.size else 0.0
    colour = {"intensity": dist, "colorscale": COLOURSCALE, "cmin": 0.0, "cmax": top or 1e-12,
              "colorbar": {"title": f"distance to target, {unit}", "tickformat": ".3g"},
              "customdata": 100 * dist / diag,
              "hovertemplate": f"%{{intensity:.4g}} {unit} (%{{customdata:.3g}} % of the diagonal)"}
    side = make_subplots(rows=1, cols=2, specs=[[{"type": "scene"}, {"type": "scene"}]],
                         subplot_titles=("target", f"result (level-{levels} limit surface and control mesh)"))
    if target is not None:
        side.add_trace(_target_trace(go, target), row=1, col=1)
    side.add_trace(_mesh3d(go, limit.vertices, tris, "result", **(colour if target is not None else
                                                                   {"color": "#bdbdbd"})), row=1, col=2)
    side.add_trace(_wire(go, result.control_mesh, "control mesh"), row=1, col=2)
    side.update_layout(height=560, margin={"t": 40}, scene=_scene(unit), scene2=_scene(unit),
                       legend={"orientation": "h"})
    sections = [("target beside the result (drag to turn; the two views turn together)", _div(side, "surfaces"))]
    states = hist.replayed(hist.surface_template(result), tuple(result.genome))
    if states is not None:
        sections.append(("op history (slider: the control mesh and its limit surface after each op)",
                         _div(_surface_history(go, states, result.genome, levels, boundary, unit), "history")))
    sections.append(("convergence", _div(_convergence(go, result), "convergence")))
    pareto = _front(go, result)
    if pareto is not None:
        sections.append(("accuracy/complexity front (the simplest cage at each distance; --max-distance picks on "
                         "it)", _div(pareto, "front")))
    name = _title(result, title, "surface")
    ops = str((result.metrics or {}).get("ops", ""))
    page = _page(f"{name}: surface report (ops {run_length(ops) or '-'})", summary_lines(result), sections)
    return _write(path, page.replace("</body>", _LINK_CAMERAS + "</body>"))


def _surface_history(go: Any, states: list, genome: Sequence[Any], levels: int, boundary: str, unit: str) -> Any:
    from .plots import _limit_distances

    steps = hist.step_indices(len(genome), HISTORY_STEPS)
    fig = go.Figure()
    for i, k in enumerate(steps):
        limit, tris, _ = _limit_distances(states[k], None, levels, boundary)
        fig.add_trace(_mesh3d(go, limit.vertices, tris, f"limit after {k} ops", color="#fdae6b", opacity=0.85,
                              visible=i == len(steps) - 1))
        fig.add_trace(_wire(go, states[k], f"control mesh after {k} ops", visible=i == len(steps) - 1))
    slider = [{"label": f"{k}" + (f" {hist.op_label(genome[k - 1])}" if k else " template"), "method": "update",
               "args": [{"visible": [j // 2 == i for j in range(2 * len(steps))]},
                        {"title": f"after {k} ops" + (f": {hist.op_text(genome[k - 1])}" if k else " (template)")}]}
              for i, k in enumerate(steps)]
    fig.update_layout(height=520, margin={"t": 40}, title=f"after {steps[-1]} ops (the result)",
                      scene=_scene(unit),
                      sliders=[{"active": len(steps) - 1, "steps": slider, "currentvalue": {"prefix": "ops: "}}])
    return fig


_LINK_CAMERAS = """<script>
(function () {
  var gd = document.getElementById("surfaces");
  if (!gd || !gd.on) { return; }
  var busy = false;
  gd.on("plotly_relayout", function (ev) {
    if (busy) { return; }
    var cam = ev["scene.camera"] ? ["scene2.camera", ev["scene.camera"]]
            : ev["scene2.camera"] ? ["scene.camera", ev["scene2.camera"]] : null;
    if (!cam) { return; }
    busy = true;
    var update = {};
    update[cam[0]] = cam[1];
    Plotly.relayout(gd, update).then(function () { busy = false; });
  });
})();
</script>
"""

