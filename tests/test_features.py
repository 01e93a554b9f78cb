"""Feature lines of surface targets and the crease proposals built on them."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from gsr_cad.errors import ConfigError
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.reconstruct.features import CreaseProposals, cloud_feature_points, feature_points, mesh_feature_edges


def test_cylinder_rims_are_its_feature_edges():
    m = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=32)
    edges = mesh_feature_edges(m.vertices, m.faces)
    assert len(edges) == 64  # two rims of 32 edges; the side's and caps' triangulation edges are smooth
    assert np.allclose(np.abs(m.vertices[edges.ravel(), 2]), 1.0)
    assert len(mesh_feature_edges(m.vertices, m.faces, angle_deg=89.0)) == 64
    assert len(mesh_feature_edges(m.vertices, m.faces, angle_deg=5.0)) > 64  # the faceted side too
    with pytest.raises(ConfigError):
        mesh_feature_edges(m.vertices, m.faces, angle_deg=0.0)


def test_smooth_targets_have_no_feature_lines():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    assert len(feature_points(sphere.vertices, sphere.faces)) == 0
    cloud = np.random.default_rng(0).normal(size=(4000, 3))
    cloud /= np.linalg.norm(cloud, axis=1, keepdims=True)
    assert len(cloud_feature_points(cloud)) < 0.01 * len(cloud)


def _cube_cloud(n: int, rng: np.random.Generator) -> np.ndarray:
    """Points uniform on the faces of the cube [-1, 1]^3."""
    pts = rng.uniform(-1.0, 1.0, (n, 3))
    axis = rng.integers(3, size=n)
    pts[np.arange(n), axis] = rng.choice([-1.0, 1.0], size=n)
    return pts


def test_cloud_features_lie_on_the_cube_edges():
    rng = np.random.default_rng(0)
    f = cloud_feature_points(_cube_cloud(6000, rng) + rng.normal(0, 1e-4, (6000, 3)))
    assert len(f) > 100
    near_edge = np.sort(np.abs(np.abs(f) - 1.0), axis=1)[:, 1]  # two coordinates at +-1 on an edge
    assert np.median(near_edge) < 0.05


def test_proposals_follow_the_feature_lines():
    """A box control mesh whose limit lies on a cube with rounded-off edges: no proposal; the same box with a
    fitted limit: its top rim edges, which a crease would make run along the target's sharp edges."""
    target = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    proposals = CreaseProposals(target.vertices, target.faces, radius=0.05)
    assert len(proposals.features) > 12
    far = unit_cube(2.0)  # its smooth limit shrinks well inside the cube
    assert proposals.edges(far) == []
    cube = unit_cube(2.0)
    sharp = cube.with_creases({tuple(sorted(e)): 10.0 for e in cube.topology.edges.tolist()})
    # infinitely sharp everywhere: the limit is the cube itself, every edge lies on a feature line
    assert sorted(CreaseProposals(target.vertices, target.faces, radius=0.05).edges(sharp)) == list(range(12))
    assert CreaseProposals(target.vertices[:0], None).edges(cube) == []


def test_rim_proposals_pick_the_cylinder_caps():
    """The box template fitted to a cylinder: its top and bottom faces' outlines are nearest the rims."""
    target = trimesh.creation.cylinder(radius=1.0, height=2.0)
    proposals = CreaseProposals(target.vertices, target.faces)
    box = unit_cube(1.0)
    box = box.with_vertices(box.vertices * [2.4, 2.4, 2.4])
    faces = proposals.faces(box)
    assert sorted(faces) == [4, 5]  # -z and +z
    assert CreaseProposals(target.vertices[:0], None).faces(box) == []
