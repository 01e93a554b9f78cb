"""Surface samples: true genomes replay to the true control meshes, targets are OpenSubdiv's limit meshes,
clouds lie on the targets, the bundled files match the generators, and ``gsr sample`` writes them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import opensubdiv
from trimesh.triangles import closest_point
from scipy.spatial import cKDTree

from gsr_cad import genome as genome_mod
from gsr_cad.geometry.limit_surface import LimitSurface
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.validation import mesh_report
from gsr_cad.reconstruct import samples as S
from gsr_cad.reconstruct.inputs import load_surface_target
from gsr_cad.reconstruct.meshio import load_mesh
from gsr_cad.reconstruct.surface_samples import LEVELS, SURFACE_SAMPLES, random_ops_sample

REPO = Path(__file__).resolve().parents[1]
SURFACES = REPO / "samples" / "surfaces"
NAMES = ("extended", "flattened_extended", "inset_extrude", "random_ops", "unreachable")
TRUE_OPS = {"extended": "E", "flattened_extended": "FE", "inset_extrude": "IE"}


def test_registry_holds_every_surface_sample():
    assert set(NAMES) <= set(S.sample_names("surface"))
    assert set(SURFACE_SAMPLES) == set(S.sample_names("surface"))
    for name in NAMES:
        s = S.get_sample(name)
        assert s.kind == "surface" and s.name == name and s.has_truth and "\n" not in s.description


@pytest.mark.parametrize("name", NAMES)
def test_target_is_the_limit_mesh_of_the_true_control_mesh(name):
    s = S.get_sample(name)
    if s.truth_genome is not None:
        rebuilt = genome_mod.replay(unit_cube(), s.truth_genome)
        assert rebuilt.faces == s.truth_control.faces
        np.testing.assert_array_equal(rebuilt.vertices, s.truth_control.vertices)
    report = mesh_report(s.truth_control)
    assert report["valid"] and report["closed"] and report["manifold"]
    # OpenSubdiv (through lagrange) computes the same limit points, in its own order
    osd = opensubdiv(s.truth_control, LEVELS).vertices
    assert osd.shape == s.target.vertices.shape
    dist, match = cKDTree(osd).query(s.target.vertices)
    assert dist.max() < 1e-12 * s.target.diagonal and len(np.unique(match)) == len(osd)
    assert s.target.n_faces == 4 ** LEVELS * s.truth_control.n_faces


@pytest.mark.parametrize("name", NAMES)
def test_cloud_lies_on_the_target_and_is_not_its_vertices(name):
    s = S.get_sample(name)
    # on the exact limit surface of the true control mesh, within the target's chord error of its triangles
    assert LimitSurface.of(s.truth_control).closest(s.cloud).distance.max() < 1e-9 * s.target.diagonal
    v = s.target.vertices
    tris = v[[f for q in s.target.faces for f in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]]
    # trimesh's point-triangle projection, every point against every triangle
    pts = np.repeat(s.cloud, len(tris), axis=0)
    near = closest_point(np.tile(tris, (len(s.cloud), 1, 1)), pts)
    dist = np.linalg.norm(near - pts, axis=1).reshape(len(s.cloud), len(tris)).min(axis=1)
    assert dist.max() < 2e-2 * s.target.diagonal
    assert len(s.cloud) == round(1.5 * s.target.n_vertices)
    assert cKDTree(s.target.vertices).query(s.cloud)[0].min() > 1e-4 * s.target.diagonal


def test_true_genomes_are_the_papers_examples():
    for name, ops in TRUE_OPS.items():
        assert SURFACE_SAMPLES[name]().true_ops == ops
    assert mesh_report(SURFACE_SAMPLES["unreachable"]().truth_control)["genus"] == 1
    for seed in range(6):
        s = random_ops_sample(seed)
        assert 4 <= len(s.truth_genome) <= 6
        again = random_ops_sample(seed)
        assert again.truth_genome == s.truth_genome
        np.testing.assert_array_equal(again.cloud, s.cloud)


@pytest.mark.parametrize("name", NAMES)
def test_bundled_files_are_what_the_generators_make(name):
    s = S.get_sample(name)
    bundled = load_mesh(SURFACES / f"{name}.obj")
    assert bundled.faces == s.target.faces
    np.testing.assert_array_equal(bundled.vertices, s.target.vertices)
    truth = load_mesh(SURFACES / f"{name}.truth.obj")
    np.testing.assert_array_equal(truth.vertices, s.truth_control.vertices)
    np.testing.assert_array_equal(load_surface_target(SURFACES / f"{name}.cloud.xyz").points, s.cloud)
    assert (SURFACES / f"{name}.genome.json").exists() == (s.truth_genome is not None)


def test_cli_writes_surface_samples(gsr, tmp_path):
    res = gsr("sample", "inset_extrude", "-o", tmp_path / "t.obj", "--truth", tmp_path / "truth.obj")
    assert res.code == 0, res.err
    s = SURFACE_SAMPLES["inset_extrude"]()
    target = load_surface_target(tmp_path / "t.obj")
    assert target.kind == "mesh" and len(target.points) == s.target.n_vertices
    assert load_mesh(tmp_path / "truth.obj").n_faces == s.truth_control.n_faces
    res = gsr("sample", "extended", "-o", tmp_path / "c.xyz")
    assert res.code == 0, res.err
    cloud = load_surface_target(tmp_path / "c.xyz")
    assert cloud.kind == "cloud"
    np.testing.assert_array_equal(cloud.points, SURFACE_SAMPLES["extended"]().cloud)
    listing = gsr("sample", "--list")
    assert all(name in listing.out for name in NAMES)
