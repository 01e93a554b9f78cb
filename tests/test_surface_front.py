"""The accuracy/complexity front of a surface run: non-dominated, in result.json, and --max-distance picks
its simplest cage that meets the tolerance (or says none did)."""

from __future__ import annotations

import math

import numpy as np

from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import front, reconstruct_surface

SMALL = dict(population=12, initial_population=12, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
             generations=1, final_polish_rounds=5, simplify_history=False)


def test_front_keeps_only_the_non_dominated():
    evaluated = {8: (0.3, ("a",)), 12: (0.1, ("b",)), 16: (0.2, ("c",)), 20: (0.05, ("d",)), 24: (math.inf, ())}
    assert [(n, c) for n, c, _ in front(evaluated)] == [(8, 0.3), (12, 0.1), (20, 0.05)]


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
