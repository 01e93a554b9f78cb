"""``gsr batch`` on a real 2-worker dask LocalCluster: 6 targets (curves and surfaces), one bad; the summary
is right, the bad target fails alone, and a second run skips the targets already done."""

from __future__ import annotations

import csv

import pytest
from cli_subprocess import gsr

from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.samples import get_sample

pytest.importorskip("dask.distributed")

SETTINGS = ["--set", "max-seconds=60", "--set", "curve.generations=3", "--set", "curve.population=6",
            "--set", "curve.initial-population=12", "--set", "surface.generations=1", "--set", "surface.population=4",
            "--set", "surface.initial-population=4", "--set", "surface.n-parents=2", "--set", "surface.n-perturb=1",
            "--set", "surface.no-simplify-history=", "--set", "surface.final-polish-rounds=2"]


def _targets(d):
    names = []
    for name, file in (("bspline_05", "hook.csv"), ("bspline_07", "wave.csv"), ("sine_arc", "sine.npy"),
                       ("spiral", "spiral.csv"), ("extended", "box.obj")):
        get_sample(name).write(d / file)
        names.append(file)
    (d / "bad.csv").write_text("x,y\n0,0\n1,1\n")  # too few points: fails in its own run
    names.insert(3, "bad.csv")
    return names


def _rows(out):
    with open(out / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_batch_on_two_workers_survives_a_bad_target_and_resumes(tmp_path):
    names = _targets(tmp_path)
    argv = ["batch", *names, "-o", "out", "--workers", "2", "--seed", "1", *SETTINGS,
            "--timeout", "300"]
    first = gsr(argv, tmp_path, timeout=600)
    assert "Traceback" not in first.err, first.describe()
    assert first.code == 1, first.describe()  # some targets failed
    rows = _rows(tmp_path / "out")
    assert [r["target"] for r in rows] == names
    status = {r["target"]: r["status"] for r in rows}
    assert status.pop("bad.csv") == "failed"
    assert set(status.values()) == {"done"}, rows
    bad = next(r for r in rows if r["target"] == "bad.csv")
    assert "need at least 4 points" in bad["error"]
    kinds = {r["target"]: r["kind"] for r in rows}
    assert kinds["box.obj"] == "surface" and kinds["sine.npy"] == "curve"
    for r in rows:
        if r["status"] == "done":
            result = Result.load(tmp_path / "out" / r["out"].split("/")[-1])
            assert float(r["data_to_fit_mean"]) > 0 and int(r["controls"]) >= 4
            assert int(r["ops"]) == len(result.genome)
            if r["kind"] == "surface":  # the cluster's workers share the CPUs: one refinement process each
                assert result.config["refine_workers"] == 1
    assert sum(line.startswith("[") for line in first.out.splitlines()) == 6
    assert "batch: 6/6 targets finished, 1 failed" in first.out
    md = (tmp_path / "out" / "summary.md").read_text()
    assert md.count("\n") == 8 and "| bad.csv | curve | failed |" in md

    mtime = (tmp_path / "out" / "hook" / "result.json").stat().st_mtime_ns
    second = gsr(argv, tmp_path, timeout=600)
    assert "skipping 5 target(s) already done" in second.out, second.describe()
    assert (tmp_path / "out" / "hook" / "result.json").stat().st_mtime_ns == mtime
    rows2 = _rows(tmp_path / "out")
    assert [r["status"] for r in rows2].count("done (earlier run)") == 5


def test_batch_refuses_bad_arguments_before_starting(tmp_path):
    get_sample("bspline_05").write(tmp_path / "a.csv")
    for args, reason in ((["--workers", "0"], "--workers must lie in"), (["--timeout", "nan"], "--timeout"),
                         (["--set", "oops"], "FIELD=VALUE"), (["--seed", "-3"], "seed must lie")):
        run = gsr(["batch", "a.csv", "-o", "out", *args], tmp_path)
        assert run.code == 2 and reason in run.err and len(run.err_lines) == 1, run.describe()
    assert not (tmp_path / "out").exists()
