"""STEP, DXF and SVG curve exports against independent readers, the exporter registry, damaged files.

Oracles: OCP's STEP reader and OCCT's evaluator, ezdxf's reader and B-spline code, svgelements' SVG
parser and Bezier evaluator, each compared with scipy's BSpline on a hand-written knot vector.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_export_results import hand_result, polygon_result, scipy_curve

from gsr_cad.cli import formats
from gsr_cad.errors import ExportError, InputError
from gsr_cad.exporters.base import num
from gsr_cad.exporters.model import curve_spline
from gsr_cad.exporters.dxf import DxfExporter
from gsr_cad.exporters.checks import read_step_curves
from gsr_cad.exporters.step import StepExporter
from gsr_cad.exporters.svg import SvgExporter
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.reconstruct.result import Result

pytest.importorskip("OCP")
ezdxf = pytest.importorskip("ezdxf")
se = pytest.importorskip("svgelements")

POLYGONS = st.tuples(st.integers(4, 12), st.sampled_from(["bspline", "chaikin"]),
                     st.sampled_from([1e-3, 1.0, 250.0, 1e4]), st.integers(0, 2**31 - 1))


def random_polygon(n: int, scale: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 2)) * scale + rng.normal(size=2) * 3 * scale


def by_status(checks) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {"pass": [], "FAIL": [], "skip": []}
    for c in checks:
        out[c.status].append(f"{c.host}:{c.check}")
    return out


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(POLYGONS)
def test_step_round_trip_is_exact(tmp_path, case):
    n, scheme, scale, seed = case
    result = polygon_result(random_polygon(n, scale, seed), scheme)
    (path,) = StepExporter().export(result, tmp_path, f"c{seed}")
    u = np.linspace(0, 1, 41)
    (curve,) = read_step_curves(path, u)
    assert curve.degree == result.degree and not curve.rational
    big = max(1.0, np.abs(result.control_points).max())
    np.testing.assert_allclose(curve.poles[:, :2], result.control_points, rtol=0, atol=1e-12 * big)
    np.testing.assert_array_equal(curve.poles[:, 2], 0.0)
    n_spans = n - result.degree
    knots = np.concatenate([np.zeros(result.degree), np.arange(n_spans + 1) / n_spans, np.ones(result.degree)])
    np.testing.assert_allclose(curve.knots, knots, rtol=0, atol=1e-11)
    np.testing.assert_allclose(curve.samples[:, :2], scipy_curve(result, u), rtol=0, atol=1e-10 * big)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(POLYGONS)
def test_dxf_holds_the_exact_spline_and_polygon(tmp_path, case):
    n, scheme, scale, seed = case
    result = polygon_result(random_polygon(n, scale, seed), scheme)
    (path,) = DxfExporter().export(result, tmp_path, f"c{seed}")
    msp = ezdxf.readfile(path).modelspace()
    (spline,) = msp.query("SPLINE")
    (poly,) = msp.query("LWPOLYLINE")
    assert spline.dxf.layer == "GSR_CURVE" and poly.dxf.layer == "GSR_CONTROL_POLYGON"
    assert spline.dxf.degree == result.degree and not spline.closed
    np.testing.assert_array_equal(np.array(spline.control_points)[:, :2], result.control_points)
    np.testing.assert_array_equal(np.array(spline.knots), curve_spline(result).knots)
    np.testing.assert_array_equal(np.array([p[:2] for p in poly.get_points()]), result.control_points)
    u = np.linspace(0, 1, 33)
    theirs = np.array([spline.construction_tool().point(float(t)) for t in u])[:, :2]
    np.testing.assert_allclose(theirs, scipy_curve(result, u), rtol=0,
                               atol=1e-8 * max(1.0, np.abs(result.control_points).max()))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(POLYGONS)
def test_svg_path_is_the_curve_with_y_up(tmp_path, case):
    n, scheme, scale, seed = case
    result = polygon_result(random_polygon(n, scale, seed), scheme)
    (path,) = SvgExporter().export(result, tmp_path, f"c{seed}")
    svg = se.SVG.parse(str(path), reify=False)
    width, height = float(svg.width), float(svg.height)
    curve = svg.get_element_by_id("curve")
    segments = [s for s in curve if not isinstance(s, se.Move)]
    kind = se.CubicBezier if result.degree == 3 else se.QuadraticBezier
    assert len(segments) == n - result.degree and all(isinstance(s, kind) for s in segments)
    # The numbers in the path are ours, exactly (the y flip lives in a transform).
    t = np.linspace(0, 1, 9)
    local = np.array([[p.x, p.y] for s in segments for p in (s.point(float(v)) for v in t)])
    params = ((np.arange(len(segments))[:, None] + t[None]) / len(segments)).ravel()
    big = max(1.0, np.abs(result.control_points).max())
    np.testing.assert_allclose(local, scipy_curve(result, params), rtol=0, atol=1e-9 * big)
    # On the page, everything is inside the viewport and y points up.
    page = np.array([[p.x, p.y] for p in (curve.transform.point_in_matrix_space(q) for q in map(tuple, local))])
    assert page[:, 0].min() >= 0 and page[:, 0].max() <= width and page[:, 1].min() >= 0
    assert page[:, 1].max() <= height
    polygon = svg.get_element_by_id("control_polygon")
    ys = np.array([p.y for p in polygon.points])
    page_y = np.array([polygon.transform.point_in_matrix_space(p).y for p in polygon.points])
    np.testing.assert_array_equal(np.argsort(ys, kind="stable"), np.argsort(-page_y, kind="stable"))


@pytest.mark.parametrize("exporter", [StepExporter(), DxfExporter(), SvgExporter()], ids=lambda e: e.name)
@pytest.mark.parametrize("scheme", ["bspline", "chaikin"])
def test_validate_passes_on_fresh_exports(tmp_path, exporter, scheme):
    result = hand_result(seed=5, scheme=scheme, scale=40.0, offset=(-300.0, 1200.0))
    (path,) = exporter.export(result, tmp_path, "curve")
    status = by_status(exporter.validate(path, result))
    assert status["FAIL"] == [] and len(status["pass"]) >= 5


def _perturb_step(text: str, pole: int) -> str:
    ids = re.search(r"B_SPLINE_CURVE_WITH_KNOTS\('[^']*',\d+,\(([^)]*)\)", text).group(1).split(",")
    target = ids[pole].strip()
    line = re.search(rf"^{re.escape(target)} = CARTESIAN_POINT\('',\(([^,]+),", text, re.M)
    x = float(line.group(1))
    return text[:line.start(1)] + repr(x + 0.25) + text[line.end(1):]


def _perturb_first(text: str, value: float) -> str:
    old = num(value)
    assert old in text
    return text.replace(old, repr(value + 0.25), 1)


@pytest.mark.parametrize("fmt", ["step", "dxf", "svg"])
def test_validate_reports_a_hand_edited_pole(tmp_path, fmt):
    result = hand_result(seed=6, scale=3.0)
    exporter = formats.registry()[fmt].exporter
    (path,) = exporter.export(result, tmp_path, "curve")
    text = path.read_text()
    pole = result.control_points[3]
    if fmt == "step":
        edited = _perturb_step(text, 3)
    elif fmt == "svg":  # an inner Bezier point of the path (poles are not on the path)
        d = re.search(r' d="([^"]*)"', text)
        numbers = d.group(1).split()
        numbers[5] = repr(float(numbers[5]) + 0.25)
        edited = text[:d.start(1)] + " ".join(numbers) + text[d.end(1):]
    else:
        edited = _perturb_first(text, float(pole[0]))
    path.write_text(edited)
    failed = by_status(exporter.validate(path, result))["FAIL"]
    if fmt == "svg":
        assert any("Bezier samples" in f for f in failed)
    else:
        assert any(f.endswith(":poles") for f in failed) and any("curve samples" in f for f in failed)


def test_validate_reports_unreadable_files(tmp_path):
    result = hand_result(seed=7)
    for exporter, name in ((StepExporter(), "x.step"), (DxfExporter(), "x.dxf"), (SvgExporter(), "x.svg")):
        path = tmp_path / name
        path.write_text("this is not a CAD file\n")
        checks = exporter.validate(path, result)
        assert checks and checks[0].status == "FAIL", (name, checks)


def test_registry_lists_the_curve_formats():
    reg = formats.registry()
    mine = {"step", "dxf", "svg", "fcmacro", "scad", "cadquery"}
    assert mine <= set(reg)
    for name in mine:
        assert reg[name].exporter is not None and reg[name].exporter.name == name
        assert reg[name].supports("curve")
    assert mine <= set(formats.default_formats("curve"))
    assert not {"dxf", "svg"} & set(formats.default_formats("surface"))
    assert {"step", "cadquery"} <= set(formats.default_formats("surface"))
    with pytest.raises(InputError, match="unknown format 'iges'"):
        formats.check_formats(["iges"], "curve")
    with pytest.raises(InputError, match="does not export surface results"):
        formats.check_formats(["dxf"], "surface")
    assert formats.check_formats(["svg", "dxf", "svg"], "curve") == ["svg", "dxf"]


def test_export_all_writes_every_format_or_none(tmp_path, monkeypatch):
    result = hand_result(seed=8)
    written = formats.export_all(result, tmp_path / "ok", ["step", "dxf", "svg", "fcmacro"], stem="arc")
    assert sorted(p.name for p in written) == ["arc.FCMacro", "arc.dxf", "arc.step", "arc.svg"]
    assert sorted(p.name for p in (tmp_path / "ok").iterdir()) == sorted([formats.MANIFEST] + [p.name for p in written])
    # The macro exporter fails after STEP and DXF were produced: nothing new reaches the output
    # directory, and the previous run's exports stay.
    before = {p.name: p.read_bytes() for p in (tmp_path / "ok").iterdir()}
    macro = formats.registry()["fcmacro"].exporter

    def broken(*_):
        raise ExportError("the macro writer broke")

    monkeypatch.setattr(macro, "render_curve", broken)
    with pytest.raises(ExportError, match="broke"):
        formats.export_all(hand_result(seed=9), tmp_path / "ok", ["step", "dxf", "fcmacro"], stem="arc")
    assert {p.name: p.read_bytes() for p in (tmp_path / "ok").iterdir()} == before


def test_export_all_skips_curve_formats_for_surfaces(tmp_path):
    cube = unit_cube()
    template = {"vertices": cube.vertices.tolist(), "faces": [list(f) for f in cube.faces]}
    surface = Result(kind="surface", config={"template": template}, seed=None, genome=(), metrics={}, history=[],
                     control_mesh=cube)
    written = formats.export_all(surface, tmp_path, None)
    curve_suffixes = (".dxf", ".svg")
    assert not [p for p in written if p.name.endswith(curve_suffixes)]


def test_export_all_reports_an_unwritable_directory(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(ExportError, match="cannot write"):
        formats.export_all(hand_result(), blocker / "out", ["svg"])


def test_exports_of_a_real_reconstruction_validate(tmp_path):
    from test_export_results import reconstructed_result

    result = reconstructed_result("bspline")
    written = formats.export_all(result, tmp_path, ["step", "dxf", "svg"])
    result.save(tmp_path)
    checks = formats.validate_all(tmp_path)
    assert {c.file for c in checks} == {p.name for p in written}
    assert by_status(checks)["FAIL"] == []
    assert Path(tmp_path / "curve.step").read_text().startswith("ISO-10303-21;")
