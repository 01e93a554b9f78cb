"""Results to export (hand-built and reconstructed) and the shared exporter machinery in exporters/base.py.

The builders here are imported by the other ``test_export_*`` modules.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from gsr_cad.errors import ExportError, OpError
from gsr_cad.exporters import base, model
from gsr_cad.ops import curve as curve_ops
from gsr_cad.reconstruct.result import Result


def hand_result(seed: int = 0, scheme: str = "bspline", n_ops: int = 8, scale: float = 1.0,
                offset: tuple[float, float] = (0.0, 0.0)) -> Result:
    """A curve result built by replaying random valid ops on the paper's template of a sine arc."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 4.0, 50)
    data = np.column_stack([x, np.sin(0.8 * x) + 0.3 * x]) * scale + np.asarray(offset)
    template = curve_ops.template(data, margin=0.1)
    genome, state = [], template
    while len(genome) < n_ops:
        op = curve_ops.random_op(rng, state, move_scale=0.2, local_add=True)
        try:
            state = op.apply(state)
        except OpError:  # an op that would leave the box: draw another
            continue
        genome.append(op)
    config = {"scheme": scheme, "template": template.points.tolist(),
              "bounds": [list(template.lo), list(template.hi)]}
    return Result(kind="curve", config=config, seed=seed, genome=tuple(genome), metrics={}, history=[],
                  control_points=np.array(state.points))


def polygon_result(points: np.ndarray, scheme: str = "bspline") -> Result:
    """A curve result for given control points, built by ops: the template, then adds and moves."""
    pts = np.asarray(points, dtype=float)
    lo, hi = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
    template = np.array([pts[0], pts[1], pts[-2], pts[-1]])
    genome = [curve_ops.AddPoint(i, tuple(map(float, pts[i]))) for i in range(2, len(pts) - 2)]
    config = {"scheme": scheme, "template": template.tolist(), "bounds": [lo.tolist(), hi.tolist()]}
    return Result(kind="curve", config=config, seed=None, genome=tuple(genome), metrics={}, history=[],
                  control_points=pts)


def reconstructed_result(scheme: str = "bspline") -> Result:
    """A real (short) reconstruction, so exports see exactly what ``gsr curve`` produces."""
    from gsr_cad.reconstruct.config import CurveConfig
    from gsr_cad.reconstruct.curve import reconstruct_curve

    t = np.linspace(0.0, 3.0, 60)
    points = np.column_stack([10 * t, 4 * np.sin(t) + t])
    config = CurveConfig.preset("default", scheme=scheme, generations=4, initial_population=60, population=20)
    return reconstruct_curve(points, seed=3, config=config)


def scipy_curve(result: Result, params: np.ndarray) -> np.ndarray:
    """Independent oracle: scipy's BSpline on the clamped uniform knot vector written out by hand."""
    ctrl = np.asarray(result.control_points, dtype=float)
    k = result.degree
    spans = len(ctrl) - k
    knots = np.concatenate([np.zeros(k), np.arange(spans + 1) / spans, np.ones(k)])
    return BSpline(knots, ctrl, k)(params)


def test_history_replays_ops_and_labels_them():
    result = hand_result(seed=4, n_ops=9)
    history = model.curve_history(result)
    assert len(history) == len(result.genome) + 1
    assert history[0].label == "00 template" and history[0].op is None
    np.testing.assert_array_equal(history[0].points, np.asarray(result.config["template"]))
    np.testing.assert_array_equal(history[-1].points, result.control_points)
    points = np.asarray(result.config["template"], dtype=float)
    for number, (step, op) in enumerate(zip(history[1:], result.genome), start=1):
        if op.name == "add_point":
            points = np.insert(points, op.index, op.position, axis=0)
            x, y = op.position
            assert step.label == f"{number:02d} add point {op.index} at ({x:.4g}, {y:.4g})"
        else:
            points = points.copy()
            points[op.index] += op.delta
            assert step.label.startswith(f"{number:02d} move point {op.index} by (")
        np.testing.assert_array_equal(step.points, points)
        assert step.op == op.to_json()


def test_op_label_pads_to_the_genome_length():
    add = {"op": "add_point", "index": 2, "position": [0.41, 0.77]}
    assert model.op_label(3, add) == "03 add point 2 at (0.41, 0.77)"
    assert model.op_label(7, {"op": "move_point", "index": 1, "delta": [0.1, -0.25]}, width=3) == \
        "007 move point 1 by (0.1, -0.25)"
    assert model.op_label(12, {"op": "scale", "factor": 2.0}) == "12 scale factor=2.0"


def test_the_genome_wins_over_stored_control_points():
    result = hand_result(seed=1)
    edited = dataclasses.replace(result, control_points=result.control_points + 1e-3)
    np.testing.assert_array_equal(edited.control_points, result.control_points)
    assert len(edited.notes) == 1 and "the genome wins" in edited.notes[0] and "0.00141" in edited.notes[0]
    assert result.notes == []
    np.testing.assert_array_equal(model.curve_history(edited)[-1].points, result.control_points)
    no_template = dataclasses.replace(result, config={"scheme": "bspline"})
    with pytest.raises(ExportError, match="no config.template"):
        model.curve_history(no_template)
    boxed = dict(result.config, bounds=[[-1e-9, -1e-9], [1e-9, 1e-9]])  # every op now leaves the box
    with pytest.raises(OpError, match=r"genome op 0 \(.*\) no longer applies"):
        dataclasses.replace(result, config=boxed)


def test_curve_spline_matches_scipy_and_rejects_short_polygons():
    result = hand_result(seed=2, scheme="chaikin")
    spline = model.curve_spline(result)
    assert spline.degree == 2 and spline.knots[0] == 0.0 and spline.knots[-1] == 1.0
    assert spline.multiplicities.sum() == len(spline.poles) + 3
    u = np.linspace(0, 1, 101)
    np.testing.assert_allclose(spline.points(u), scipy_curve(result, u), atol=1e-12)
    pieces = spline.bezier()
    assert pieces.shape == (spline.n_spans, 3, 2)
    short = Result(kind="curve", config={"scheme": "bspline"}, seed=None, genome=(), metrics={}, history=[],
                   control_points=np.zeros((3, 2)))
    with pytest.raises(ExportError, match="at least 4 control points"):
        model.curve_spline(short)


def test_checks_measure_and_compare():
    ok = base.measured("a.step", "OCP", "poles", 1e-12, 1e-9)
    bad = base.measured("a.step", "OCP", "poles", math.nan, 1e-9)
    assert (ok.status, bad.status) == ("pass", "FAIL")
    assert base.skipped("a", "freecad", "run", "not installed").status == "skip"
    assert base.point_deviation(np.zeros((3, 2)), np.zeros((4, 2))) == math.inf
    assert base.point_deviation(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0]])) == 5.0
    long = base.expect_equal("f", "h", "labels", list(range(100)), list(range(99)))
    assert long.status == "FAIL" and len(long.detail) <= 160


@settings(max_examples=30, deadline=None)
@given(st.integers(4, 14), st.sampled_from(["bspline", "chaikin"]), st.integers(0, 2**31 - 1))
def test_bezier_pieces_are_the_curve(n, scheme, seed):
    pts = np.random.default_rng(seed).normal(size=(n, 2)) * 10
    result = polygon_result(pts, scheme)
    spline = model.curve_spline(result)
    pieces = spline.bezier()
    t = np.linspace(0, 1, 7)
    k = spline.degree
    coeff = np.array([math.comb(k, i) * t**i * (1 - t) ** (k - i) for i in range(k + 1)]).T
    got = np.einsum("ti,sid->std", coeff, pieces).reshape(-1, 2)
    params = ((np.arange(spline.n_spans)[:, None] + t[None]) / spline.n_spans).ravel()
    np.testing.assert_allclose(got, scipy_curve(result, params), atol=1e-9 * np.abs(pts).max())


@pytest.mark.parametrize("kind", ["curve", "surface"])
def test_one_replay_and_one_limit_mesh_per_export_run_and_per_validation(kind, tmp_path, monkeypatch):
    from test_export_surface_hosts import surface_result

    from gsr_cad.ops.base import Op
    from gsr_cad.reconstruct.export import export, format_names, validate

    for host in ("BLENDER", "FREECAD", "OPENSCAD", "CADQUERY_PYTHON"):  # count our work, not the hosts'
        monkeypatch.setenv(f"GSR_{host}", str(tmp_path / "absent"))
    source = hand_result(seed=5, n_ops=7) if kind == "curve" else surface_result()
    source.save(tmp_path / "out")
    applied, limits = [], []
    for cls in {type(op) for op in source.genome}:
        real_apply = cls.apply
        monkeypatch.setattr(cls, "apply",
                            lambda self, state, real=real_apply: applied.append(self) or real(self, state))
    real_limit = model.limit_mesh
    monkeypatch.setattr(model, "limit_mesh", lambda *a: limits.append(a) or real_limit(*a))
    assert all(isinstance(op, Op) for op in source.genome)
    result = Result.load(tmp_path / "out")
    names = [n for n in format_names(kind) if n != "step"] + ["step"]
    written = export(result, tmp_path / "out", names)
    assert len(written) >= len(names)
    assert len(applied) == len(source.genome) and len(limits) == (kind == "surface")
    checks = validate(tmp_path / "out")
    assert checks and not [c for c in checks if c.passed is False]
    assert len(applied) == 2 * len(source.genome) and len(limits) == 2 * (kind == "surface")
