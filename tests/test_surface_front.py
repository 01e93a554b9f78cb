"""The accuracy/complexity front of a surface run: non-dominated, in result.json, and --max-distance picks
its simplest cage that meets the tolerance (or says none did)."""

from __future__ import annotations

import math

import numpy as np

from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import (SurfaceProblem, _evaluated_from, box_template, front, reconstruct_surface,
                                         surface_metrics)

SMALL = dict(population=12, initial_population=12, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
             generations=1, final_polish_rounds=5, simplify_history=False, refine_points=3000)


def test_front_keeps_only_the_non_dominated():
    evaluated = {8: (0.3, ("a",)), 12: (0.1, ("b",)), 16: (0.2, ("c",)), 20: (0.05, ("d",)), 24: (math.inf, ())}
    assert [(n, c) for n, c, _ in front(evaluated)] == [(8, 0.3), (12, 0.1), (20, 0.05)]


def test_the_front_made_up_from_a_memo_equals_the_one_scored_here_and_replays_only_what_was_scored_elsewhere():
    k = np.arange(600) + 0.5
    polar, azimuth = np.arccos(1 - 2 * k / 600), np.pi * (1 + 5 ** 0.5) * k
    target = surface_target(np.c_[2 * np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth),
                                  np.cos(polar)], "ellipsoid")
    config = SurfaceConfig(max_target_points=600, polish_rounds=2)
    here = SurfaceProblem(target, config, box_template(target))
    rng = np.random.default_rng(4)
    genomes = []
    for _ in range(12):
        genome: tuple = ()
        for _ in range(int(rng.integers(1, 5))):
            genome += (here.random_gene(rng, genome),)
        genomes.append(here.repair(genome, rng))
    memo = {g: here.cost(g) for g in genomes}
    elsewhere = SurfaceProblem(target, config, box_template(target))  # a pool's main process: scored nothing
    _evaluated_from(elsewhere, memo)
    assert elsewhere.evaluated == here.evaluated and len(here.evaluated) >= 2
    replays = []
    real = here.control_mesh
    here.control_mesh = lambda genome: replays.append(genome) or real(genome)
    before = dict(here.evaluated)
    _evaluated_from(here, memo)
    assert replays == [] and here.evaluated == before


def test_the_runs_front_is_non_dominated_and_max_distance_picks_the_simplest():
    # points on a sphere: no Catmull-Clark limit surface is a sphere exactly, so 1e-12 cannot be met
    k = np.arange(800) + 0.5
    polar, azimuth = np.arccos(1 - 2 * k / 800), np.pi * (1 + 5 ** 0.5) * k
    target = surface_target(np.c_[np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)],
                            "sphere")
    result = reconstruct_surface(target, seed=2, **SMALL)
    points = result.metrics["front"]
    assert points and "tolerance_met" not in result.metrics
    for p in points:
        assert not any(q["vertices"] <= p["vertices"] and q["distance"] < p["distance"] and q is not p
                       for q in points)
    loose = points[0]["distance"] * 1.01
    picked = reconstruct_surface(target, seed=2, max_distance=loose, **SMALL)
    assert picked.metrics["n_control_vertices"] == points[0]["vertices"]
    strict = reconstruct_surface(target, seed=2, max_distance=1e-12, max_seconds=20, **SMALL)
    assert strict.metrics["tolerance_met"] is False


def test_front_cages_carry_exact_distances_both_ways():
    """Every front point (no time limit) carries the reported measure, both directions' exact means, besides
    the distance the run ranked it by; the result's own cage carries its final metrics."""
    import trimesh

    from gsr_cad.geometry.polymesh import PolyMesh

    mesh = trimesh.creation.capsule(height=1.0, radius=0.5, count=[16, 16])
    target = surface_target(PolyMesh.from_faces(mesh.vertices, mesh.faces.tolist()), "capsule")
    result = reconstruct_surface(target, seed=3, refine_seconds=20, refine_until=1e-3, **SMALL)
    m = result.metrics
    points = m["front"]
    assert len(points) >= 2
    for p in points:
        assert p["data_to_fit_mean"] >= 0 and p["fit_to_data_mean"] >= 0
        assert p["symmetric_distance"] == 0.5 * (p["data_to_fit_mean"] + p["fit_to_data_mean"])
    own = [p for p in points if p["vertices"] == m["n_control_vertices"]]
    assert own and own[0]["fit_to_data_mean"] == m["fit_to_data_mean"]
    assert own[0]["data_to_fit_mean"] == m["data_to_fit_mean"]
    # the smallest cage is the farthest by the reported measure as well as by the ranked one
    assert points[0]["symmetric_distance"] > own[0]["symmetric_distance"]
    # the in-memory front replays each point's cage, and the cage is the one measured
    assert [(n, c) for n, c, _ in result.front] == [(p["vertices"], p["distance"]) for p in points]
    for i, p in enumerate(points):
        control = result.front_control(i)
        assert control.n_vertices == p["vertices"]
        again = surface_metrics(control, target, SurfaceConfig())["symmetric_distance"]
        assert abs(again - p["symmetric_distance"]) <= 0.2 * p["symmetric_distance"]


def test_the_template_fitted_joins_the_front_beside_the_searchs_own_cage():
    """The search's simplest cage may be a worse minimum of the template's own structure (example007: a pyramid
    of moves at 5.9e-2 of the diagonal both ways where the fitted box gave 3.7e-2); the front keeps the better."""
    import trimesh

    from gsr_cad.geometry.polymesh import PolyMesh
    from gsr_cad.ops.mesh import EdgeLoop, TranslateVertex
    from gsr_cad.reconstruct.config import SurfaceConfig
    from gsr_cad.reconstruct.inputs import SurfaceTarget
    from gsr_cad.reconstruct.surface import SurfaceProblem, _refined, surface_metrics

    blob = trimesh.creation.icosphere(subdivisions=3)
    blob.apply_scale([1.5, 1.0, 0.7])
    target = SurfaceTarget(np.asarray(blob.vertices), np.asarray(blob.faces), "ellipsoid")
    v = np.array([[x, y, z] for x in (-1.5, 1.5) for y in (-1.0, 1.0) for z in (-0.7, 0.7)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    cube = PolyMesh.from_faces(v, faces)
    problem = SurfaceProblem(target, SurfaceConfig(max_target_points=600), cube)
    apex = (0.0, 0.0, 0.7)
    pyramid = tuple(TranslateVertex(i, tuple(float(x) for x in 0.9 * (np.array(apex) - v[i]))) for i in (4, 5, 6, 7))
    assert problem.control_mesh(pyramid).n_vertices == 8
    searched = [(8, problem.evaluate(pyramid, 0).cost, pyramid)]
    winner = (EdgeLoop(0),)
    growth = _refined(problem, winner, 1.0, None, searched, None, pick=True)
    eight = [entry for entry in growth.front if entry[0] == 8]
    assert eight
    cost, genome = eight[0][1], eight[0][2]
    assert all(isinstance(op, TranslateVertex) for op in genome)
    start = problem.control_mesh(pyramid)
    refit = start.with_vertices(SurfaceProblem(target, SurfaceConfig(max_target_points=600), cube,
                                               exact_back=True).fit(start, 30)[0])
    config = SurfaceConfig()
    kept = surface_metrics(problem.control_mesh(genome), target, config)["symmetric_distance"]
    assert kept < 0.9 * surface_metrics(refit, target, config)["symmetric_distance"]
    assert math.isfinite(cost)
