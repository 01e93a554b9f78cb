"""Bundled samples: registry, geometry against independent oracles, bundled files, and ``gsr sample``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.interpolate import BSpline
from scipy.special import fresnel

from gsr_cad.errors import InputError
from gsr_cad.reconstruct import samples as S
from gsr_cad.reconstruct.inputs import load_curve_points

REPO = Path(__file__).resolve().parents[1]
CURVES = REPO / "samples" / "curves"
BSPLINES = {"bspline_05": 5, "bspline_07": 7, "bspline_09": 9, "bspline_12": 12}
ANALYTIC = ("sine_arc", "spiral", "glyph_s", "clothoid")
REQUIRED = (*BSPLINES, *ANALYTIC, "bspline_07_noisy", "bspline_07_sparse")


def fresh(name: str) -> S.CurveSample:
    """Build a sample bypassing the registry's cache (to check determinism)."""
    return S.CURVE_SAMPLES[name].__wrapped__()


def scipy_clamped(ctrl: np.ndarray, degree: int = 3) -> BSpline:
    """Independent oracle: clamped uniform knots written out here, evaluated by scipy."""
    n_spans = len(ctrl) - degree
    knots = np.r_[np.zeros(degree), np.linspace(0.0, 1.0, n_spans + 1), np.ones(degree)]
    return BSpline(knots, ctrl, degree)


def read_csv(path: Path) -> np.ndarray:
    with open(path, encoding="utf-8") as fh:
        assert fh.readline().strip() == "x,y"
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_registry_lists_every_required_curve_with_a_description():
    assert set(REQUIRED) <= set(S.sample_names("curve"))
    for name in S.sample_names():
        info = S.SAMPLES[name]
        assert info.kind in S.KIND_DIRS and info.description and "\n" not in info.description
    assert S.sample_names("surface") == [n for n, i in S.SAMPLES.items() if i.kind == "surface"]


@pytest.mark.parametrize("name", REQUIRED)
def test_sample_shape_determinism_and_read_only(name):
    s = S.get_sample(name)
    assert s.name == name and s.kind == "curve" and s.description == S.SAMPLES[name].description
    expected_n = round(S.SPARSE_KEEP * S.N_POINTS) if name.endswith("_sparse") else S.N_POINTS
    assert s.points.shape == (expected_n, 2) and s.clean.shape == (S.N_CLEAN, 2)
    assert np.all(np.isfinite(s.points)) and np.all(np.isfinite(s.clean))
    again = fresh(name)
    assert again is not s
    np.testing.assert_array_equal(again.points, s.points)
    np.testing.assert_array_equal(again.clean, s.clean)
    with pytest.raises(ValueError):
        s.points[0, 0] = 1.0
    # the target starts and ends where the clean curve does (ends are kept even when sparse)
    tol = 5 * S.NOISE_SIGMA * s.diagonal if name.endswith("_noisy") else 1e-12
    np.testing.assert_allclose(s.points[[0, -1]], s.clean[[0, -1]], atol=tol)


@pytest.mark.parametrize("name,n_ctrl", BSPLINES.items())
def test_bspline_samples_match_scipy_at_uniform_parameters(name, n_ctrl):
    s = S.get_sample(name)
    assert s.truth_ctrl.shape == (n_ctrl, 2) and s.degree == 3
    spline = scipy_clamped(s.truth_ctrl)
    np.testing.assert_allclose(s.points, spline(np.linspace(0, 1, S.N_POINTS)), atol=1e-12)
    np.testing.assert_allclose(s.clean, spline(np.linspace(0, 1, S.N_CLEAN)), atol=1e-12)
    # shapes with character: the polygon is not degenerate and the curve bends (not a straight stroke)
    centred = s.points - s.points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    assert sv[1] / sv[0] > 0.2


def _arc_spacing_cv(points: np.ndarray) -> float:
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return float(seg.std() / seg.mean())


@pytest.mark.parametrize("name", ANALYTIC)
def test_analytic_samples_are_evenly_spaced_by_arc_length_and_have_no_truth(name):
    s = S.get_sample(name)
    assert s.truth_ctrl is None and not s.has_truth
    assert _arc_spacing_cv(s.points) < 2e-3
    assert _arc_spacing_cv(s.clean) < 2e-3


def test_sine_arc_lies_on_its_formula():
    s = S.get_sample("sine_arc")
    for pts in (s.points, s.clean):
        np.testing.assert_allclose(pts[:, 1], 3.0 * np.sin(2 * np.pi * pts[:, 0] / 10.0), atol=1e-6)
    assert s.points[:, 0].min() == pytest.approx(0.0) and s.points[:, 0].max() == pytest.approx(10.0)


def test_spiral_radius_grows_linearly_over_one_and_a_half_turns():
    s = S.get_sample("spiral")
    theta = np.unwrap(np.arctan2(s.points[:, 1], s.points[:, 0]))
    theta -= theta[0]
    r = np.linalg.norm(s.points, axis=1)
    np.testing.assert_allclose(r, 0.5 + 1.5 * theta / np.pi, atol=1e-6)
    assert theta[-1] == pytest.approx(3 * np.pi, abs=1e-9)


def test_clothoid_is_fresnel_at_arc_length():
    s = S.get_sample("clothoid")
    # a clothoid's parameter is its arc length: evenly spaced by arc length means evenly spaced in t
    fs, fc = fresnel(np.linspace(0.0, 2.0, S.N_POINTS))
    np.testing.assert_allclose(s.points, 10.0 * np.column_stack([fc, fs]), atol=1e-6)


def test_glyph_s_is_two_tangent_bowls_and_a_straight_spine():
    s = S.get_sample("glyph_s")
    p = s.clean / np.array([2.6, 2.0])
    d = 1.25
    on_upper = np.abs(np.linalg.norm(p - [0, d], axis=1) - 1.0)
    on_lower = np.abs(np.linalg.norm(p + [0, d], axis=1) - 1.0)
    tangent_dir = np.array([1 / d, -np.sqrt(1 - 1 / d**2)])  # the bowls' inner common tangent, through 0
    on_spine = np.abs(p @ np.array([-tangent_dir[1], tangent_dir[0]]))
    assert np.max(np.minimum(np.minimum(on_upper, on_lower), on_spine)) < 1e-6
    assert np.sum(on_spine < 1e-9) > 100  # the spine really is straight, not just close to a circle
    # an S turns by 180 degrees onto itself: reversing it equals rotating it
    np.testing.assert_allclose(s.points[::-1], -s.points, atol=1e-9)
    # it bends both ways (an S, not a C): the signed turning changes sign along the stroke
    v = np.diff(s.points, axis=0)
    turn = v[:-1, 0] * v[1:, 1] - v[:-1, 1] * v[1:, 0]
    assert turn.max() > 0 > turn.min()


def test_noisy_sample_adds_gaussian_noise_of_the_stated_sigma():
    base, noisy = S.get_sample("bspline_07"), S.get_sample("bspline_07_noisy")
    np.testing.assert_array_equal(noisy.truth_ctrl, base.truth_ctrl)
    np.testing.assert_array_equal(noisy.clean, base.clean)
    residual = noisy.points - base.points
    sigma = S.NOISE_SIGMA * base.diagonal
    assert residual.std() == pytest.approx(sigma, rel=0.1)
    assert np.abs(residual.mean(axis=0)).max() < 4 * sigma / np.sqrt(len(residual))
    # the noise is independent per coordinate (no structure borrowed from the curve)
    assert abs(np.corrcoef(residual[:, 0], residual[:, 1])[0, 1]) < 0.2


def test_sparse_sample_is_an_ordered_quarter_of_the_dense_one_with_its_ends():
    base, sparse = S.get_sample("bspline_07"), S.get_sample("bspline_07_sparse")
    idx = [int(np.flatnonzero(np.all(base.points == p, axis=1))[0]) for p in sparse.points]
    assert idx[0] == 0 and idx[-1] == len(base.points) - 1
    assert np.all(np.diff(idx) > 0)
    assert len(idx) == len(base.points) // 4
    assert max(np.diff(idx)) > 4  # really removed at random, not every fourth sample
    np.testing.assert_array_equal(sparse.truth_ctrl, base.truth_ctrl)


def test_unknown_name_and_missing_truth_raise_input_errors(tmp_path):
    with pytest.raises(InputError, match="unknown sample 'nope'.*bspline_05"):
        S.get_sample("nope")
    with pytest.raises(InputError, match="no ground-truth"):
        S.get_sample("spiral").write_truth(tmp_path / "t.csv")
    assert not (tmp_path / "t.csv").exists()


def test_registering_a_taken_name_or_unknown_kind_fails():
    with pytest.raises(ValueError, match="taken"):
        S.register("curve", "bspline_05", "duplicate")(lambda name, description: None)
    with pytest.raises(ValueError, match="kind"):
        S.register("volume", "cube_volume", "no such kind")


@pytest.mark.parametrize("name", REQUIRED)
def test_bundled_files_are_what_the_generators_make(name):
    s = S.get_sample(name)
    np.testing.assert_allclose(read_csv(CURVES / f"{name}.csv"), s.points, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(read_csv(CURVES / f"{name}.clean.csv"), s.clean, rtol=1e-11, atol=1e-11)
    truth = CURVES / f"{name}.truth.csv"
    assert truth.exists() == s.has_truth
    if s.has_truth:
        np.testing.assert_allclose(read_csv(truth), s.truth_ctrl, rtol=1e-11, atol=1e-11)


def test_bundle_listing_and_readme_cover_exactly_the_files(tmp_path):
    listing = S.bundle_all(tmp_path)
    written = {p.name for p in (tmp_path / "curves").iterdir()}
    assert written == set(listing["curves"]) | {"README.md"}
    readme = (tmp_path / "curves" / "README.md").read_text()
    for fname in listing["curves"]:
        assert f"`{fname}`" in readme
    # the committed folder holds the same file set and README as a fresh regeneration
    assert {p.name for p in CURVES.iterdir()} == written
    assert (CURVES / "README.md").read_text() == readme


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 30), st.just(2)),
              elements=st.floats(-1e9, 1e9, allow_nan=False, allow_infinity=False, width=64)))
def test_csv_round_trips_to_twelve_significant_digits(tmp_path_factory, pts):
    path = tmp_path_factory.mktemp("csv") / "p.csv"
    S.write_points_csv(path, pts)
    np.testing.assert_allclose(read_csv(path), pts, rtol=1e-11, atol=1e-300)


# --- gsr sample ---------------------------------------------------------------------------------------------

def test_cli_writes_sample_truth_and_clean(gsr, tmp_path):
    run = gsr("sample", "bspline_09", "-o", tmp_path / "t.csv", "--truth", tmp_path / "truth.csv",
              "--clean", tmp_path / "c.npy")
    assert run.code == 0, run.err
    s = S.get_sample("bspline_09")
    np.testing.assert_allclose(load_curve_points(tmp_path / "t.csv"), s.points, rtol=1e-11)
    np.testing.assert_allclose(load_curve_points(tmp_path / "truth.csv"), s.truth_ctrl, rtol=1e-11)
    np.testing.assert_array_equal(np.load(tmp_path / "c.npy"), s.clean)
    assert run.out.count("wrote ") == 3


def test_cli_list_shows_every_sample_with_its_description(gsr):
    run = gsr("sample", "--list")
    assert run.code == 0
    lines = run.out.strip().splitlines()
    registry = S.all_samples()
    assert len(lines) == len(registry) and set(REQUIRED) <= set(registry)
    for line, info in zip(lines, registry.values()):
        assert line.split()[0] == info.name and line.endswith(info.description)


@pytest.mark.parametrize("args,message", [
    (("sample", "no_such_curve", "-o", "{tmp}/x.csv"), "unknown sample 'no_such_curve'"),
    (("sample",), "needs a NAME"),
    (("sample", "spiral"), "needs -o FILE"),
    (("sample", "spiral", "-o", "{tmp}/x.csv", "--bogus"), "unrecognized arguments"),
    (("sample", "spiral", "-o", "{tmp}/x.csv", "--cloud", "{tmp}/c.xyz"), "--cloud does not apply to curve"),
])
def test_cli_errors_are_one_line_exit_2(gsr, tmp_path, args, message):
    run = gsr(*(a.format(tmp=tmp_path) for a in args))
    assert run.code == 2
    assert run.err.startswith("error: ") and message in run.err and run.err.count("\n") == 1
    assert not (tmp_path / "x.csv").exists()


def test_cli_truth_of_a_sample_without_one_is_a_note_not_a_file(gsr, tmp_path):
    run = gsr("sample", "clothoid", "-o", tmp_path / "c.csv", "--truth", tmp_path / "truth.csv")
    assert run.code == 0
    assert (tmp_path / "c.csv").exists() and not (tmp_path / "truth.csv").exists()
    assert "no ground truth" in run.err


# --- benchmarks/curves.py --quick -----------------------------------------------------------------------

def test_quick_curve_benchmark_runs_and_baselines_meet_the_tolerance(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "curves.md"
    proc = subprocess.run([sys.executable, str(REPO / "benchmarks" / "curves.py"), "--quick", "--samples",
                           "bspline_05", "--tolerance", "1e-3", "--out", str(out)],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in out.read_text().splitlines()
            if line.startswith("| bspline_05")]
    by_method = {r[1]: r for r in rows}
    assert list(by_method) == ["gsr default", "gsr @ tolerance", "gsr paper", "scipy splprep", "scipy lsq"]
    for r in rows:
        n_ctrl, data_max, clean_mean, clean_max, seconds = int(r[2]), float(r[3]), float(r[5]), float(r[6]), float(r[7])
        assert n_ctrl >= 4 and 0 <= clean_mean <= clean_max and seconds >= 0 and data_max >= 0
        assert (r[4] == "yes") == (data_max <= 1e-3)
    for method in ("scipy splprep", "scipy lsq"):
        assert by_method[method][4] == "yes"
    # data sampled at uniform parameters of a 5-point clamped cubic: least squares recovers it exactly
    lsq = by_method["scipy lsq"]
    assert int(lsq[2]) == 5 and float(lsq[6]) < 1e-9
