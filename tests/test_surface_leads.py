"""Leaded parts: the body and its legs are found in an OpenCascade part, and the start built from them replays,
fits and pays where a plain box does not."""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import grower

from gsr_cad.ops.mesh import Crease, Extrude, TranslateVertex
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.blocks import BLOCK_PATH
from gsr_cad.reconstruct.leads import LEAD_PATH, find_leads, lead_genomes
from gsr_cad.reconstruct.starts import start_prefixes, structured_start
from gsr_cad.reconstruct.refine import refine
from gsr_cad.reconstruct.summary import summary_lines
from gsr_cad.reconstruct.surface import SurfaceProblem, place_template, reconstruct_surface

BODY = (6.0, 4.0, 2.0)
PIN = (0.6, 1.5, 0.4)  # width (x), reach beyond the body (y), height (z)
PIN_X = (-1.8, 1.8)  # two pins on each long side
BENT = 1.4  # how far a gull-wing pin drops at its end


def _part(tmp_path, pins: bool = True, pin_x: tuple[float, ...] = PIN_X, width: float = PIN[0],
          bent: bool = False) -> SurfaceTarget:
    """A box body with straight pins at ``pin_x`` on both long sides, fused and tessellated by OpenCascade (not by
    our kernel); ``bent``: gull-wing pins, out and then down past the body's floor."""
    bd = pytest.importorskip("build123d", reason="the cad extra (build123d) builds the part")
    shape = bd.Box(*BODY)
    if pins:
        for x in pin_x:
            for side in (-1, 1):
                y = side * (BODY[1] / 2 + PIN[1] / 2 - 0.1)
                shape = shape + bd.Pos(x, y, -0.4) * bd.Box(width, PIN[1] + 0.2, PIN[2])
                if bent:
                    foot = side * (BODY[1] / 2 + PIN[1] - PIN[2] / 2)
                    shape = shape + bd.Pos(x, foot, -0.4 - BENT / 2) * bd.Box(width, PIN[2], BENT)
    path = tmp_path / (("bent.stl" if bent else "pins.stl") if pins else "box.stl")
    bd.export_stl(shape, str(path), tolerance=1e-3, angular_tolerance=0.1)
    return surface_target(path)


_problem = grower


def test_the_pins_of_a_part_are_found_where_they_leave_the_body(tmp_path):
    found = find_leads(_part(tmp_path))
    assert found is not None and len(found.leads) == 4
    pitch = max(BODY[0], BODY[1] + 2 * PIN[1]) / 120
    for start, tip in found.leads:
        side = np.sign(start[1])
        assert abs(abs(start[1]) - BODY[1] / 2) < 4 * pitch  # at the body's wall
        assert abs(tip[1] - side * (BODY[1] / 2 + PIN[1])) < 2 * pitch  # the pin's end
        assert min(abs(start[0] - x) for x in PIN_X) < PIN[0] / 2
    lo, hi = found.body.min(axis=0), found.body.max(axis=0)
    assert np.allclose((hi - lo)[[0, 2]], np.array(BODY)[[0, 2]], atol=3 * pitch)
    assert BODY[1] - 3 * pitch < (hi - lo)[1] < BODY[1] + 0.5  # the opening's ball rounds into the pins' roots


def test_a_box_has_no_leads_and_a_cloud_is_not_looked_at(tmp_path):
    box = _part(tmp_path, pins=False)
    assert find_leads(box) is None
    assert find_leads(SurfaceTarget(box.points, None, "cloud")) is None


def test_an_open_mesh_is_not_voxelised(tmp_path):
    part = _part(tmp_path)
    assert find_leads(SurfaceTarget(part.points, part.faces[:-10], "open")) is None


def test_the_lead_genome_replays_on_the_placed_cube_to_a_closed_quad_cage(tmp_path):
    problem = _problem(_part(tmp_path))
    body, legs = lead_genomes(problem, find_leads(problem.target))
    assert legs[:len(body)] == body
    box, cage = problem.control_mesh(body), problem.control_mesh(legs)
    assert box.n_vertices == 98 and np.all(cage.face_sizes == 4)
    # per pin an inset (4 vertices) and three extrusions (4 each); genus 0 and closed
    assert cage.n_vertices == 98 + 4 * 16
    t = cage.topology
    assert t.is_closed and t.is_manifold and t.euler_characteristic == 2
    letters = "".join(op.letter for op in legs[len(body):])
    assert letters == "IEEE" * 4
    # the extrusions run along the pins: the cage reaches past the body's box on both sides
    assert np.ptp(cage.vertices[:, 1]) > np.ptp(box.vertices[:, 1]) + PIN[1]


def test_a_row_of_pins_too_crowded_for_the_box_grid_gets_a_finer_one(tmp_path):
    # two pins per column of the twice-split box's side (four faces across it), one per column split thrice
    problem = _problem(_part(tmp_path, pin_x=(-1.05, -0.45, 0.45, 1.05), width=0.3))
    found = find_leads(problem.target)
    assert len(found.leads) == 8
    body, legs = lead_genomes(problem, found)
    assert problem.control_mesh(body).n_vertices == 386  # three splits: eight faces along each side
    assert "".join(op.letter for op in legs[len(body):]) == "IEEE" * 8


def test_a_user_template_other_than_a_cube_gets_no_lead_genome(tmp_path):
    problem = _problem(_part(tmp_path))
    problem.template = problem.control_mesh(lead_genomes(problem, find_leads(problem.target))[0])
    assert lead_genomes(problem, find_leads(problem.target)) is None


@pytest.fixture(scope="module")
def six_legs(tmp_path_factory):
    """A gull-wing part with three legs on each long side, its problem and designer's start (built once: the
    start's gates are most of these tests' time)."""
    problem = _problem(_part(tmp_path_factory.mktemp("six"), pin_x=(-2.0, 0.0, 2.0), bent=True))
    genome, info = structured_start(problem)
    return problem, genome, info


@pytest.mark.xdist_group("six_legs")  # one start for both under --dist loadgroup
def test_the_legs_pay_on_a_gull_wing_part_and_refine_from_there(six_legs):
    problem, genome, info = six_legs
    built = lead_genomes(problem, find_leads(problem.target))[1]
    # the start, then the creases of its edges along the part's (module sharp) where they gained
    assert info["path"] == LEAD_PATH and genome[:len(built)] == built
    after = genome[len(built):]
    creases = [op for op in after if isinstance(op, Crease)]
    assert after[:len(creases)] == tuple(creases) and len(creases) == info.get("creases", 0)
    assert all(isinstance(op, TranslateVertex) for op in after[len(creases):])
    legs = info["leads"]
    assert legs["kept"] and legs["found"] == legs["grown"] == 6 and legs["gain"] >= 1.0
    assert legs["distance"] < 0.5 * legs["body_distance"]
    # blocks stand where the pins leave the body, straight out: they miss the drop, and the legs stand
    assert info["blocks"]["distance"] > legs["distance"]
    final, levels = refine(problem, genome, 2e-3, time.perf_counter() + 20, 400)
    assert problem.control_mesh(final).n_vertices >= 194
    assert levels[-1].cost < legs["distance"]


def test_of_two_starts_kept_the_closer_stands_as_fitted(tmp_path, monkeypatch):
    import gsr_cad.reconstruct.starts as starts_module

    # no crease gains here: the start is the blocks' cage with the moves to the gate's fit of it
    monkeypatch.setattr(starts_module, "sharpened", lambda *args, **kwargs: None)
    # straight pins: a block per pin is as close as a leg with fewer vertices
    problem = _problem(_part(tmp_path))
    genome, info = structured_start(problem)
    assert info["leads"]["kept"] and info["blocks"]["kept"]
    assert info["blocks"]["distance"] < info["leads"]["distance"]
    letters = "".join(op.letter for op in genome)
    assert info["path"] == BLOCK_PATH and letters.rstrip("V").endswith("X" * 4) and letters.endswith("V")
    # a path short of time starts from the cage as fitted, not as built
    assert problem.fit(problem.control_mesh(genome), 0)[1] == pytest.approx(info["blocks"]["distance"], rel=0.1)


_SMALL = dict(population=10, initial_population=10, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
              generations=2, final_polish_rounds=4, simplify_history=False, refine_seconds=60, refine_workers=1,
              refine_points=3000)


@pytest.mark.parametrize("seconds", [30, pytest.param(60, marks=pytest.mark.slow)])  # CI: 30 s
def test_a_run_on_a_gull_wing_part_grows_its_legs_into_the_history(tmp_path, seconds):
    result = reconstruct_surface(_part(tmp_path, bent=True), seed=1, **dict(_SMALL, refine_seconds=seconds))
    m = result.metrics
    legs = m["lead_start"]["leads"]
    assert legs["kept"] and legs["found"] == legs["grown"] == 4
    assert m["refined_from"] == m["lead_start"]["path"] == LEAD_PATH
    assert "the body's box with 4 legs" in "\n".join(summary_lines(result))
    letters = "".join(op.letter for op in result.genome)
    assert letters.count("I") == 4 and letters.count("E") == 12
    assert m["n_control_vertices"] >= 162
    # at least twice as close as the body's box alone (8.3e-3 at the gate; 2.3e-3 in a run alone on two cores)
    assert 0.5 * (m["data_to_fit_mean"] + m["fit_to_data_mean"]) < 0.5 * legs["body_distance"], (
        m["refined_from"], m["n_control_vertices"], m["refinement"], m["sharp_edges"], m["seconds"])


def test_a_run_on_a_plain_box_looks_for_leads_and_grows_no_legs(tmp_path):
    result = reconstruct_surface(_part(tmp_path, pins=False), seed=1, **dict(_SMALL, refine_seconds=10))
    m = result.metrics
    assert m["lead_start"] is None and m["refined_from"] not in (LEAD_PATH, BLOCK_PATH)


def test_with_two_processes_the_second_path_grows_the_legs_and_the_template_has_its_turn(tmp_path, monkeypatch):
    import gsr_cad.reconstruct.surface as surface_module
    from gsr_cad.reconstruct.second_path import TemplatePath

    started, calls = [], []
    real = surface_module.refine

    class Spied(TemplatePath):
        def __init__(self, problem, *args, **kwargs):
            started.append(kwargs)
            super().__init__(problem, *args, **kwargs)

    def spied(problem, genome, *args, **kwargs):
        calls.append((genome, kwargs.get("free_corners", False)))
        return real(problem, genome, *args, **kwargs)

    monkeypatch.setattr(surface_module, "TemplatePath", Spied)
    monkeypatch.setattr(surface_module, "refine", spied)
    target = _part(tmp_path, bent=True)
    # smooth cages: the template's creased cube would meet this loose goal before any path grows (module sharp)
    config = SurfaceConfig(refine_workers=2, refine_fill=0.0, sharp_edges=False, refine_points=3000)
    problem = SurfaceProblem(target, config, place_template("cube", target, config).mesh)
    winner = (Extrude(5, 0.3),)  # a boss the part does not have: the search's winner stays the first path
    # a loose goal: both paths meet it at once, and the template, whose place the legs took, grows after them
    grown = surface_module._refined(problem, winner, 2e-2, time.perf_counter() + 120, [], None, False)
    assert len(started) == 1 and started[0]["free_corners"] is False
    assert "".join(op.letter for op in started[0]["genome"]).rstrip("V").rstrip("C").endswith("IEEE" * 4)
    assert grown is not None and grown.workers == 2 and grown.leads["path"] == LEAD_PATH
    assert calls == [(winner, False), ((), False)]  # the winner's own structure: the template's corners stay convex
    assert grown.cost <= 2e-2
    assert any(n >= 162 for n, _, _ in grown.front)  # the legs' cages grown in the second process


@pytest.mark.xdist_group("six_legs")  # one start for both under --dist loadgroup
def test_the_body_with_its_first_legs_are_points_of_the_front_below_the_start(six_legs):
    problem, genome, info = six_legs
    assert info["path"] == LEAD_PATH and info["leads"]["grown"] == 6
    body = problem.control_mesh(genome[:info["body_ops"]]).n_vertices
    start = problem.control_mesh(genome)
    points = start_prefixes(problem, genome, info["body_ops"])
    assert points  # 98 + 16 per leg: the gap 98 -> 194 is filled at 130 (two legs whole)
    for n, cost, history in points:
        assert body < n < start.n_vertices and (n - body) % 16 == 0
        cage = problem.control_mesh(history)
        assert cage.n_vertices == n
        assert "".join(op.letter for op in history).count("I") == (n - body) // 16
        # the history replays to the cage that was measured (the fit's cost uses the last round's foot points as hints),
        # creased where the start is
        assert problem.fit(cage, 0)[1] == pytest.approx(cost, rel=1e-2)
        assert bool(np.any(cage.edge_sharpness > 0)) == bool(np.any(start.edge_sharpness > 0))
        # the legs it has pull it closer than the body's box alone
        assert cost < info["leads"]["body_distance"]
