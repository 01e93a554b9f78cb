"""A refined history regrouped as a designer writes it: structural ops first, one move per vertex at the end."""

from __future__ import annotations

import time

import numpy as np

from gsr_cad.ops.mesh import EdgeLoop, TranslateVertex
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import SurfaceProblem, box_template


def _moves(rng, n: int, size: float) -> tuple:
    return tuple(TranslateVertex(i, tuple(float(x) for x in size * rng.uniform(-1, 1, 3))) for i in range(n))


def test_moves_between_the_loops_fold_into_one_move_per_vertex_at_the_end_and_replay_exactly():
    rng = np.random.default_rng(0)
    target = surface_target(rng.normal(size=(300, 3)), "cloud")
    problem = SurfaceProblem(target, SurfaceConfig(), box_template(target))
    size = 0.02 * problem.diag
    first = _moves(rng, problem.template.n_vertices, size) + (EdgeLoop(0),)
    second = _moves(rng, problem.control_mesh(first).n_vertices, size) + (EdgeLoop(5),)
    genome = first + second + _moves(rng, problem.control_mesh(first + second).n_vertices, size)
    grouped = problem.grouped(genome)
    letters = "".join(op.letter for op in grouped)
    assert letters == "LL" + "V" * (len(grouped) - 2) and len(grouped) < len(genome)
    a, b = problem.control_mesh(genome), problem.control_mesh(grouped)
    assert a.topology_key == b.topology_key
    assert np.abs(a.vertices - b.vertices).max() <= 1e-12 * problem.diag
    assert problem.grouped(grouped) == grouped  # already grouped: unchanged
    assert problem.grouped(genome, deadline=time.perf_counter() - 1.0) == genome  # no time: unchanged
