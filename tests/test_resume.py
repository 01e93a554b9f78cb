"""Checkpoints and resume: a run stopped after some generations and resumed from its checkpoint gives
bit-identical genomes to the uninterrupted run with the same seed (API and CLI)."""

from __future__ import annotations

import json
import signal
import time

import numpy as np
import pytest
from cli_subprocess import assert_clean, gsr, popen

from gsr_cad import genome as genome_mod
from gsr_cad.errors import InputError
from gsr_cad.reconstruct.curve import reconstruct_curve
from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.samples import get_sample
from gsr_cad.reconstruct.surface import reconstruct_surface

CURVE = dict(generations=12, stall_generations=0, population=20, initial_population=40)
SURFACE = dict(generations=3, population=6, initial_population=6, n_parents=4, max_children=2, n_perturb=2,
               n_newcomers=2, final_polish_rounds=2, polish_rounds=1, simplify_history=False,
               op_kinds="VELBFS",  # no inset: the protrusion start would solve inset_extrude at generation 0
               refine_max_faces=24, refine_seconds=0,  # a short refinement, bounded by faces, not seconds
               refine_points=3000)


def _stop_after(generation: int):
    """A progress callback and a should_stop that turns true once ``generation`` has completed."""
    seen = []
    return seen.append, (lambda: bool(seen) and seen[-1].generation >= generation)


def _genome(result) -> str:
    return json.dumps(genome_mod.to_json(result.genome))


@pytest.mark.parametrize("stop_at", [0, 5])
def test_curve_resume_is_bit_identical(tmp_path, stop_at):
    points = get_sample("bspline_09").points
    whole = reconstruct_curve(points, seed=11, **CURVE)
    ck = tmp_path / "run.ckpt"
    progress, stop = _stop_after(stop_at)
    cut = reconstruct_curve(points, seed=11, progress=progress, should_stop=stop, checkpoint=ck, **CURVE)
    assert cut.interrupted and ck.exists()
    resumed = reconstruct_curve(points, seed=11, checkpoint=ck, **CURVE)
    assert not resumed.interrupted
    assert _genome(resumed) == _genome(whole)
    assert np.array_equal(resumed.control_points, whole.control_points)
    assert [h["best_fitness"] for h in resumed.history] == [h["best_fitness"] for h in whole.history]


def test_surface_resume_is_bit_identical(tmp_path):
    target = get_sample("inset_extrude").target
    whole = reconstruct_surface(target, seed=4, **SURFACE)
    ck = tmp_path / "s.ckpt"
    progress, stop = _stop_after(1)
    cut = reconstruct_surface(target, seed=4, progress=progress, should_stop=stop, checkpoint=ck, **SURFACE)
    assert cut.interrupted
    resumed = reconstruct_surface(target, seed=4, checkpoint=ck, **SURFACE)
    assert _genome(resumed) == _genome(whole)
    assert np.array_equal(resumed.control_mesh.vertices, whole.control_mesh.vertices)


def test_checkpoint_of_another_run_is_refused(tmp_path):
    ck = tmp_path / "run.ckpt"
    reconstruct_curve(get_sample("bspline_05").points, seed=1, checkpoint=ck, **CURVE)
    with pytest.raises(InputError, match="another run"):
        reconstruct_curve(get_sample("bspline_07").points, seed=1, checkpoint=ck, **CURVE)
    ck.write_bytes(b"not a pickle")
    with pytest.raises(InputError, match="not a gsr_cad GA checkpoint"):
        reconstruct_curve(get_sample("bspline_05").points, seed=1, checkpoint=ck, **CURVE)


def test_cli_resume_after_ctrl_c(tmp_path):
    """gsr curve --checkpoint, Ctrl-C in the search, gsr resume OUT: the uninterrupted run's genome."""
    get_sample("bspline_12").write(tmp_path / "c.csv")
    flags = ["--seed", "3", "--generations", "60", "--stall-generations", "0", "--population", "60",
             "--initial-population", "200", "--formats", "none", "--quiet"]
    whole = gsr(["curve", "c.csv", "-o", "whole", *flags], tmp_path)
    assert_clean(whole)
    proc = popen(["curve", "c.csv", "-o", "cut", "--checkpoint", "cut.ckpt", *flags], tmp_path)
    deadline = time.monotonic() + 60
    while not (tmp_path / "cut.ckpt").exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=60)
    cut = Result.load(tmp_path / "cut")
    resumed = gsr(["resume", "cut"], tmp_path)
    assert_clean(resumed)
    assert resumed.code == 0
    final = Result.load(tmp_path / "cut")
    assert not final.interrupted
    assert _genome(final) == _genome(Result.load(tmp_path / "whole"))
    assert cut.interrupted or _genome(cut) == _genome(final)
