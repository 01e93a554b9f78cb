"""``gsr replay`` and ``gsr validate``: re-export without re-running, round-trip table, exit codes."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.image import imread
from test_export_results import hand_result

from gsr_cad.exporters import hosts

FAST = "step,dxf,svg"


@pytest.fixture
def saved(tmp_path):
    """A result.json in its own directory, as ``gsr curve`` leaves it."""
    result = hand_result(seed=21, n_ops=7, scale=4.0)
    result.save(tmp_path / "run")
    return result, tmp_path / "run" / "result.json"


def test_replay_writes_exports_csv_and_result(gsr, saved, tmp_path):
    result, source = saved
    out = tmp_path / "again"
    run = gsr("replay", source, "-o", out, "--formats", FAST)
    assert run.code == 0, run.err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["control_points.csv", "curve.dxf", "curve.step", "curve.svg", "exports.json", "result.json"]
    assert (out / "result.json").read_bytes() == source.read_bytes()
    csv = np.loadtxt(out / "control_points.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(csv, result.control_points)
    assert run.out.count("wrote ") == 5

    check = gsr("validate", out)
    assert check.code == 0, check.out + check.err
    header, *rows, summary = check.out.strip().splitlines()
    assert header.split()[:5] == ["file", "host", "check", "deviation", "result"]
    assert {r.split()[0] for r in rows} == {"curve.dxf", "curve.step", "curve.svg"}
    assert all(" pass " in r or " skip " in r for r in rows)
    assert summary.startswith("validate: ") and " 0 FAIL" in summary


def test_replay_into_its_own_directory_keeps_result_json(gsr, saved):
    _, source = saved
    before = source.read_bytes()
    run = gsr("replay", source.parent, "-o", source.parent, "--formats", "svg")
    assert run.code == 0, run.err
    assert source.read_bytes() == before
    assert (source.parent / "curve.svg").is_file()


def test_validate_fails_on_a_hand_edited_file(gsr, saved, tmp_path):
    result, source = saved
    out = tmp_path / "edit"
    assert gsr("replay", source, "-o", out, "--formats", "dxf,svg").code == 0
    dxf = out / "curve.dxf"
    x = repr(float(result.control_points[2][0]))
    dxf.write_text(dxf.read_text().replace(x, repr(float(x) + 0.5), 1))
    run = gsr("validate", out)
    assert run.code == 1
    failed = [r for r in run.out.splitlines() if " FAIL " in r]
    assert failed and all(r.startswith("curve.dxf") for r in failed)
    assert any(" poles " in r for r in failed)


@pytest.mark.parametrize("damage", ["version", "malformed", "not json", "missing"])
def test_replay_rejects_a_bad_result_and_writes_nothing(gsr, saved, tmp_path, damage):
    _, source = saved
    data = json.loads(source.read_text())
    if damage == "version":
        data["version"] = 99
        source.write_text(json.dumps(data))
    elif damage == "malformed":
        data["control_points"] = [[0.0, "x"]]
        source.write_text(json.dumps(data))
    elif damage == "not json":
        source.write_text("{ half a file")
    else:
        source.unlink()
    out = tmp_path / "never"
    run = gsr("replay", source, "-o", out)
    assert run.code == 2
    assert run.err.startswith("error: ") and len(run.err.strip().splitlines()) == 1
    assert not out.exists()


def test_replay_reports_bad_formats_and_directories(gsr, saved, tmp_path):
    _, source = saved
    run = gsr("replay", source, "-o", tmp_path / "a", "--formats", "step,iges")
    assert run.code == 2 and "unknown format 'iges'" in run.err and not (tmp_path / "a").exists()
    blocker = tmp_path / "file"
    blocker.write_text("")
    run = gsr("replay", source, "-o", blocker / "sub", "--formats", "svg")
    assert run.code == 2 and run.err.startswith("error: ") and len(run.err.strip().splitlines()) == 1


def test_replay_reports_a_missing_library_for_a_requested_format(saved, tmp_path):
    """With ezdxf unimportable (Python's documented import block), asking for DXF is a clean error."""
    _, source = saved
    out = tmp_path / "nodxf"
    code = ("import sys; sys.modules['ezdxf'] = None\n"
            "from gsr_cad.cli import main\n"
            f"sys.exit(main(['replay', {str(source)!r}, '-o', {str(out)!r}, '--formats', 'svg,dxf']))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == \
        "error: format 'dxf' is unavailable: ezdxf is not installed (pip install 'gsr-cad[cad]')"
    assert not out.exists()


def test_validate_exit_2_when_nothing_can_be_checked(gsr, saved, tmp_path, monkeypatch):
    _, source = saved
    run = gsr("validate", source.parent)
    assert run.code == 2 and "no exported files" in run.err
    assert gsr("validate", tmp_path / "nowhere").code == 2
    if hosts.find_host("openscad") is None:
        pytest.skip("OpenSCAD not installed: the host-missing case below needs it installed to hide it")
    out = tmp_path / "scad"
    assert gsr("replay", source, "-o", out, "--formats", "scad").code == 0
    monkeypatch.setenv("GSR_OPENSCAD", str(tmp_path / "no-such-openscad"))
    run = gsr("validate", out)
    assert run.code == 2 and "none of their hosts is installed" in run.err
    assert " skip " in run.out and "OpenSCAD is not installed" in run.out
    monkeypatch.delenv("GSR_OPENSCAD")
    assert gsr("validate", out).code == 0


def test_cli_help_lists_replay_and_validate():
    from gsr_cad.cli import build_parser

    text = build_parser().format_help()
    assert "replay" in text and "validate" in text


def test_curve_then_replay_reproduces_the_exports(gsr, tmp_path):
    from conftest import SAMPLES

    first, again = tmp_path / "first", tmp_path / "again"
    run = gsr("curve", SAMPLES / "curves" / "bspline_07.csv", "-o", first, "--seed", "2", "--generations", "3",
              "--population", "20", "--initial-population", "40", "--quiet", "--formats", "svg,dxf,step")
    assert run.code == 0, run.err
    assert gsr("validate", first).code == 0
    assert gsr("replay", first, "-o", again, "--formats", "svg,dxf").code == 0
    for name in ("control_points.csv", "curve.svg", "result.json"):
        assert (again / name).read_bytes() == (first / name).read_bytes(), name
    check = gsr("validate", again)
    assert check.code == 0 and "curve.dxf" in check.out


def test_a_closed_3d_curve_end_to_end_through_the_cli(gsr, tmp_path):
    """``gsr curve`` on (x, y, z) data writes every format that carries a space curve (SVG and OpenSCAD are
    skipped with a warning), the manifest lists exactly those files, and ``gsr validate`` passes them all."""
    s = np.linspace(0.0, 2.0 * np.pi, 160, endpoint=False)
    data = tmp_path / "ring.csv"
    np.savetxt(data, np.c_[np.cos(s), np.sin(s), 0.3 * np.sin(2.0 * s)], delimiter=",")
    out = tmp_path / "out"
    run = gsr("curve", data, "-o", out, "--seed", "1", "--quiet", "--formats", "step,dxf,cadquery,fcmacro")
    assert run.code == 0, run.err
    assert run.err == ""  # no warning: the reports draw space curves too
    result = json.loads((out / "result.json").read_text())
    assert result["config"]["closed"] and len(result["control_points"][0]) == 3
    for name in ("report.png", "report.html"):
        assert f"wrote {out / name}" in run.out
    assert imread(out / "report.png").shape[1] == 8 * 110  # report.png at its default size
    page = (out / "report.html").read_text(encoding="utf-8")
    assert page.count('"type":"scatter3d"') >= 4 and '"aspectmode":"data"' in page  # a 3D scene, not a plane
    manifest = json.loads((out / "exports.json").read_text())["files"]
    assert sorted(manifest) == ["curve.FCMacro", "curve.dxf", "curve.step", "curve_cadquery.py"]
    assert gsr("replay", out, "-o", out, "--formats", "svg").code == 2  # planar by nature: refused, one line
    check = gsr("validate", out)
    assert check.code == 0, check.out
    rows = check.out.strip().splitlines()[1:-1]
    assert {r.split()[0] for r in rows} == set(manifest)
    if hosts.find_host("freecad"):
        assert any(r.startswith("curve.FCMacro") and " periodic poles " in r and " pass " in r for r in rows)
    assert sorted(json.loads((out / "exports.json").read_text())["files"]) == sorted(manifest)
