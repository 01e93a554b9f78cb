"""Closed, cornered and 3D curves in every export: curves reconstructed through the API are exported in every
format that carries them and re-read by the real hosts (OCP, FreeCAD, ezdxf, Blender, CadQuery, svgelements,
OpenSCAD), which must give back our curve: closed curves as closed (periodic where the host has periodic
curves), corners as repeated knots or Bezier joints, space curves with their z. SVG and OpenSCAD are planar by
nature and refuse 3D curves (a default export skips them with a warning)."""

from __future__ import annotations

import json
import subprocess
import warnings

import numpy as np
import pytest

import gsr_cad
from gsr_cad.errors import ExportError, GsrWarning
from gsr_cad.exporters import hosts
from gsr_cad.exporters.base import curve_checks
from gsr_cad.exporters.model import curve_spline
from gsr_cad.geometry import bspline
from gsr_cad.reconstruct.curve import reconstruct_curve
from gsr_cad.reconstruct.export import default_formats
from gsr_cad.reconstruct.inputs import curve_target

PLANAR_ONLY = {"svg", "scad"}


def _square() -> np.ndarray:
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    return np.vstack([np.linspace(corners[i], corners[i + 1], 40, endpoint=False) for i in range(4)])


def _vee3d() -> np.ndarray:
    """Two space arcs meeting at a corner (two straight legs would be fitted exactly by three coincident control
    points, with no corner op)."""
    t = np.linspace(0.0, np.pi / 2.0, 80, endpoint=False)
    a = np.c_[np.cos(t) - 1.0, np.sin(t), 0.3 * t]
    s = np.linspace(0.0, np.pi / 2.0, 80)
    return np.vstack([a, np.c_[0.8 * np.sin(s) - 1.0, 1.0 + 0.5 * s, 0.3 * np.pi / 2.0 - 0.2 * s]])


def _helix() -> np.ndarray:
    t = np.linspace(0.0, 4.0 * np.pi, 300)
    return np.c_[np.cos(t), np.sin(t), 0.2 * t]


def _ring3d() -> np.ndarray:
    s = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    return np.c_[np.cos(s), np.sin(s), 0.3 * np.sin(2.0 * s)]


pytestmark = pytest.mark.xdist_group("curve_forms")  # one worker builds the module's fixtures once

CASES = {"square": (_square, True, True, 2), "vee3d": (_vee3d, False, True, 3), "helix": (_helix, False, False, 3),
         "ring3d": (_ring3d, True, False, 3), "square-chaikin": (_square, True, True, 2)}
"""name: (data, closed, cornered, dimension) as the reconstruction must find them (a "-chaikin" case is
reconstructed with the Chaikin scheme: quadratic B-splines)."""


@pytest.fixture(scope="session")
def results():
    out = {}
    for name, (data, closed, cornered, dim) in CASES.items():
        result = reconstruct_curve(curve_target(data()), seed=1,
                                   scheme="chaikin" if name.endswith("-chaikin") else "bspline")
        assert (bool(result.config["closed"]), bool(result.config["corners"])) == (closed, cornered), name
        assert np.asarray(result.control_points).shape[1] == dim, name
        out[name] = result
    return out


@pytest.fixture(scope="session")
def validated(results, tmp_path_factory):
    """Every case exported in its default formats and validated once: name -> (files, warnings, checks)."""
    out = {}
    for name, result in results.items():
        folder = tmp_path_factory.mktemp(name)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            files = gsr_cad.export(result, folder)
        result.save(folder)
        out[name] = ({p.name for p in files}, [str(w.message) for w in caught if issubclass(w.category, GsrWarning)],
                     gsr_cad.validate(folder))
    return out


def test_the_module_is_one_group_under_loadgroup(request):
    """Under ``--dist loadgroup`` (the suite's) this module's tests run on one worker, which builds the fixtures
    once: xdist names the group in the node id (it did not under pytest 9.2, so pytest is pinned below 9)."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run by pytest-xdist with --dist loadgroup")
    assert request.node.nodeid.endswith("@curve_forms")


@pytest.mark.parametrize("name", list(CASES))
def test_every_format_that_carries_the_curve_passes_its_host_round_trip(validated, name):
    files, _, checks = validated[name]
    failed = [(c.file, c.host, c.check, c.detail) for c in checks if c.status == "FAIL"]
    assert checks and not failed, failed
    dim = CASES[name][3]
    expected = set(default_formats("curve")) - (PLANAR_ONLY if dim == 3 else set())
    suffix = {"step": ".step", "dxf": ".dxf", "svg": ".svg", "scad": ".scad", "fcmacro": ".FCMacro",
              "blender": "_blender.py", "cadquery": "_cadquery.py"}
    assert {fmt for fmt in expected if "curve" + suffix[fmt] in files} == expected
    judges = {"OCP", "ezdxf"} | {h for h in ("freecad", "blender") if hosts.find_host(h)}
    judges |= {"cadquery"} if hosts.cadquery_python() else set()
    if dim == 2:
        judges |= {"svgelements"} | ({"openscad"} if hosts.find_host("openscad") else set())
    assert judges <= {c.host for c in checks if c.status == "pass"}


@pytest.mark.parametrize("name", list(CASES))
def test_the_hosts_see_the_form_closed_periodic_cornered_and_in_space(validated, results, name):
    _, _, checks = validated[name]
    closed, cornered, dim = CASES[name][1:]
    passed = {(c.file, c.check) for c in checks if c.status == "pass"}
    # the closed flag of OCP (STEP, CadQuery where its venv is), FreeCAD and the DXF SPLINE says whether the curve
    # is closed
    for file in ("curve.step", "curve.dxf") + (("curve_cadquery.py",) if hosts.cadquery_python() else ()):
        assert (file, "closed") in passed
    # a closed curve is periodic in OCCT: the STEP reader's form and the macro's own periodic B-spline
    periodic = {c.file for c in checks if c.check == "periodic poles" and c.status == "pass"}
    macro = {"curve.FCMacro"} if hosts.find_host("freecad") else set()
    cadquery = {"curve_cadquery.py"} if hosts.cadquery_python() else set()
    assert periodic == ({"curve.step"} | cadquery | macro if closed else set())
    if hosts.find_host("freecad"):
        assert ("curve.FCMacro", "history corners") in passed
        assert ("curve.FCMacro", "closed") in passed
    if hosts.find_host("blender"):
        assert ("curve_blender.py", "Bezier spline, free handles, cyclic if closed") in passed
    if dim == 2:
        assert ("curve.svg", "closed path (Z at the end)" if closed else "open path") in passed
    spline = curve_spline(results[name])
    assert spline.dim == dim and spline.closed == closed
    if cornered:  # corners are knots of multiplicity degree in the exported form
        assert spline.multiplicities[1:-1].max() == spline.degree
    for c in checks:  # exact formats agree far below the tolerance (Blender keeps single precision)
        if c.status == "pass" and c.deviation is not None and c.host not in ("blender", "openscad"):
            assert c.deviation <= 1e-9 * spline.scale, (c.file, c.host, c.check, c.deviation)


def test_3d_curves_skip_the_planar_formats_with_a_warning_and_refuse_them_when_asked(validated, results, tmp_path):
    for name in ("helix", "ring3d", "vee3d"):
        files, caught, _ = validated[name]
        assert {msg.split()[1] for msg in caught} == PLANAR_ONLY & set(default_formats("curve"))
        assert all("3D" in msg for msg in caught)
        assert not any(f.endswith((".svg", ".scad")) for f in files)
    for fmt in PLANAR_ONLY:
        with pytest.raises(ExportError, match="planar by nature"):
            gsr_cad.export(results["helix"], tmp_path, [fmt])
    assert not any(tmp_path.iterdir())
    assert not validated["square"][1]  # a planar closed cornered curve: every format carries it


@pytest.mark.parametrize("degree", [2, 3])
def test_the_periodic_form_is_the_curve_in_occt_for_every_corner_placement(degree):
    """Our periodic form (control points turned by the copies of the knot at 0 after t[k]) built as an OCCT
    periodic B-spline evaluates to our closed curve, corners at the seam included."""
    pytest.importorskip("OCP")
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt

    from gsr_cad.exporters.step import _arrays

    point_array, real_array, int_array = _arrays()
    rng = np.random.default_rng(7)
    n, k = 9, degree
    u = np.linspace(0.0, 1.0, 97)
    for corners in [(), (0,), (1,), (n - 1,), (n - 2,), (2, 6), (0, 4), (1, 5 + (k == 2))]:
        ctrl = rng.normal(size=(n, 3))
        want = bspline.make_spline(ctrl, k, True, corners)(u)
        knots, clamped = bspline.clamped_form(ctrl, k, True, corners)
        spline = curve_spline_of(ctrl, k, corners, knots, clamped)
        for poles, values, mults in spline.periodic_forms():
            pa, ka, ma = point_array(1, len(poles)), real_array(1, len(values)), int_array(1, len(values))
            for i, p in enumerate(poles.tolist(), start=1):
                pa.SetValue(i, gp_Pnt(*p))
            for i, (v, m) in enumerate(zip(values.tolist(), mults.tolist()), start=1):
                ka.SetValue(i, v)
                ma.SetValue(i, int(m))
            curve = Geom_BSplineCurve(pa, ka, ma, k, True)
            got = np.array([[p.X(), p.Y(), p.Z()] for p in (curve.Value(float(x)) for x in u)])
            assert np.abs(got - want).max() < 1e-12, (corners, len(poles))


def curve_spline_of(ctrl, degree, corners, knots, clamped):
    from gsr_cad.exporters.model import CurveSpline

    return CurveSpline(clamped, degree, knots, True, tuple(corners), ctrl)


def test_a_periodic_curve_off_by_one_pole_or_an_open_curve_read_as_closed_fails(results):
    spline = curve_spline(results["ring3d"])
    params = spline.params(4)
    poles, values, mults = spline.periodic_forms()[0]
    good = curve_checks("x", "host", spline, params, degree=spline.degree, rational=False, poles=poles,
                        knots=np.repeat(values, mults), samples=spline.points(params), periodic=True, closed=True)
    assert all(c.status == "pass" for c in good)
    turned = curve_checks("x", "host", spline, params, degree=spline.degree, rational=False,
                          poles=np.roll(poles, 1, axis=0), knots=np.repeat(values, mults), samples=None, periodic=True)
    assert {c.check: c.status for c in turned}["periodic poles"] == "FAIL"
    vee = curve_spline(results["vee3d"])
    wrong = curve_checks("x", "host", vee, params, degree=vee.degree, rational=False, poles=vee.poles,
                         knots=vee.knots, samples=None, closed=True)
    assert {c.check: c.status for c in wrong}["closed"] == "FAIL"


def test_a_dxf_spline_that_lost_its_closed_flag_or_its_z_fails(results, tmp_path):
    pytest.importorskip("ezdxf")
    import ezdxf

    from gsr_cad.exporters.dxf import CURVE_LAYER, DxfExporter

    exporter = DxfExporter()
    (path,) = exporter.export(results["ring3d"], tmp_path, "curve")
    assert all(c.status == "pass" for c in exporter.validate(path, results["ring3d"]))
    doc = ezdxf.readfile(path)
    (entity,) = doc.modelspace().query(f'SPLINE[layer=="{CURVE_LAYER}"]')
    entity.dxf.flags = entity.dxf.flags & ~1
    entity.control_points = [(x, y, 0.0) for x, y, _ in entity.control_points]
    doc.saveas(path)
    got = {c.check: c.status for c in exporter.validate(path, results["ring3d"])}
    assert got["closed"] == "FAIL" and got["poles"] == "FAIL"


def _host_helper() -> dict:
    """The pure-Python helper the FreeCAD macro and the Blender script inline (hostside/curve_knots.py)."""
    import runpy
    from importlib import resources

    return runpy.run_path(str(resources.files("gsr_cad.exporters.hostside").joinpath("curve_knots.py")))


@pytest.mark.parametrize("degree", [2, 3])
def test_the_host_scripts_knots_and_bezier_pieces_are_gsr_cads(degree):
    """The knots the host scripts compute for themselves, and the Blender script's Bezier pieces, are exactly
    those of gsr_cad.geometry.bspline, for open and closed curves with corners anywhere (seam included)."""
    from gsr_cad.exporters.encode import fill_python, host_file

    helper = _host_helper()
    for script in ("freecad_macro.py", "blender_curve.py"):  # both inline the helper
        assert "  # gsr:inline" in host_file(script) and "def form_knots(" in fill_python(script, {})
    rng = np.random.default_rng(11)
    k = degree
    for n, closed, corners in [(4, False, ()), (9, False, ()), (9, False, (k,)), (12, False, (k, 2 * k + 1)),
                               (9, True, ()), (9, True, (0,)), (9, True, (1,)), (9, True, (8,)), (10, True, (2, 7)),
                               (3 * k + 1, True, (0, k, 2 * k))]:
        assert helper["form_knots"](n, k, closed, corners) == bspline.form_knots(n, k, closed, corners).tolist()
        ctrl = rng.normal(size=(n, 3))
        knots, clamped = bspline.clamped_form(ctrl, k, closed, corners)
        got = np.array(helper["bezier_pieces"](ctrl.tolist(), k, closed, corners))
        np.testing.assert_allclose(got, bspline.bezier_pieces(knots, clamped, k), rtol=0, atol=1e-12)
        if closed:
            poles, values, mults = helper["periodic_form"](ctrl.tolist(), k, corners)
            ours = curve_spline_of(ctrl, k, corners, knots, clamped).periodic_forms()[0]
            np.testing.assert_array_equal(poles, ours[0])
            assert values == ours[1].tolist() and mults == ours[2].tolist()


def test_the_host_scripts_allow_an_op_exactly_where_gsr_cad_does():
    """The FreeCAD macro's and the Blender script's op checks (hostside/curve_knots.py) accept an add, a move or
    a corner exactly where gsr_cad's curve ops do, for every index on open and closed polygons with corners."""
    import itertools

    from gsr_cad.errors import GsrError
    from gsr_cad.ops import curve as curve_ops

    helper = _host_helper()
    checked = 0
    for k, n, closed in itertools.product((2, 3), range(4, 11), (False, True)):
        pts = np.c_[np.arange(n, dtype=float), np.zeros(n)]
        for size in (0, 1, 2):
            for corners in itertools.combinations(range(n), size):
                try:
                    state = curve_ops.Polygon(pts, (-1.0, -1.0), (n + 1.0, 1.0), closed, corners, k)
                except GsrError:
                    continue
                for index, (name, op) in itertools.product(range(n + 1), (
                        ("corner", lambda i: curve_ops.Corner(i)),
                        ("add_point", lambda i: curve_ops.AddPoint(i, (0.5, 0.5))),
                        ("move_point", lambda i: curve_ops.MovePoint(i, (0.0, 0.25))))):
                    try:
                        ours = op(index).apply(state)
                    except GsrError:
                        ours = None
                    try:
                        if name == "corner":
                            theirs = helper["with_corner"](list(state.corners), index, n, k, closed)
                        else:
                            theirs = helper["check_index"](name, index, n, closed)
                    except ValueError as exc:
                        assert ours is None, (name, index, n, k, closed, corners)
                        assert (f"{name} {index}" if name == "corner" else f"{name} index {index}") in str(exc)
                        continue
                    assert ours is not None, (name, index, n, k, closed, corners)
                    if name == "corner":
                        assert theirs == list(ours.corners)
                    checked += 1
    assert checked > 3000


def test_blender_refuses_a_corner_where_gsr_cad_allows_none(tmp_path):
    """The Blender curve script, edited to put a corner next to the end of an open curve, stops with the
    reason; the same script with the corner where gsr_cad allows it builds the curve."""
    from gsr_cad.exporters.encode import fill_python

    if not hosts.find_host("blender"):
        pytest.skip("Blender is not installed")
    template = [[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 1.0], [4.0, 0.0], [5.0, 1.0], [6.0, 0.0]]

    def script(index):
        path = tmp_path / f"corner_{index}.py"
        path.write_text(fill_python("blender_curve.py", {
            "name": "c", "degree": 3, "closed": False, "resolution": 12, "template": template,
            "steps": [{"label": "template", "op": None}, {"label": "corner", "op": {"op": "corner", "index": index}}],
        }))
        return path

    hosts.run_blender(script(3), ["--json", tmp_path / "ok.json"])
    built = json.loads((tmp_path / "ok.json").read_text())
    assert len(built["bezier"]) == 3  # two Bezier pieces meeting at the corner: 3 Bezier points
    with pytest.raises(ExportError, match="blender failed"):
        hosts.run_blender(script(2))
    run = subprocess.run([hosts.find_host("blender"), "-b", "--factory-startup", "--python-exit-code", "1",
                          "--python", str(script(2))], capture_output=True, text=True, timeout=300)
    assert run.returncode == 1
    assert "ValueError: corner 2 not allowed with corners [] on 7 points of degree 3" in run.stdout + run.stderr


def test_openscad_checks_that_a_closed_stroke_is_joined_at_its_seam(results, tmp_path):
    """The square's seam is one of its corners (a 90 degree turn): the rendered stroke passes the seam check,
    and the same file with its seam join taken out fails it with the notch's depth."""
    from gsr_cad.exporters.openscad import OpenscadExporter, stroke_width

    if not hosts.find_host("openscad"):
        pytest.skip("OpenSCAD is not installed")
    result = results["square"]
    spline = curve_spline(result)
    seam = spline.points(np.array([0.0]))[0]
    assert spline.closed and min(np.abs(seam - c).max() for c in ([0, 0], [1, 0], [1, 1], [0, 1])) < 1e-9
    exporter = OpenscadExporter()
    ((name, text),) = exporter.render_curve(result, "curve").items()
    path = tmp_path / name
    assert text.count("if (gsr_closed) let") == 1
    for joined in (True, False):
        path.write_text(text if joined else text.replace("if (gsr_closed) let", "if (false) let"))
        (seam,) = [c for c in exporter.validate_curve(path, result) if c.check == "curve: joined at the seam"]
        assert seam.passed is joined
        if not joined:  # the join's centroid, h * sqrt(2) / 3 out along the bisector: h / 3 from the notch's sides
            assert seam.deviation == pytest.approx(stroke_width(spline) / 2 / 3, rel=0.02)
