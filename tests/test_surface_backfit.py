"""The surface -> target direction: no sampling slack over a part's flat faces in the refinement's fits."""

from __future__ import annotations

import numpy as np

from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.surface import SurfaceProblem, on_facets, surface_metrics


def _cube(size: float = 1.0) -> PolyMesh:
    v = np.array([[x, y, z] for x in (-size, size) for y in (-size, size) for z in (-size, size)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return PolyMesh.from_faces(v, faces)


def _box_target() -> SurfaceTarget:
    cube = _cube()
    tris = np.array([t for f in cube.faces for t in ((f[0], f[1], f[2]), (f[0], f[2], f[3]))])
    return SurfaceTarget(cube.vertices, tris, "box")


def test_a_bulge_over_a_flat_face_is_measured_in_full_and_pulled():
    target = _box_target()
    problem = SurfaceProblem(target, SurfaceConfig(max_target_points=400), _cube(), exact_facets=True)
    assert on_facets(target, problem.points).all()
    lift = 0.01 * target.diagonal  # well inside the samples' spacing on a 400-point box
    assert lift < np.median(problem._cloud_radius)
    X = np.array([[0.3, -0.2, 1.0 + lift], [-0.5, 0.4, 1.0 + 2 * lift]])
    d, goal, weight = problem._back(X)
    np.testing.assert_allclose(d, [lift, 2 * lift], rtol=1e-9)
    np.testing.assert_allclose(goal, X * [1, 1, 0] + [0, 0, 1], atol=1e-12)
    assert np.all(weight == 1.0)
    search = SurfaceProblem(target, SurfaceConfig(max_target_points=400), _cube())  # the search keeps the slack
    assert np.all(search._back(X)[0] < d)


def test_a_smooth_tessellation_keeps_its_sampling_slack():
    target = surface_target(limit_mesh(_cube(), 2), "round")
    problem = SurfaceProblem(target, SurfaceConfig(max_target_points=400), _cube(), exact_facets=True)
    assert not on_facets(target, problem.points).any()
    near = problem.points[:5] + 1e-3 * problem._cloud_radius[:5, None] * np.array([0.0, 0.0, 1.0])
    d, _, weight = problem._back(near)
    assert np.all(d == 0.0) and np.all(weight == 0.0)


def test_a_sheet_past_the_data_is_pulled_back_along_the_target():
    """A thin pancake cage reaching far past a sphere: its overhang's samples have their closest target points
    in its own plane, so rows along the surface's normal could not pull it in (0.23 of the diagonal left after
    30 rounds); rows towards the corresponding target points do."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=3)
    target = SurfaceTarget(np.asarray(sphere.vertices), np.asarray(sphere.faces), "sphere")
    cage = PolyMesh.from_faces(_cube().vertices * [3.0, 3.0, 0.05], _cube().faces)
    config = SurfaceConfig(max_target_points=1500)
    problem = SurfaceProblem(target, config, cage, exact_back=True)
    start = surface_metrics(cage, target, config)["fit_to_data_mean"]
    fitted = cage.with_vertices(problem.fit(cage, 30, min_gain=0.999)[0])
    m = surface_metrics(fitted, target, config)
    assert start > 0.1
    assert m["fit_to_data_mean"] < 5e-3 and m["fit_to_data_max"] < 2e-2
    assert m["data_to_fit_mean"] < 5e-3
