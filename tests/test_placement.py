"""Template placement: the cube on a rotated target's principal axes, a user template fitted to a rotated,
scaled and moved target, a template placed already kept as given."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gsr_cad.geometry.limit_surface import LimitSurface
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.placement import fit_template, oriented_box, place_cube
from gsr_cad.reconstruct.surface import place_template
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


def moved(mesh, rotation, scale=1.0, shift=(0.0, 0.0, 0.0)):
    return mesh.with_vertices(scale * mesh.vertices @ rotation.T + np.asarray(shift))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_cube_sits_on_a_rotated_targets_principal_axes(seed):
    s = SURFACE_SAMPLES["flattened_extended"]()
    rot = Rotation.random(random_state=seed).as_matrix()
    target = surface_target(moved(s.target, rot), "rotated")
    placement = place_template("cube", target, SurfaceConfig())
    assert placement.method.startswith("oriented box")
    # its axes are the target's: the rotation maps the cube's axes onto the truth's, up to order and sign
    align = np.abs(placement.rotation.T @ rot)
    np.testing.assert_allclose(np.sort(align, axis=1)[:, -1], 1.0, atol=1e-3)
    # and its limit surface spans the target's box in that frame
    local = target.points @ placement.rotation
    lim = limit_mesh(placement.mesh, 3).vertices @ placement.rotation
    np.testing.assert_allclose(np.ptp(lim, axis=0), np.ptp(local, axis=0), rtol=1e-3)
    # an axis-aligned target keeps the axis-aligned box
    assert oriented_box(s.target.vertices)[3] == "axis-aligned box"
    assert place_cube(s.target.vertices).method == "axis-aligned box"


@pytest.mark.parametrize("seed", [3, 4])
def test_a_user_template_is_fitted_to_a_rotated_scaled_moved_target(seed):
    s = SURFACE_SAMPLES["flattened_extended"]()
    rot = Rotation.random(random_state=seed).as_matrix()
    truth = moved(s.truth_control, rot, 1.7, (0.3, -2.0, 1.0))
    target = surface_target(limit_mesh(truth, 3), "moved")
    placement = place_template(s.truth_control, target, SurfaceConfig())
    assert placement.method.startswith("similarity fit")
    assert placement.scale[0] == pytest.approx(1.7, rel=2e-2)
    # the same surface (a symmetric shape may come back as its symmetric image, so compare surfaces)
    d = LimitSurface.of(placement.mesh).closest(target.points).distance / target.diagonal
    assert d.mean() < 2e-3 and d.max() < 1e-2
    kept = fit_template(truth, target.points)
    assert kept.mesh is truth and kept.method.startswith("as given")
    as_given = place_template(s.truth_control, target, SurfaceConfig(fit_template=False))
    assert as_given.mesh.vertices.tolist() == s.truth_control.vertices.tolist()
