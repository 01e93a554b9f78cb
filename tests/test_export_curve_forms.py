"""Closed and cornered curves in the exports: the formats that carry them exactly do, and pass their host
round trips; the history scripts that cannot yet are skipped by a default export (with a warning) and refused
when asked for, never written wrong."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import gsr_cad
from gsr_cad.errors import ExportError, GsrWarning
from gsr_cad.reconstruct.curve import reconstruct_curve
from gsr_cad.reconstruct.export import default_formats
from gsr_cad.reconstruct.inputs import curve_target


@pytest.fixture(scope="module")
def square_result():
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    pts = np.vstack([np.linspace(corners[i], corners[i + 1], 40, endpoint=False) for i in range(4)])
    result = reconstruct_curve(curve_target(pts), seed=1)
    assert result.config["closed"] and result.config["corners"]
    return result


def test_default_export_skips_what_cannot_carry_the_form_and_says_so(square_result, tmp_path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        files = gsr_cad.export(square_result, tmp_path)
    skipped = {str(w.message).split()[1] for w in caught if issubclass(w.category, GsrWarning)}
    assert skipped == {"blender", "fcmacro"} & set(default_formats("curve"))
    assert not any(p.name.endswith(("_blender.py", ".FCMacro")) for p in files)
    assert {p.suffix for p in files} >= {".step", ".dxf", ".svg"}


@pytest.mark.parametrize("fmt", ["fcmacro", "blender"])
def test_an_explicit_format_that_cannot_carry_it_is_refused(square_result, tmp_path, fmt):
    with pytest.raises(ExportError, match="cannot carry this result"):
        gsr_cad.export(square_result, tmp_path, [fmt])
    assert not any(tmp_path.iterdir())


def test_closed_cornered_exports_pass_their_round_trips(square_result, tmp_path):
    gsr_cad.export(square_result, tmp_path, ["step", "dxf", "svg"])
    square_result.save(tmp_path)
    checks = gsr_cad.validate(tmp_path)
    failed = [(c.file, c.check, c.detail) for c in checks if c.status == "FAIL"]
    assert checks and not failed, failed
    assert {c.file for c in checks if c.status == "pass"} >= {"curve.step", "curve.dxf", "curve.svg"}


def test_a_3d_curve_is_refused_by_the_planar_formats_not_written_flat(tmp_path):
    t = np.linspace(0.0, 4.0 * np.pi, 300)
    result = reconstruct_curve(curve_target(np.c_[np.cos(t), np.sin(t), 0.2 * t]), seed=1)
    assert np.asarray(result.control_points).shape[1] == 3
    with pytest.raises(ExportError, match="3D"):
        gsr_cad.export(result, tmp_path, ["step"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GsrWarning)
        assert gsr_cad.export(result, tmp_path) == []
