"""What a run prints and records for a user who works in mm: tolerances in, distances out, both ways."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gsr_cad.cli.summary import EXIT_TOLERANCE_MISSED, summary_lines, template_warning, warning_lines
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.result import Result

FAST = ["--initial-population", "60", "--population", "20", "--generations", "8", "--quiet", "--formats", "none"]
SMALL_SURFACE = ["--population", "8", "--initial-population", "8", "--n-parents", "4", "--n-perturb", "2",
                 "--n-newcomers", "2", "--generations", "1", "--quiet", "--formats", "none", "--seed", "1"]


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    from gsr_cad.reconstruct.samples import get_sample

    path = tmp_path_factory.mktemp("c") / "noisy.csv"
    get_sample("bspline_07_noisy").write(path)
    return path


def test_a_tolerance_in_mm_is_met_and_read_back_in_mm(gsr, noisy, tmp_path):
    run = gsr("curve", noisy, "-o", tmp_path / "o", "--units", "mm", "--max-distance", "0.5", *FAST)
    assert run.code == 0, run.err
    data = json.loads((tmp_path / "o" / "result.json").read_text())
    m, cfg = data["metrics"], data["config"]
    diag = cfg["target"]["diagonal"]
    assert cfg["units"] == "mm" and m["units"] == "mm" and m["diagonal"] == pytest.approx(diag)
    assert cfg["max_distance"] == pytest.approx(0.5 / diag)  # held as a fraction of the diagonal
    assert m["max_distance_model"] == pytest.approx(m["max_distance"] * diag)
    assert m["mean_distance_model"] == pytest.approx(m["mean_distance"] * diag)
    assert f"max-distance tolerance 0.5 mm ({100 * 0.5 / diag:.3g} %): met" in run.out
    assert f"max {m['max_distance_model']:.3g} mm ({100 * m['max_distance']:.3g} %)" in run.out
    assert "stopped: " in run.out and run.err == ""
    page = (tmp_path / "o" / "report.html").read_text(encoding="utf-8")  # the interactive report, beside it
    assert "lengths in mm" in page and "deviation, mm" in page


def test_a_missed_tolerance_warns_once_and_exits_3(gsr, noisy, tmp_path):
    run = gsr("curve", noisy, "-o", tmp_path / "o", "--units", "in", "--max-distance", "0.01%", *FAST,
              "--max-seconds", "4")
    assert run.code == EXIT_TOLERANCE_MISSED
    assert "MISSED" in run.out and (tmp_path / "o" / "result.json").exists()
    (line,) = run.err.splitlines()
    assert line.startswith("warning: tolerance missed: max distance ") and line.endswith("in (0.01 %)")


def test_a_cloud_records_no_mean_distance_to_target_and_an_offset_template_warns(gsr, tmp_path):
    from gsr_cad.reconstruct.samples import get_sample

    sample = get_sample("extended")
    cloud = sample.write_cloud(tmp_path / "t.xyz")
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) + [7.0, 0, 0]
    template = PolyMesh.from_faces(cube, [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                                          [1, 5, 7, 3]])
    from gsr_cad.reconstruct.meshio import save_obj

    path = save_obj(template, tmp_path / "cage.obj")
    run = gsr("surface", cloud, "-o", tmp_path / "o", "--template", path, "--no-fit-template", *SMALL_SURFACE)
    assert run.code == 0, run.err
    metrics = json.loads((tmp_path / "o" / "result.json").read_text())["metrics"]
    assert "mean_distance_to_target" not in metrics and "mean_distance_model" in metrics
    (line,) = run.err.splitlines()
    assert line.startswith(f"warning: template {path} is used where it is, not placed on the target")
    lines = run.out.splitlines()
    assert "mixed" not in lines[0] and any("the paper's mixed mean distance" in x for x in lines[1:])
    # the default cube, or a template on the target, says nothing
    target = surface_target(sample.target)
    assert template_warning(template, target, "cube") is None
    placed = PolyMesh.from_faces(target.bbox[0] + (cube - [7.0, 0, 0]) * np.ptp(target.bbox, axis=0),
                                 [list(f) for f in template.faces])
    assert template_warning(placed, target, "cage.obj") is None


def result_with(metrics: dict, config: dict | None = None) -> Result:
    cfg = {"target": {"name": "t", "diagonal": 200.0}, "units": "mm", **(config or {})}
    return Result(kind="curve", config=cfg, seed=0, genome=(), metrics=metrics, history=[],
                  control_points=np.zeros((4, 2)))


def test_two_sided_keys_are_shown_when_present_and_the_old_ones_otherwise(tmp_path):
    old = summary_lines(result_with({"mean_distance": 1e-4, "max_distance": 5e-4, "stop_reason": "stall"}), tmp_path)
    assert "  data to fit: mean distance 0.02 mm (0.01 %), max 0.1 mm (0.05 %)" in old
    assert not [line for line in old if "fit to data" in line]  # not measured: no line
    assert "no improvement" in old[0]
    new = summary_lines(result_with({"mean_distance": 1.0, "max_distance": 1.0, "data_to_fit_mean": 1e-4,
                                     "data_to_fit_max": 2e-4, "fit_to_data_mean": 3e-4, "fit_to_data_max": 4e-4,
                                     "tolerance_met": False}, {"max_distance": 1e-3}), tmp_path)
    assert "  data to fit: mean distance 0.02 mm (0.01 %), max 0.04 mm (0.02 %)" in new
    assert "  fit to data: mean distance 0.06 mm (0.03 %), max 0.08 mm (0.04 %)" in new
    assert "  max-distance tolerance 0.2 mm (0.1 %): MISSED" in new  # tolerance_met decides, when present
    (warning,) = warning_lines(result_with({"data_to_fit_max": 2e-3}, {"max_distance": 1e-3}))
    assert warning == "warning: tolerance missed: max distance 0.4 mm (0.2 %) > --max-distance 0.2 mm (0.1 %)"
    assert warning_lines(result_with({"max_distance": 1e-4}, {"max_distance": 1e-3})) == []


def test_ops_are_counted_once_whether_stored_as_letters_or_counted():
    """A long history's ``ops`` is stored counted (``V8 E L V24``); the summary must not count it again."""
    from gsr_cad.reconstruct.summary import run_length

    assert run_length("VVVVVVVVELVV") == "V8 E L V2"
    assert run_length("V8 E L V24 L15") == "V8 E L V24 L15"
    assert run_length(run_length("LLSVVV")) == run_length("LLSVVV") == "L2 S V3"
    assert run_length("") == ""
