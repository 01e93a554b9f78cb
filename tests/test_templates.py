"""Genus-n templates, the genus of targets (Euler characteristic; voxel solid for clouds and open meshes),
template placement and the genus metrics of a surface result."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from gsr_cad.errors import ConfigError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.reconstruct.inputs import SurfaceTarget
from gsr_cad.reconstruct.surface import reconstruct_surface
from gsr_cad.reconstruct.templates import (fitted_template, genus_metrics, genus_template, hole_axis, mesh_genus,
                                           target_genus, voxel_genus, voxel_solid)


def _frame(holes: int) -> trimesh.Trimesh:
    """A slab with ``holes`` square windows in a row (boolean-free: boxes glued by vertex welding)."""
    parts = [trimesh.creation.box(extents=(0.4, 1.6, 0.5), transform=trimesh.transformations.translation_matrix(
        [1.2 * i - 0.6 * holes, 0, 0])) for i in range(holes + 1)]
    parts += [trimesh.creation.box(extents=(0.8, 0.4, 0.5), transform=trimesh.transformations.translation_matrix(
        [1.2 * i + 0.6 - 0.6 * holes, y, 0])) for i in range(holes) for y in (-0.6, 0.6)]
    return trimesh.util.concatenate(parts)


@pytest.mark.parametrize("genus", [0, 1, 2, 3])
def test_genus_templates(genus):
    m = genus_template(genus)
    t = m.topology
    assert t.is_closed and t.is_manifold and (2 - t.euler_characteristic) // 2 == genus
    assert np.all(m.face_sizes == 4)
    assert np.ptp(m.vertices, axis=0).tolist() == [max(genus, 1), 1.0, 1.0]
    get_catmull_clark(m, 2)


def test_genus_template_bounds():
    for bad in (-1, 9, 1.5, True):
        with pytest.raises(ConfigError):
            genus_template(bad)


@pytest.mark.parametrize("name,mesh,genus", [
    ("sphere", trimesh.creation.icosphere(2), 0), ("box", trimesh.creation.box(), 0),
    ("cylinder", trimesh.creation.cylinder(1.0, 2.0), 0), ("torus", trimesh.creation.torus(1.0, 0.3), 1),
    ("ring", trimesh.creation.annulus(0.8, 1.0, 0.5), 1)])
def test_genus_of_closed_meshes_and_clouds(name, mesh, genus):
    assert mesh_genus(mesh.vertices, mesh.faces) == genus
    assert target_genus(SurfaceTarget(mesh.vertices, mesh.faces)) == (genus, "euler")
    cloud = SurfaceTarget(trimesh.sample.sample_surface(mesh, 30000)[0])
    assert target_genus(cloud) == (genus, "voxels")


def test_genus_by_voxels_of_a_frame_and_an_open_mesh():
    frame = trimesh.creation.box(extents=(1, 1, 1))
    assert voxel_genus(voxel_solid(frame.vertices, frame.faces)) == 0
    for holes in (2, 3):
        f = _frame(holes)
        assert voxel_genus(voxel_solid(f.vertices, f.faces)) == holes
    ring = trimesh.creation.annulus(0.6, 1.0, 0.5)
    assert mesh_genus(ring.vertices, ring.faces[:-2]) is None  # open: the Euler count does not apply
    assert target_genus(SurfaceTarget(ring.vertices, ring.faces[:-2])) == (1, "voxels")  # a gap the dilation closes
    # a wide gap opens the shell: the estimate counts the opening as a handle
    assert target_genus(SurfaceTarget(ring.vertices, ring.faces[:-8]))[0] == 2


def test_hole_axis_and_placement():
    ring = trimesh.creation.annulus(0.6, 1.0, 2.5)  # a tube taller than wide: its hole runs along z anyway
    target = SurfaceTarget(ring.vertices, ring.faces)
    assert hole_axis(target) == 2
    turned = ring.copy()
    turned.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    tt = SurfaceTarget(turned.vertices, turned.faces)
    assert hole_axis(tt) == 1
    template = fitted_template(tt, 1)
    limit = get_catmull_clark(template, 2).limit(template.vertices).vertices
    np.testing.assert_allclose([limit.min(axis=0), limit.max(axis=0)], tt.bbox, atol=1e-9)
    # the template's hole runs along y: the column through the centre is free
    assert np.abs(limit[:, [0, 2]]).max(axis=1).min() > 0.1


def test_genus_metrics_warn_on_a_mismatch():
    ok = genus_metrics(genus_template(1), 1, "euler")
    assert ok == {"target_genus": 1, "target_genus_method": "euler", "result_genus": 1}
    bad = genus_metrics(genus_template(0), 2, "voxels")
    assert bad["result_genus"] == 0 and "genus 0" in bad["genus_warning"] and "genus 2" in bad["genus_warning"]
    open_box = PolyMesh.from_faces(genus_template(0).vertices, genus_template(0).faces[:5])
    assert genus_metrics(open_box, 0, "euler")["result_genus"] is None


def test_surface_search_reports_genus_and_seeds_with_it():
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    target = PolyMesh.from_faces(torus.vertices, torus.faces)
    small = dict(generations=2, population=8, initial_population=8, n_parents=4, max_children=2, n_perturb=2,
                 n_newcomers=2, polish_rounds=1, final_polish_rounds=1, simplify_history=False, seed=0,
                 refine=False)  # the search's starts compared, not how far a refinement grows either
    seeded = reconstruct_surface(target, template="genus", **small)
    m = seeded.metrics
    assert (m["target_genus"], m["target_genus_method"], m["result_genus"]) == (1, "euler", 1)
    assert "genus_warning" not in m
    plain = reconstruct_surface(target, **small)
    assert plain.metrics["result_genus"] == 0 and "genus 1" in plain.metrics["genus_warning"]
    assert m["mean_distance"] < plain.metrics["mean_distance"]


def test_benchmark_targets_have_their_genus(capsys):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    import genus_creases

    expected = {"cylinder": 0, "nut": 1, "torus": 1, "ring": 1, "frame": 3}
    for name, mesh in genus_creases.targets().items():
        t = mesh.topology
        assert t.is_closed and t.is_manifold and (2 - t.euler_characteristic) // 2 == expected[name], name
    assert genus_creases.main(["--targets", "teapot"]) == 2
    assert "unknown targets teapot" in capsys.readouterr().err


# --- feature-driven starts ---------------------------------------------------------------------------------------

def _split_cylinder() -> PolyMesh:
    c = trimesh.creation.cylinder(radius=1.0, height=2.0)
    v, f = trimesh.remesh.subdivide_to_size(c.vertices, c.faces, max_edge=0.25)
    return PolyMesh.from_faces(v, f)


def test_ring_representatives_give_one_edge_per_loop():
    from gsr_cad.geometry.polymesh import unit_cube
    from gsr_cad.ops.mesh import EdgeLoop
    from gsr_cad.reconstruct.templates import _ring_representatives

    cube = unit_cube()
    reps = _ring_representatives(cube)
    assert len(reps) == 3
    # the three loops cut the cube into 8 blocks: 26 vertices
    mesh = cube
    for _ in range(3):
        mesh = EdgeLoop(_ring_representatives(mesh)[-1]).apply(mesh)
    assert len(_ring_representatives(mesh)) == 6


def test_feature_genomes_crease_the_caps_and_keep_gaining():
    from gsr_cad.reconstruct.config import SurfaceConfig
    from gsr_cad.reconstruct.inputs import surface_target
    from gsr_cad.reconstruct.surface import SurfaceProblem
    from gsr_cad.reconstruct.templates import feature_genomes

    target = surface_target(_split_cylinder())
    template = fitted_template(target, 0)
    problem = SurfaceProblem(target, SurfaceConfig.preset("default", op_kinds="VLCR", max_seconds=360), template)
    seeds = problem.seed_genomes()  # a quarter of max_seconds at most
    assert seeds and all(seeds[0][:len(g)] == g for g in seeds)
    # both caps' rims creased infinitely sharp (the feature lines), loops for the round section
    letters = "".join(op.letter for op in seeds[0])
    assert letters.count("R") == 2 and "L" in letters
    mesh = problem.control_mesh(seeds[0])
    rims = np.flatnonzero(mesh.edge_sharpness >= 10)
    heights = mesh.vertices[mesh.topology.edges[rims]][..., 2]
    assert np.allclose(np.abs(heights), np.abs(heights).max(), rtol=0.2)  # on the top and bottom only
    costs = [problem.fit(problem.control_mesh(g), 20, min_gain=0.95)[1] for g in [(), *seeds[::-1]]]
    assert all(b < 0.98 * a for a, b in zip(costs, costs[1:]))
    assert costs[-1] < 0.05 * costs[0]
    assert feature_genomes(template, problem.proposals, lambda g: (problem.cost(g), None), "V") == []


def _hole_clearance(template: PolyMesh, centre: np.ndarray, axis: np.ndarray) -> float:
    """Distance from the line ``centre + t axis`` to the nearest limit vertex of ``template`` (level 2)."""
    limit = get_catmull_clark(template, 2).limit(template.vertices).vertices - centre
    return float(np.linalg.norm(limit - np.outer(limit @ axis, axis), axis=1).min())


@pytest.mark.parametrize("angles", [(0.0, 0.0, 0.0), (0.4, -0.7, 1.1)])
def test_template_holes_follow_a_turned_and_moved_target(angles):
    """The hole of a thin-walled ring is sized to its bore (its limit rim near the inner wall, far from the
    small default hole) and follows the ring wherever it is turned and moved."""
    turn = trimesh.transformations.euler_matrix(*angles)
    turn[:3, 3] = [3.0, -2.0, 5.0]
    ring = trimesh.creation.annulus(0.85, 1.0, 0.4, sections=64)
    ring.apply_transform(turn)
    target = SurfaceTarget(ring.vertices, ring.faces)
    template = fitted_template(target, 1)
    assert genus_metrics(template, 1, "euler")["result_genus"] == 1
    clearance = _hole_clearance(template, turn[:3, 3], turn[:3, 2])
    assert 0.7 < clearance < 0.9  # the bore's radius is 0.85; the unplaced template's hole is half the box
    limit = get_catmull_clark(template, 2).limit(template.vertices).vertices - turn[:3, 3]
    assert np.abs(limit @ turn[:3, 2]).max() < 0.25  # flat along the turned axis (height 0.4)


def test_template_holes_sit_in_the_target_windows():
    """Two windows of unequal size at unequal spacing: each template hole lies on its window's centre line."""
    mask = np.ones((10, 5), dtype=bool)
    mask[1:3, 1:4] = False  # a wide window near one end
    mask[7, 2] = False  # a small one further along
    # unit cells side by side (their shared walls lie inside the solid the voxels see)
    slab = trimesh.util.concatenate([trimesh.creation.box(extents=(1, 1, 1), transform=trimesh.transformations.
                                     translation_matrix([i + 0.5, j + 0.5, 0.0]))
                                     for i in range(10) for j in range(5) if mask[i, j]])
    target = SurfaceTarget(slab.vertices, slab.faces)
    template = fitted_template(target, 2)
    up = np.array([0.0, 0.0, 1.0])
    wide = _hole_clearance(template, np.array([2.0, 2.5, 0.0]), up)
    small = _hole_clearance(template, np.array([7.5, 2.5, 0.0]), up)
    assert 0.8 < wide < 1.2 and 0.35 < small < 0.65  # half-widths 1 and 0.5 (equal strips: 0.9 and 1.1)
    assert _hole_clearance(template, np.array([5.0, 2.5, 0.0]), up) < 0.1  # solid between the windows


def test_a_block_bored_along_three_axes_gets_the_window_box():
    """A box frame (3 x 3 x 3 cells, the centre column along each axis bored out: genus 5; stretched so that its
    principal axes are its own), turned: the template is the hollow box with six windows, each window on a
    bore's centre line (a row of holes would block two of them), its limit spanning the target."""
    stretch = np.diag([1.6, 1.0, 0.7, 1.0])
    turn = trimesh.transformations.euler_matrix(0.3, 0.5, -0.2)
    cells = [trimesh.creation.box(extents=(1, 1, 1), transform=trimesh.transformations.translation_matrix(
        [i - 1.0, j - 1.0, k - 1.0])) for i in range(3) for j in range(3) for k in range(3)
        if (i == 1) + (j == 1) + (k == 1) <= 1]
    frame = trimesh.util.concatenate(cells)
    frame.apply_transform(turn @ stretch)
    target = SurfaceTarget(frame.vertices, frame.faces)
    template = fitted_template(target, 5)
    assert template.n_vertices == 64 and genus_metrics(template, 5, "euler")["result_genus"] == 5
    for k, half in enumerate((0.35, 0.35, 0.5)):  # the bores' narrower half-widths
        assert 0.7 * half < _hole_clearance(template, np.zeros(3), turn[:3, k]) < 1.3 * half
    # (the principal axes of the target's area samples are within a degree or two of the turned ones)
    limit = get_catmull_clark(template, 2).limit(template.vertices).vertices @ turn[:3, :3]
    np.testing.assert_allclose(np.abs([limit.min(axis=0), limit.max(axis=0)]),
                               np.tile(1.5 * np.diag(stretch)[:3], (2, 1)), rtol=0.08)


def test_the_summary_and_report_lines_say_when_the_genus_differs():
    from gsr_cad.cli.summary import summary_lines, warning_lines
    from gsr_cad.reconstruct.result import Result

    def result(control: PolyMesh, genus: int) -> Result:
        metrics = {"mean_distance": 1e-3, "max_distance": 2e-3, **genus_metrics(control, genus, "euler")}
        return Result(kind="surface", config={"target": {"name": "t", "diagonal": 1.0}}, seed=0, genome=(),
                      metrics=metrics, history=[], control_mesh=control)

    same = result(genus_template(1), 1)
    assert "  genus: control mesh 1, target 1 (euler)" in summary_lines(same)
    assert warning_lines(same) == []
    missing = result(genus_template(0), 2)
    assert "  genus: control mesh 0, target 2 (euler) - DIFFERS: through-holes missing or extra" in summary_lines(
        missing)
    assert warning_lines(missing) == ["warning: the control mesh has genus 0 but the target has genus 2 (euler): "
                                      "through-holes are missing or extra"]


def test_a_sparse_cloud_keeps_its_genus():
    """Cells no finer than a cloud's spacing: 250 points on a box are genus 0 (at 48 cells along the box the
    gaps between them were counted as holes), 400 on a torus genus 1."""
    rng = np.random.default_rng(3)
    box, _ = trimesh.sample.sample_surface(trimesh.creation.box(extents=(2.0, 1.0, 1.0)), 250, seed=3)
    assert target_genus(SurfaceTarget(np.asarray(box), None)) == (0, "voxels")
    torus, _ = trimesh.sample.sample_surface(trimesh.creation.torus(1.0, 0.35), 400, seed=int(rng.integers(100)))
    assert target_genus(SurfaceTarget(np.asarray(torus), None)) == (1, "voxels")


def test_windows_side_by_side_keep_the_even_row():
    """Four windows in a 2 x 2 grid do not follow one another along a row: the even strips stand (a sound
    genus-4 template spanning the target) rather than strips cut across each other."""
    mask = np.ones((5, 5), dtype=bool)
    mask[1::2, 1::2] = False
    slab = trimesh.util.concatenate([trimesh.creation.box(extents=(1, 1, 1), transform=trimesh.transformations.
                                     translation_matrix([i + 0.5, j + 0.5, 0.0]))
                                     for i in range(5) for j in range(5) if mask[i, j]])
    target = SurfaceTarget(slab.vertices, slab.faces)
    template = fitted_template(target, 4)
    assert genus_metrics(template, 4, "euler")["result_genus"] == 4
    even = genus_template(4).vertices
    # the even row's hole rims (cut strips would put each hole at its own window, 6 distinct y instead of 4)
    assert np.unique(np.round(template.vertices[:, 1], 9)).size == np.unique(even[:, 1]).size == 4
    limit = get_catmull_clark(template, 2).limit(template.vertices).vertices
    np.testing.assert_allclose([limit.min(axis=0), limit.max(axis=0)], target.bbox, atol=1e-9)
