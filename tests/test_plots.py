"""The curve report (paper's Figure 3): what each row draws, odd results, files and laziness."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.image import imread
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ExportError, InputError
from gsr_cad.ops import curve as curve_ops
from gsr_cad.plots import ADD_COLOUR, CURVE_SAMPLES, MOVE_COLOUR, curve_figure, curve_report
from gsr_cad.reconstruct.result import Result
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
    (lc,) = ax.collections[1:]  # the scatter of targets comes first
    segs = np.array(lc.get_segments())
    curve = scipy_curve(ctrl, CURVE_SAMPLES, 3)
    np.testing.assert_allclose(segs[:, 0], curve[:-1], atol=1e-9)
    np.testing.assert_allclose(segs[-1, 1], curve[-1], atol=1e-9)
    diag = np.linalg.norm(np.ptp(s.points, axis=0))
    d = 100 * oracle_deviation(ctrl, s.points, 3, CURVE_SAMPLES) / diag  # percent of the diagonal
    np.testing.assert_allclose(lc.get_array(), 0.5 * (d[1:] + d[:-1]), atol=2e-3)
    top = 100 * cKDTree(scipy_curve(ctrl, 200_001, 3)).query(s.points)[0].max() / diag
    assert lc.get_clim() == pytest.approx((0.0, top), rel=1e-4)
    assert lc.get_array().max() > 0.1  # the perturbed points really pull the curve off the target
    np.testing.assert_array_equal(ax.collections[0].get_offsets(), s.points)
    assert "wave" in fig._suptitle.get_text() and "0.09 %" in fig._suptitle.get_text()


def test_an_exact_fit_to_sparse_data_is_coloured_as_exact():
    s = get_sample("bspline_07_sparse")
    genome, ctrl = genome_onto(s.points, s.truth_ctrl)
    fig = curve_figure(make_result(ctrl, genome, history(2)), s.points, s.truth_ctrl)
    (lc,) = axis(fig, "result curve").collections[1:]
    assert lc.get_array().max() < 1e-7  # chords between the sparse points would show ~1 % here


def test_polygon_row_overlays_result_on_truth(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(3)), s.points, s.truth_ctrl)
    ax = axis(fig, "result control polygon over the ground-truth")
    lines = {line.get_label(): line.get_xydata() for line in ax.get_lines()}
    np.testing.assert_array_equal(lines["result (7 points)"], ctrl)
    np.testing.assert_array_equal(lines["ground truth (7 points)"], s.truth_ctrl)
    dev = 0.4 / np.linalg.norm(np.ptp(s.points, axis=0))
    assert f"{100 * dev:.2g} %" in ax.get_title(loc="left")
    no_truth = curve_figure(make_result(ctrl, genome, history(3)), s.points)
    assert [ln.get_label() for ln in axis(no_truth, "result control polygon").get_lines()][-1] == "result (7 points)"


def test_genome_row_has_one_bar_per_op_in_order(wave):
    s, genome, ctrl = wave
    fig = curve_figure(make_result(ctrl, genome, history(3)), s.points)
    bars = axis(fig, "genome").patches
    assert len(bars) == len(genome)
    moves = [np.hypot(*op.delta) for op in genome if op.name == "move_point"]
    for bar, op in zip(bars, genome):
        colour = to_rgb(bar.get_facecolor())
        if op.name == "add_point":
            assert colour == pytest.approx(to_rgb(ADD_COLOUR)) and bar.get_height() == pytest.approx(max(moves))
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
    assert "INTERRUPTED" in fig._suptitle.get_text()
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
    (lc,) = axis(fig, "result curve").collections[1:]
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
    (lc,) = axis(fig, "result curve").collections[1:]
    assert lc.get_clim()[1] == pytest.approx(100 * result.metrics["max_distance"], rel=1e-4)  # colour bar = metric
    best = axis(fig, "convergence").get_lines()[-1].get_ydata()
    np.testing.assert_allclose(best, [h["best_fitness"] for h in result.history])
    assert np.all(np.diff(best) <= 1e-12)  # elitism: the best never gets worse
    assert curve_report(result, s.points, tmp_path / "report.png", truth=s.truth_ctrl).exists()


def test_importing_plots_does_not_import_matplotlib():
    code = "import sys, gsr_cad.plots; sys.exit('matplotlib' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
