"""The voxel solid a designer's start is read from: its volume is the mesh's, and only closed meshes have one."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from gsr_cad.geometry.voxels import is_closed, solid_voxels


@pytest.mark.parametrize("mesh", [trimesh.creation.box((3.0, 1.0, 0.5)), trimesh.creation.icosphere(3, 1.3),
                                  trimesh.creation.annulus(0.4, 1.0, 0.6)], ids=["box", "sphere", "annulus"])
def test_the_solid_has_the_meshs_volume(mesh):
    assert is_closed(mesh.faces)
    matrix, origin, pitch = solid_voxels(mesh.vertices, mesh.faces)
    assert pitch == pytest.approx(np.ptp(mesh.vertices, axis=0).max() / 120)
    # voxels whose centres fall within half a pitch of the surface count: about half a pitch of skin too many
    skin = 0.5 * pitch * mesh.area
    assert abs(matrix.sum() * pitch ** 3 - mesh.volume - skin) < 0.5 * skin
    centres = origin + pitch * np.argwhere(matrix)
    assert np.all(centres.min(axis=0) > mesh.bounds[0] - pitch) and np.all(centres.max(axis=0) < mesh.bounds[1] + pitch)


def test_an_open_mesh_or_a_cloud_has_no_solid():
    mesh = trimesh.creation.box((1.0, 1.0, 1.0))
    assert not is_closed(mesh.faces[:-1])
    assert solid_voxels(mesh.vertices, mesh.faces[:-1]) is None
    assert solid_voxels(mesh.vertices, None) is None
