"""The curve report (paper's Figure 3): what each row draws, odd results, files and laziness."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgb
from matplotlib.image import imread
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ExportError, InputError
from gsr_cad.ops import curve as curve_ops
from gsr_cad.plots import ADD_COLOUR, CURVE_SAMPLES, MOVE_COLOUR, curve_figure, curve_report
from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.units import format_length
from gsr_cad.reconstruct.samples import get_sample


def scipy_curve(ctrl: np.ndarray, n: int, degree: int) -> np.ndarray:
    knots = np.r_[np.zeros(degree), np.linspace(0, 1, len(ctrl) - degree + 1), np.ones(degree)]
    return BSpline(knots, ctrl, degree)(np.linspace(0, 1, n))


def oracle_deviation(ctrl: np.ndarray, target: np.ndarray, degree: int, n: int) -> np.ndarray:
    """Target-to-curve distances by brute force on 200 001 scipy samples, carried along the curve parameter."""
    fine = np.linspace(0, 1, 200_001)
    dist, idx = cKDTree(scipy_curve(ctrl, len(fine), degree)).query(target)
    order = np.argsort(fine[idx], kind="stable")
    return np.interp(np.linspace(0, 1, n), fine[idx][order], dist[order])


def genome_onto(points: np.ndarray, goal: np.ndarray) -> tuple[tuple, np.ndarray]:
    """A real genome on the paper's template that builds ``goal`` (adds, then one move per inner point)."""
    poly = curve_ops.template(points, margin=1.0)
    ops = [curve_ops.AddPoint(1, tuple(map(float, poly.points[1]))) for _ in range(len(goal) - 4)]
    poly = genome_mod.replay(poly, ops)
    for i in range(1, len(goal) - 1):
        ops.append(curve_ops.MovePoint(i, tuple(map(float, goal[i] - poly.points[i]))))
    ctrl = genome_mod.replay(curve_ops.template(points, margin=1.0), ops).points
    return tuple(ops), np.asarray(ctrl)


def make_result(ctrl, genome, history, *, scheme="bspline", interrupted=False, metrics=None) -> Result:
    return Result(kind="curve", config={"scheme": scheme, "target": {"name": "t"}}, seed=0, genome=genome,
                  metrics=metrics if metrics is not None else {"fitness": 1.5e-3, "mean_distance": 2e-4,
                                                               "max_distance": 9e-4, "seconds": 3.2},
                  history=history, control_points=ctrl, interrupted=interrupted)


def history(n: int) -> list[dict]:
    return [{"generation": g, "best_fitness": 10.0 / (g + 1), "mean_fitness": 30.0 / (g + 1) ** 0.5,
             "seconds": 0.1 * (g + 1)} for g in range(n)]


def line_collection(ax):
    (lc,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    return lc


def axis(fig, title_start: str):
    (ax,) = [a for a in fig.axes if a.get_title(loc="left").startswith(title_start)]
    return ax


@pytest.fixture(scope="module")
def wave():
    s = get_sample("bspline_07")
    goal = s.truth_ctrl + np.array([[0, 0], [0.3, 0], [0, 0], [0, -0.4], [0, 0], [0, 0], [0, 0]])
    genome, ctrl = genome_onto(s.points, goal)
    return s, genome, ctrl


def test_curve_row_is_the_result_coloured_by_its_distance_to_the_target(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(12)), s.points, s.truth_ctrl, title="wave")
    ax = axis(fig, "result curve")
    lc = line_collection(ax)
    segs = np.array(lc.get_segments())
    curve = scipy_curve(ctrl, CURVE_SAMPLES, 3)
    np.testing.assert_allclose(segs[:, 0], curve[:-1], atol=1e-9)
    np.testing.assert_allclose(segs[-1, 1], curve[-1], atol=1e-9)
    diag = np.linalg.norm(np.ptp(s.points, axis=0))
    d = oracle_deviation(ctrl, s.points, 3, CURVE_SAMPLES)  # model units
    np.testing.assert_allclose(lc.get_array(), 0.5 * (d[1:] + d[:-1]), atol=2e-3 * diag / 100)
    dist = cKDTree(scipy_curve(ctrl, 200_001, 3)).query(s.points)[0]
    top = dist.max()
    assert lc.get_clim() == pytest.approx((0.0, top), rel=1e-4)
    assert lc.get_array().max() > 1e-3 * diag  # the perturbed points really pull the curve off the target
    np.testing.assert_array_equal(ax.collections[0].get_offsets(), s.points)
    worst = ax.collections[-1]  # the worst target point, marked
    np.testing.assert_array_equal(worst.get_offsets(), s.points[[np.argmax(dist)]])
    title = fig._suptitle.get_text()
    assert "wave" in title and f"max {format_length(9e-4, diag)}" in title  # the metric, in both units
    assert any(a.get_ylabel().startswith("target distance, model units") for a in fig.axes)  # the colour bar


def test_an_exact_fit_to_sparse_data_is_coloured_as_exact():
    s = get_sample("bspline_07_sparse")
    genome, ctrl = genome_onto(s.points, s.truth_ctrl)
    fig = curve_figure(make_result(ctrl, genome, history(2)), s.points, s.truth_ctrl)
    lc = line_collection(axis(fig, "result curve"))
    assert lc.get_array().max() < 1e-9  # chords between the sparse points would show ~1 % here


def test_polygon_row_overlays_result_on_truth(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(3)), s.points, s.truth_ctrl)
    ax = axis(fig, "result control polygon over the ground-truth")
    lines = {line.get_label(): line.get_xydata() for line in ax.get_lines()}
    np.testing.assert_array_equal(lines["result (7 points)"], ctrl)
    np.testing.assert_array_equal(lines["ground truth (7 points)"], s.truth_ctrl)
    dev = 0.4 / np.linalg.norm(np.ptp(s.points, axis=0))
    assert f"max point deviation 0.4 model units ({100 * dev:.2g} %)" in ax.get_title(loc="left")
    no_truth = curve_figure(make_result(ctrl, genome, history(3)), s.points)
    assert [ln.get_label() for ln in axis(no_truth, "result control polygon").get_lines()][-1] == "result (7 points)"


def test_genome_row_has_one_bar_per_op_in_order(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(3)), s.points)
    bars = axis(fig, "genome").patches
    assert len(bars) == len(genome)
    states = genome_mod.replay_states(curve_ops.template(s.points, margin=1.0), genome)
    for k, (bar, op) in enumerate(zip(bars, genome)):
        colour = to_rgb(bar.get_facecolor())
        if op.name == "add_point":  # height: the new point's distance from the edge it splits (dense oracle)
            a, b = states[k].points[op.index - 1], states[k].points[op.index]
            edge = a + np.linspace(0, 1, 100_001)[:, None] * (b - a)
            off = np.min(np.linalg.norm(edge - np.asarray(op.position), axis=1))
            assert colour == pytest.approx(to_rgb(ADD_COLOUR)) and bar.get_height() == pytest.approx(off, abs=1e-4)
        else:
            assert colour == pytest.approx(to_rgb(MOVE_COLOUR))
            assert bar.get_height() == pytest.approx(np.hypot(*op.delta))
    assert [b.get_x() + b.get_width() / 2 for b in bars] == pytest.approx(range(1, len(genome) + 1))


def test_convergence_row_plots_the_history_on_a_log_scale(wave):
    s, genome, ctrl = wave
    hist = history(40)
    ax = axis(curve_figure(make_result(ctrl, genome, hist), s.points), "convergence")
    lines = {line.get_label(): line.get_ydata() for line in ax.get_lines()}
    np.testing.assert_allclose(lines["best"], [h["best_fitness"] for h in hist])
    np.testing.assert_allclose(lines["population mean"], [h["mean_fitness"] for h in hist])
    assert ax.get_yscale() == "log"
    # fitness values that cannot go on a log axis (0, negative) keep it linear rather than vanish
    flat = [dict(h, best_fitness=0.0) for h in hist]
    assert axis(curve_figure(make_result(ctrl, genome, flat), s.points), "convergence").get_yscale() == "linear"


def test_interrupted_result_with_nothing_done_still_reports(tmp_path, wave):
    s, _, _ = wave
    template = np.asarray(curve_ops.template(s.points).points)
    result = make_result(template, (), [], interrupted=True, metrics={})
    fig = curve_figure(result, s.points)
    assert "interrupted: best so far" in fig._suptitle.get_text()
    assert "(interrupted)" in axis(fig, "convergence").get_title(loc="left")
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert "no generation completed" in texts and "empty genome (template only)" in texts
    assert curve_report(result, s.points, tmp_path / "r.png").stat().st_size > 0


def test_long_genome_and_chaikin_scheme(tmp_path):
    s = get_sample("spiral")
    rng = np.random.default_rng(3)
    genome = tuple(curve_ops.AddPoint(1, (0.0, 0.0)) if rng.random() < 0.3 else
                   curve_ops.MovePoint(1, tuple(rng.normal(0, 0.5, 2).tolist())) for _ in range(600))
    ctrl = s.points[::20]
    fig = curve_figure(make_result(ctrl, genome, history(500), scheme="chaikin"), s.points)
    assert len(axis(fig, "genome").patches) == 600
    lc = line_collection(axis(fig, "result curve"))
    np.testing.assert_allclose(np.array(lc.get_segments())[:, 0], scipy_curve(ctrl, CURVE_SAMPLES, 2)[:-1], atol=1e-9)
    assert "degree 2" in fig._suptitle.get_text()


def test_report_png_shows_the_paper_colours(tmp_path, wave):
    s, genome, ctrl = wave
    path = curve_report(make_result(ctrl, genome, history(20)), s.points, tmp_path / "sub" / "report.png",
                        truth=s.truth_ctrl, dpi=60)
    img = imread(path)[..., :3]
    assert img.shape[1] == 8 * 60
    for colour in (ADD_COLOUR, MOVE_COLOUR):
        assert np.sum(np.all(np.abs(img - to_rgb(colour)) < 0.02, axis=2)) > 50
    assert [p.name for p in path.parent.iterdir()] == ["report.png"]  # no temp file left behind
    svg = curve_report(make_result(ctrl, genome, history(2)), s.points, tmp_path / "report.svg")
    assert svg.read_text().lstrip().startswith("<?xml")


def test_bad_inputs_raise_typed_errors_and_leave_existing_files_alone(tmp_path, wave):
    s, genome, ctrl = wave
    good = make_result(ctrl, genome, history(2))
    path = tmp_path / "report.png"
    path.write_bytes(b"old")
    bad_target = s.points.copy()
    bad_target[3, 0] = np.nan
    with pytest.raises(InputError, match="target points"):
        curve_report(good, bad_target, path)
    with pytest.raises(InputError, match="ground-truth"):
        curve_report(good, s.points, path, truth=np.zeros((3, 3)))
    surface = Result(kind="surface", config={}, seed=None, genome=(), metrics={}, history=[])
    with pytest.raises(InputError, match="curve result"):
        curve_report(surface, s.points, path)
    assert path.read_bytes() == b"old"
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ExportError):
        curve_report(good, s.points, blocker / "report.png")


def test_real_reconstruction_reports(tmp_path):
    from gsr_cad.reconstruct.curve import reconstruct_curve

    s = get_sample("bspline_05")
    result = reconstruct_curve(s.points, preset="paper", seed=2, initial_population=30, population=10,
                               generations=4)
    fig = curve_figure(result, s.points, s.truth_ctrl)
    assert len(axis(fig, "genome").patches) == len(result.genome)
    lc = line_collection(axis(fig, "result curve"))
    diag = result.config["target"]["diagonal"]
    assert lc.get_clim()[1] == pytest.approx(result.metrics["max_distance"] * diag, rel=1e-4)  # colour bar = metric
    best = axis(fig, "convergence").get_lines()[-1].get_ydata()
    np.testing.assert_allclose(best, [h["best_fitness"] for h in result.history])
    assert np.all(np.diff(best) <= 1e-12)  # elitism: the best never gets worse
    assert curve_report(result, s.points, tmp_path / "report.png", truth=s.truth_ctrl).exists()


def test_importing_plots_does_not_import_matplotlib():
    code = "import sys, gsr_cad.plots; sys.exit('matplotlib' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_deviation_row_has_the_tolerance_line_and_the_worst_point(wave):
    s, genome, ctrl = wave
    diag = float(np.linalg.norm(np.ptp(s.points, axis=0)))
    result = make_result(ctrl, genome, history(3))
    result.config.update(max_distance=2e-3, units="mm", target={"name": "t", "diagonal": diag})
    ax = axis(curve_figure(result, s.points), "deviation along the curve")
    dist = cKDTree(scipy_curve(ctrl, 200_001, 3)).query(s.points)[0]
    (tol,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("tolerance")]
    assert tol.get_ydata()[0] == pytest.approx(2e-3 * diag)
    assert tol.get_label().endswith("MISSED") == (result.metrics["max_distance"] > 2e-3)
    worst = [c for c in ax.collections if c.get_label().startswith("worst")][0]
    assert worst.get_offsets()[0][1] == pytest.approx(dist.max(), rel=1e-4)
    assert ax.get_ylabel() == "distance, mm" and ax.get_ylim()[1] >= dist.max()


def test_history_strip_replays_the_genome_prefix_by_prefix(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(3)), s.points)
    panels = [a for a in fig.axes if a.get_xlabel() == "template" or a.get_xlabel()[:1].isdigit()]
    assert 2 <= len(panels) <= 8 and panels[0].get_xlabel() == "template"
    assert panels[-1].get_xlabel() == f"{len(genome)}: {genome[-1].name}"
    np.testing.assert_allclose(panels[-1].get_lines()[1].get_xydata(), ctrl)  # the last step is the result
    template = np.asarray(curve_ops.template(s.points, margin=1.0).points)
    np.testing.assert_allclose(panels[0].get_lines()[1].get_xydata(), template)


def test_an_insertion_off_its_edge_gets_a_bar_as_high_as_its_offset():
    s = get_sample("bspline_05")
    poly = curve_ops.template(s.points, margin=1.0)
    a, b = poly.points[1], poly.points[2]
    normal = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
    op = curve_ops.AddPoint(2, tuple((0.5 * (a + b) + 0.3 * normal).tolist()))
    ctrl = np.asarray(genome_mod.replay(poly, [op]).points)
    fig = curve_figure(make_result(ctrl, (op,), history(2)), s.points)
    (bar,) = axis(fig, "genome").patches
    assert bar.get_height() == pytest.approx(0.3)


def test_surface_report_draws_the_target_beside_the_result_in_three_views(tmp_path):
    from gsr_cad.reconstruct.surface import reconstruct_surface
    from gsr_cad.plots import VIEWS, surface_figure, surface_report

    sample = get_sample("inset_extrude")
    result = reconstruct_surface(sample.target, seed=1, units="mm", population=10, initial_population=10,
                                 n_parents=4, n_perturb=2, n_newcomers=2, generations=2, refine=False,
                                 op_kinds="VELBFS")  # no inset: an imperfect fit to colour
    fig = surface_figure(result)
    titles = [a.get_title() for a in fig.axes]
    for name, *_ in VIEWS:
        assert any(t.startswith("target (mesh") and t.endswith(name) for t in titles)
        assert any(t.startswith("result: level-2 limit surface") and t.endswith(name) for t in titles)
    (cbar,) = [a for a in fig.axes if a.get_ylabel().startswith("distance to target, mm")]
    diag = result.target.diagonal
    top = result.metrics["max_distance_to_target"] * diag
    assert cbar.get_ylim()[1] == pytest.approx(top, rel=0.05)  # the result's own range, in mm
    strip = [t for t in titles if t == "template" or t[:1].isdigit()]
    assert strip[0] == "template" and strip[-1].startswith(f"{len(result.genome)}: ")
    assert "lengths in mm" in fig._suptitle.get_text()
    again = Result.from_json(result.to_json())  # no target: the result alone, uncoloured, still drawn
    assert surface_report(again, tmp_path / "r.png").stat().st_size > 10_000


def helix_points(m: int = 300) -> np.ndarray:
    t = np.linspace(0, 4 * np.pi, m)
    return np.column_stack([np.cos(t), np.sin(t), 0.2 * t])


@pytest.fixture(scope="module")
def helix_run():
    from gsr_cad.reconstruct.curve import reconstruct_curve
    from gsr_cad.reconstruct.summary import add_model_units

    pts = helix_points()
    result = reconstruct_curve(pts, seed=0, units="mm", max_distance=1e-3, initial_population=60, population=16,
                               generations=6)
    add_model_units(result)
    return pts, result


def spline_oracle(result):
    """The result's own curve form, and target distances by brute force on 200 001 of its points."""
    from gsr_cad.geometry.bspline import make_spline

    cfg = result.config
    return make_spline(result.control_points, result.degree, cfg["closed"], cfg["corners"])


def test_a_space_curve_report_draws_its_geometry_in_3d_at_equal_scale(helix_run):
    pts, result = helix_run
    ctrl = result.control_points
    truth = ctrl + np.array([0.0, 0.0, 0.05])  # a ground truth to draw under the result
    fig = curve_figure(result, pts, truth)
    ax = axis(fig, "result curve")
    assert ax.name == "3d"
    lc = line_collection(ax)
    segs = np.asarray(lc._segments3d)  # the 3D segments (get_segments gives their projection)
    spline = spline_oracle(result)
    np.testing.assert_allclose(segs[:, 0], spline(np.linspace(0, 1, CURVE_SAMPLES))[:-1], atol=1e-9)
    fine = np.linspace(0, 1, 200_001)
    dist, idx = cKDTree(spline(fine)).query(pts)
    order = np.argsort(fine[idx], kind="stable")
    d = np.interp(np.linspace(0, 1, CURVE_SAMPLES), fine[idx][order], dist[order])
    diag = result.config["target"]["diagonal"]
    np.testing.assert_allclose(lc.get_array(), 0.5 * (d[1:] + d[:-1]), atol=1e-5 * diag)
    assert lc.get_clim()[1] == pytest.approx(dist.max(), rel=1e-3)
    assert lc.get_clim()[1] == pytest.approx(result.metrics["data_to_fit_max"] * diag, rel=1e-3)  # bar top = metric
    target, worst = ax.collections[0], ax.collections[-1]
    np.testing.assert_array_equal(np.column_stack(target._offsets3d), pts)
    np.testing.assert_array_equal(np.column_stack(worst._offsets3d), pts[[np.argmax(dist)]])
    everything = np.vstack([pts, ctrl, truth])
    box = np.asarray(ax.get_box_aspect())
    side = np.ptp(everything, axis=0) + 0.08 * np.ptp(everything, axis=0).max()
    np.testing.assert_allclose(box / box.max(), side / side.max(), rtol=1e-9)  # equal scale on x, y and z
    assert ax.get_zlabel() == "z, mm"

    poly = axis(fig, "result control polygon over the ground-truth")
    assert poly.name == "3d"
    lines = {line.get_label(): np.column_stack(line.get_data_3d()) for line in poly.get_lines()}
    np.testing.assert_array_equal(lines[f"result ({len(ctrl)} points)"], ctrl)
    np.testing.assert_array_equal(lines[f"ground truth ({len(ctrl)} points)"], truth)
    assert f"max point deviation {0.05:.3g} mm" in poly.get_title(loc="left")

    dev = axis(fig, "deviation along the curve")  # the 2D rows stay as they are
    (tol,) = [ln for ln in dev.get_lines() if ln.get_label().startswith("tolerance")]
    assert tol.get_ydata()[0] == pytest.approx(1e-3 * diag) and tol.get_label().endswith(": met")
    assert len(axis(fig, "genome").patches) == len(result.genome)
    np.testing.assert_allclose(axis(fig, "convergence").get_lines()[-1].get_ydata(),
                               [h["best_fitness"] for h in result.history])


def test_a_space_curve_history_strip_is_3d_and_ends_at_the_result(helix_run):
    pts, result = helix_run
    fig = curve_figure(result, pts)
    panels = [a for a in fig.axes if a.name == "3d" and a.texts]
    labels = [a.texts[0].get_text() for a in panels]
    assert 2 <= len(panels) <= 8 and labels[0] == "template"
    assert labels[-1] == f"{len(result.genome)}: {result.genome[-1].name}"
    np.testing.assert_allclose(np.column_stack(panels[-1].get_lines()[1].get_data_3d()), result.control_points)
    template = np.asarray(result.config["template"], dtype=float)
    np.testing.assert_allclose(np.column_stack(panels[0].get_lines()[1].get_data_3d()), template)


def test_a_space_curve_report_png_is_written_and_bad_dimensions_are_refused(helix_run, tmp_path):
    pts, result = helix_run
    path = curve_report(result, pts, tmp_path / "report.png", title="helix $x$", dpi=60)
    img = imread(path)[..., :3]
    assert img.shape[1] == 8 * 60
    assert np.sum(np.all(np.abs(img - to_rgb(MOVE_COLOUR)) < 0.02, axis=2)) > 50  # the polygon, the moves
    assert "helix \\$x\\$" in curve_figure(result, pts, title="helix $x$")._suptitle.get_text()  # no mathtext
    with pytest.raises(InputError, match=r"result control points .* x, y rows \(the target points' dimension\)"):
        curve_report(result, pts[:, :2], tmp_path / "bad.png")  # a 3D result over planar points
    with pytest.raises(InputError, match="ground-truth"):
        curve_report(result, pts, tmp_path / "bad.png", truth=np.zeros((4, 2)))
    assert not (tmp_path / "bad.png").exists()


def test_a_space_curve_report_has_its_three_orthographic_projections(helix_run):
    from gsr_cad.plots import PROJECTIONS

    pts, result = helix_run
    fig = curve_figure(result, pts)
    coloured = line_collection(axis(fig, "result curve"))
    segs3d = np.asarray(coloured._segments3d)
    views = {a.get_title(): a for a in fig.axes if a.get_title().startswith(("top", "front", "side"))}
    assert sorted(views) == ["front (x, z)", "side (y, z)", "top (x, y)"]
    for name, a, b in PROJECTIONS:
        ax = views[f"{name} ({'xyz'[a]}, {'xyz'[b]})"]
        lc = line_collection(ax)
        np.testing.assert_array_equal(np.asarray(lc.get_segments()), segs3d[:, :, [a, b]])
        np.testing.assert_array_equal(lc.get_array(), coloured.get_array())
        assert lc.get_clim() == coloured.get_clim()
        (polygon,) = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        np.testing.assert_array_equal(polygon.get_xydata(), result.control_points[:, [a, b]])
        assert ax.get_aspect() == 1.0 and ax.get_xlabel() == f"{'xyz'[a]}, mm"
    planar = get_sample("bspline_05")  # a planar report has no projection row
    genome, ctrl = genome_onto(planar.points, planar.truth_ctrl)
    assert not [a for a in curve_figure(make_result(ctrl, genome, history(2)), planar.points).axes
                if a.get_title().startswith("top (")]
