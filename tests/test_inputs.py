"""Curve input loading: every malformed input is a one-line InputError."""

import numpy as np
import pytest

from gsr_cad.errors import InputError
from gsr_cad.reconstruct.inputs import curve_target, load_curve_points


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_reads_csv_with_header_and_npy(tmp_path):
    pts = np.column_stack([np.linspace(0, 1, 10), np.sin(np.linspace(0, 1, 10))])
    csv = write(tmp_path, "a.csv", "x,y\n" + "\n".join(f"{x},{y}" for x, y in pts))
    np.save(tmp_path / "a.npy", pts)
    txt = write(tmp_path, "a.txt", "\n".join(f"{x} {y}" for x, y in pts))
    for path in (csv, tmp_path / "a.npy", txt):
        np.testing.assert_allclose(load_curve_points(path), pts)


@pytest.mark.parametrize("text, message", [
    ("", "empty"),
    ("x,y\n", "no data rows"),
    ("0,0\n1,a\n2,2\n3,3\n", "non-numeric"),
    ("0,0\n1,nan\n2,2\n3,3\n", "NaN"),
    ("0,0\n1,inf\n2,2\n3,3\n", "NaN or infinite"),
    ("0,0\n1,1\n2,2\n", "at least 4 points"),
    ("0,0,0,0\n1,1,1,1\n2,2,2,2\n3,3,3,3\n", "columns"),
    ("1,1\n1,1\n1,1\n1,1\n", "all points are equal"),
    ("0,0\n1,1\n1,1\n2,2\n3,3\n", "duplicates"),
    ("0,0\n1,1,1\n2,2\n3,3\n", "different numbers of columns"),
])
def test_bad_files(tmp_path, text, message):
    path = write(tmp_path, "bad.csv", text)
    with pytest.raises(InputError, match=message) as info:
        load_curve_points(path)
    assert "\n" not in str(info.value)


def test_missing_and_unsupported(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_curve_points(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="unsupported"):
        load_curve_points(write(tmp_path, "a.stl", "solid"))
    with pytest.raises(InputError, match="directory"):
        load_curve_points(tmp_path)


def test_target_scale():
    t = curve_target(np.array([[0, 0], [3, 0], [3, 4], [0, 4.0]]))
    assert t.diagonal == pytest.approx(5.0)
