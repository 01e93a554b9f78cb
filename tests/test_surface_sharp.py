"""Sharp edges (module sharp): a cage's edges along the target's feature lines are creased where the creased cage
fits closer; a box is fitted exactly by the creased cube, a smooth target gets no crease, and the option turns
it off."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh
from conftest import grower

from gsr_cad.geometry.polymesh import SHARPNESS_INFINITE
from gsr_cad.ops.mesh import Crease
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.refine import apply_ops
from gsr_cad.reconstruct.sharp import MIN_GAIN, crease_sets, sharp_ops, sharpened
from gsr_cad.reconstruct.summary import sharp_line
from gsr_cad.reconstruct.surface import FRONT_PATH, reconstruct_surface, surface_metrics

BOX = (3.0, 2.0, 1.0)


def _box(tmp_path) -> SurfaceTarget:
    bd = pytest.importorskip("build123d", reason="the cad extra (build123d) builds the part")
    path = tmp_path / "box.stl"
    bd.export_stl(bd.Box(*BOX), str(path), tolerance=1e-3, angular_tolerance=0.1)
    return surface_target(path)


def _fitted(problem):
    cage = problem.template
    vertices, cost = problem.fit(cage, 20, min_gain=1.0, adaptive=True)
    return cage, vertices, cost


def test_the_creased_cube_fits_a_box_that_the_smooth_one_rounds(tmp_path):
    target = _box(tmp_path)
    problem = grower(target)
    cage, vertices, cost = _fitted(problem)
    found = sharpened(problem, cage, vertices, cost, 20, coarse=True)
    assert found is not None
    ops, creased, distance, _ = found
    # every edge of the cube runs along an edge of the box, and all are creased infinitely sharp
    assert sorted(op.edge for op in ops) == list(range(12))
    assert all(isinstance(op, Crease) and op.sharpness == SHARPNESS_INFINITE for op in ops)
    assert distance < 0.05 * cost
    # measured independently of the fit: both directions over the box's area samples
    mesh = apply_ops(ops, cage).with_vertices(creased)
    smooth = surface_metrics(cage.with_vertices(vertices), target, problem.config)
    sharp = surface_metrics(mesh, target, problem.config)
    assert sharp["data_to_fit_max"] < 2e-3 and sharp["fit_to_data_max"] < 2e-3
    assert sharp["data_to_fit_mean"] < 0.05 * smooth["data_to_fit_mean"]
    # the creased cage's corners sit on the box's corners
    local = np.sort(np.abs(mesh.vertices - mesh.vertices.mean(axis=0)) @ np.ones(3))
    assert np.allclose(local, local[0], rtol=1e-2)


def test_a_smooth_target_gets_no_crease(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    problem = grower(SurfaceTarget(np.asarray(sphere.vertices), np.asarray(sphere.faces), "sphere"))
    cage, vertices, cost = _fitted(problem)
    assert sharp_ops(problem, cage.with_vertices(vertices), coarse=True) == ()
    assert sharpened(problem, cage, vertices, cost, 20, coarse=True) is None


def test_sharp_edges_off_leaves_the_cage_smooth(tmp_path):
    problem = grower(_box(tmp_path))
    problem.config = dataclasses.replace(problem.config, sharp_edges=False)
    cage, vertices, cost = _fitted(problem)
    assert sharp_ops(problem, cage.with_vertices(vertices), coarse=True) == ()
    assert sharpened(problem, cage, vertices, cost, 20, coarse=True) is None


def test_creases_that_do_not_gain_are_not_kept(tmp_path):
    problem = grower(_box(tmp_path))
    cage, vertices, cost = _fitted(problem)
    ops, _, distance, _ = sharpened(problem, cage, vertices, cost, 20, coarse=True)
    # the same creases against a cage already as close as the creased one: no gain, nothing kept
    assert sharpened(problem, cage, vertices, distance / MIN_GAIN * 1.01, 20, coarse=True) is not None
    assert sharpened(problem, cage, vertices, distance, 20, coarse=True) is None
    assert len(ops) == 12


def test_a_cylinder_gets_its_rims_creased_not_its_sides(tmp_path):
    bd = pytest.importorskip("build123d", reason="the cad extra (build123d) builds the part")
    path = tmp_path / "can.stl"
    bd.export_stl(bd.Cylinder(1.0, 3.0), str(path), tolerance=1e-3, angular_tolerance=0.1)
    problem = grower(surface_target(path))
    cage, vertices, cost = _fitted(problem)
    sets = crease_sets(problem, cage, cage.with_vertices(vertices), coarse=True)
    assert len(sets) == 4 and len(sets[0]) == 12 and all(len(s) == 8 for s in sets[1:])
    ops, creased, distance, _ = sharpened(problem, cage, vertices, cost, 20, coarse=True)
    # the four edges along the can's axis (z) stay smooth: the cube rounds into the can, its rims sharp
    ends = cage.vertices[cage.topology.edges[[op.edge for op in ops]]]
    direction = ends[:, 1] - ends[:, 0]
    assert len(ops) == 8 and np.all(np.abs(direction[:, 2]) < 0.1 * np.linalg.norm(direction, axis=1))
    # closer than all twelve creased, fitted alike from both starts, measured independently of the fit
    fits = [problem.fit(apply_ops(sets[0], start), 20, min_gain=1.0, adaptive=True)
            for start in (cage.with_vertices(vertices), cage)]
    squared_vertices, squared = min(fits, key=lambda fit: fit[1])
    assert distance < 0.2 * squared and distance < 0.1 * cost

    def both(ops, at):
        d = surface_metrics(apply_ops(ops, cage).with_vertices(at), problem.target, problem.config)
        return d["data_to_fit_mean"] + d["fit_to_data_mean"]

    assert both(ops, creased) < 0.3 * both(sets[0], squared_vertices)


_SMALL = dict(population=10, initial_population=10, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
              generations=2, final_polish_rounds=4, simplify_history=False, refine_seconds=60, refine_workers=1,
              refine_points=3000)


def test_a_run_on_a_box_ends_at_the_creased_cube(tmp_path):
    target = _box(tmp_path)
    result = reconstruct_surface(target, seed=1, **_SMALL)
    m = result.metrics
    # the placed cube, every edge creased and fitted, is within the goal: the simplest cage of the front stands
    assert m["n_control_vertices"] == 8 and m["refined_from"] == FRONT_PATH
    assert [op.letter for op in result.genome].count("C") == 12
    assert m["sharp_edges"]["template_creases"] == 12
    assert m["sharp_edges"]["creased_distance"] < 0.1 * m["sharp_edges"]["template_distance"]
    assert max(m["data_to_fit_mean"], m["fit_to_data_mean"]) < 2e-4
    line = sharp_line(m)
    assert line is not None and "12 control edges creased" in line and "the placed cube's 12" in line
    # and off: the smooth cage grows past eight vertices to meet the same goal, or stays farther
    smooth = reconstruct_surface(target, seed=1, sharp_edges=False, **{**_SMALL, "refine_seconds": 10}).metrics
    assert smooth["sharp_edges"] is None and "C" not in smooth["ops"] and sharp_line(smooth) is None
    assert smooth["n_control_vertices"] > 8 or smooth["symmetric_distance"] > 10 * m["symmetric_distance"]
