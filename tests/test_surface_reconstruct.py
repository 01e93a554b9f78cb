"""Surface reconstruction: the problem's cost and polish on known genomes, end-to-end runs on the paper's
examples (mesh and cloud), the result.json contract, reproducibility across evaluators, Ctrl-C, presets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ConfigError
from gsr_cad.ga import ProcessPoolEvaluator
from gsr_cad.geometry.isomorphism import connectivity_hash, isomorphisms
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.geometry.surface_distance import mixed_mean_distance
from gsr_cad.ops.mesh import EdgeLoop, TranslateVertex
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.surface import SurfaceProblem, make_template, reconstruct_surface, template_from_config
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES, random_ops_sample

SMALL = dict(population=12, initial_population=12, n_parents=4, max_children=2, n_perturb=2, n_newcomers=2,
             generations=3, refine_points=3000)


def sample_target(name: str, kind: str = "mesh"):
    s = SURFACE_SAMPLES[name]()
    return s, (surface_target(s.target, name) if kind == "mesh" else SurfaceTarget(s.cloud, None, name))


@pytest.mark.parametrize("kind", ["mesh", "cloud"])
def test_the_true_genome_on_the_unit_cube_costs_nothing(kind):
    s, target = sample_target("inset_extrude", kind)
    problem = SurfaceProblem(target, SurfaceConfig(), unit_cube())
    # a sparse cloud leaves a few gaps wider than its points' sampling radii
    exact = 1e-12 if kind == "mesh" else 1e-5
    assert problem.evaluate(s.truth_genome, 0).cost < exact
    assert problem.cost(s.truth_genome) < exact
    # a wrong genome costs something under both measures
    assert problem.evaluate(s.truth_genome[:1], 0).cost > 1e-3
    mixed = SurfaceProblem(target, SurfaceConfig.preset("paper"), unit_cube())
    assert mixed.cost(s.truth_genome) == (0.0 if kind == "mesh" else pytest.approx(
        mixed_mean_distance(limit_mesh(s.truth_control, 2).vertices, target.points, target.diagonal) / target.diagonal))


def test_polish_fits_the_right_structure_and_replays_as_ops():
    _, target = sample_target("extended")
    config = SurfaceConfig()
    problem = SurfaceProblem(target, config, make_template("cube", target, config))
    loop = next(g for g in ((EdgeLoop(e),) for e in range(12)) if problem.evaluate(g, 10).cost < 1e-5)
    before = problem.evaluate(loop, 0).cost
    assert before > 1e-3
    polished = problem.polished(loop, 20)
    assert polished[0] == loop[0] and all(isinstance(op, TranslateVertex) for op in polished[1:])
    # the saved genome replays, with the plain genome module, to the polished mesh
    mesh = genome_mod.replay(problem.template, polished)
    assert mesh.n_vertices == 12 and problem.evaluate(polished, 0).cost < 1e-6
    # a genome with a long history of moves comes back short: its other ops, then one move per vertex
    noisy = (TranslateVertex(0, (0.0, 0.0, 0.05)),) + loop + (TranslateVertex(3, (0.01, 0.0, 0.0)),) * 5
    again = problem.polished(noisy, 20, compact=True)
    assert again[0] == loop[0] and len(again) <= 13 and problem.evaluate(again, 0).cost < 1e-6


@pytest.mark.parametrize("kind", ["mesh", "cloud"])
def test_extended_is_reconstructed_to_the_papers_accuracy(kind, tmp_path):
    s, target = sample_target("extended", kind)
    result = reconstruct_surface(target, seed=1)
    m = result.metrics
    assert m["mean_distance"] <= 1e-4 and m["max_distance"] <= 1e-3
    assert m["stop_reason"] == "threshold" and not result.interrupted
    assert result.control_mesh.n_vertices == s.truth_control.n_vertices
    # both measures and the run's figures are reported
    for key in ("fitness", "mixed_mean_distance", "symmetric_distance", "mean_distance_to_target",
                "n_control_faces", "n_control_vertices", "seconds", "generations", "evaluations", "polish_seconds",
                "unpolished_mean_distance"):
        assert key in m
    # result.json: DESIGN contract; the genome replays on the saved template to the saved control mesh
    data = json.loads(result.save(tmp_path).read_text())
    assert data["kind"] == "surface" and data["version"] == 1 and data["seed"] == 1
    assert data["control_mesh"]["faces"] == [list(f) for f in result.control_mesh.faces]
    assert [h["generation"] for h in data["history"]] == list(range(len(data["history"])))
    loaded = Result.load(tmp_path)
    replayed = genome_mod.replay(template_from_config(loaded.config), loaded.genome)
    np.testing.assert_array_equal(replayed.vertices, loaded.control_mesh.vertices)
    assert replayed.faces == loaded.control_mesh.faces
    assert loaded.config["target"]["kind"] == kind


def test_same_seed_same_result_serial_or_process_pool():
    """Same seed, same search, polish and refinement (to a level or two: the cage is bounded so the runs stay
    short), whether the genomes are evaluated here or in a process pool: the second run, in a pool, repeats the
    first. (The history's simplification runs in this process either way, after them: left out.)"""
    s = random_ops_sample(3)
    target = surface_target(s.target)
    small = dict(SMALL, refine_max_faces=30, simplify_history=False)
    a = reconstruct_surface(target, seed=7, **small)
    assert len(a.metrics["refinement"]) >= 2, "the refinement grew the cage"

    def costs(result):
        return [(h["best_fitness"], h["mean_fitness"]) for h in result.history]

    def front(result):  # the front's cages between the refinement's levels too (bounded by a count, not seconds)
        return [(p["vertices"], p["distance"]) for p in result.metrics["front"]]

    assert len(front(a)) >= 3
    with ProcessPoolEvaluator(max_workers=2) as pool:
        c = reconstruct_surface(target, seed=7, evaluator=pool, **small)
    assert c.genome == a.genome and costs(c) == costs(a) and c.metrics["fitness"] == a.metrics["fitness"]
    assert front(c) == front(a)


def test_ctrl_c_keeps_the_best_so_far():
    _, target = sample_target("unreachable")

    def interrupt(report):
        if report.generation == 1:
            raise KeyboardInterrupt

    result = reconstruct_surface(target, seed=2, progress=interrupt, **dict(SMALL, generations=50))
    assert result.interrupted and result.metrics["stop_reason"] == "interrupted"
    assert result.genome and result.metrics["mean_distance"] < 0.1
    assert json.loads(json.dumps(result.to_json()))["interrupted"] is True


def test_paper_preset_uses_the_mixed_mean_distance_without_polish():
    _, target = sample_target("extended")
    result = reconstruct_surface(target, preset="paper", seed=3, **SMALL)
    m = result.metrics
    assert result.config["fitness"] == "mixed" and result.config["polish_rounds"] == 0
    assert m["fitness"] == pytest.approx(m["mixed_mean_distance"], rel=1e-12)
    assert m["fitness_kind"].startswith("mixed")
    assert min(h["best_fitness"] for h in result.history) == pytest.approx(m["search_fitness"])


def test_snapshots_follow_the_best_individual():
    _, target = sample_target("flattened_extended")
    result = reconstruct_surface(target, seed=4, **dict(SMALL, generations=4))
    gens = [snap.generation for snap in result.snapshots]
    assert gens == sorted(gens) and len(gens) >= 1
    costs = [snap.cost for snap in result.snapshots]
    assert costs == sorted(costs, reverse=True)


@pytest.mark.parametrize("overrides, message", [
    (dict(population=1), "population"),
    (dict(levels=0), "levels"),
    (dict(op_kinds="VQ"), "op-kinds"),
    (dict(fitness="hausdorff"), "fitness"),
    (dict(mutation_rate=2.0), "mutation-rate"),
    (dict(polish_gain=0.0), "polish-gain"),
    (dict(no_such_setting=1), "unknown surface setting"),
])
def test_absurd_settings_are_config_errors(overrides, message):
    with pytest.raises(ConfigError, match=message):
        reconstruct_surface(SURFACE_SAMPLES["extended"]().target, seed=0, **overrides)


@pytest.mark.slow
@pytest.mark.parametrize("name, kind", [("flattened_extended", "mesh"), ("flattened_extended", "cloud"),
                                        ("inset_extrude", "mesh"), ("random_ops", "mesh")])
def test_full_reproduction_runs(name, kind):
    _, target = sample_target(name, kind)
    result = reconstruct_surface(target, seed=1)
    assert result.metrics["mean_distance"] <= (2e-3 if name == "flattened_extended" else 5e-3)
    if name == "inset_extrude":  # the designer's history, after the rewrite
        assert result.metrics["ops"].replace("V", "") == "IE"


def test_runs_of_moves_merge_into_one_move_per_vertex():
    _, target = sample_target("extended")
    config = SurfaceConfig()
    problem = SurfaceProblem(target, config, make_template("cube", target, config))
    genome = (TranslateVertex(0, (0.01, 0.0, 0.0)), TranslateVertex(1, (0.0, 0.02, 0.0)),
              TranslateVertex(0, (0.0, 0.0, 0.03)), EdgeLoop(0), TranslateVertex(8, (0.0, 0.01, 0.0)))
    merged = problem.merged(genome)
    assert merged == (TranslateVertex(0, (0.01, 0.0, 0.03)), TranslateVertex(1, (0.0, 0.02, 0.0)), EdgeLoop(0),
                      TranslateVertex(8, (0.0, 0.01, 0.0)))
    np.testing.assert_allclose(problem.control_mesh(merged).vertices, problem.control_mesh(genome).vertices,
                               atol=1e-15)


def test_two_polished_loops_are_saved_as_inset_then_extrude():
    sample, target = sample_target("inset_extrude")
    config = SurfaceConfig()
    problem = SurfaceProblem(target, config, make_template("cube", target, config))
    loops = None
    for e1 in range(12):  # two horizontal loops: the connectivity of inset + extrude
        for e2 in range(20):
            genome = (EdgeLoop(e1), EdgeLoop(e2))
            kept, mesh = problem.walk(genome)
            if len(kept) == 2 and connectivity_hash(mesh) == connectivity_hash(sample.truth_control):
                # the loops' vertices moved onto the true control mesh's (matched by isomorphism)
                for vmap in isomorphisms(mesh, sample.truth_control):
                    moved = genome + problem._moves(mesh, sample.truth_control.vertices[vmap])[0]
                    if len(problem.walk(moved)[0]) == len(moved) and problem.evaluate(moved, 0).cost < 1e-6:
                        loops = moved
                        break
            if loops:
                break
        if loops:
            break
    assert loops is not None and "".join(op.letter for op in loops).startswith("LLV")
    before = problem.evaluate(loops, 0).cost
    saved = problem.simplified(loops)
    letters = "".join(op.letter for op in saved)
    assert letters.replace("V", "") == "IE" and len(saved) < len(loops)
    assert problem.evaluate(saved, 0).cost <= before + config.history_tolerance
    # the paper preset keeps the search's history
    assert SurfaceConfig.preset("paper").simplify_history is False
