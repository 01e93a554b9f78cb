"""A fit round's step kept sound (gsr_cad.reconstruct.surface._sound_step): offending vertices' steps halved."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.ops.mesh_kernel import unsound_faces
from gsr_cad.reconstruct.surface import _FIT_MARGIN, _HALVINGS, _sound_step

_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def _cage(steps: int = 2) -> PolyMesh:
    """A cube's connectivity refined ``steps`` Catmull-Clark steps (98 control vertices for two)."""
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    cage = PolyMesh.from_faces(v, _FACES)
    for _ in range(steps):
        r = get_catmull_clark(cage, 1, "all").refine(cage.vertices)
        cage = PolyMesh.from_faces(r.vertices, r.faces)
    return cage


def _shares(V: np.ndarray, out: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Each vertex's share of its step that ``out`` took."""
    length = np.einsum("ij,ij->i", step, step)
    return np.divide(np.einsum("ij,ij->i", out - V, step), length, out=np.zeros(len(V)), where=length > 0)


def test_only_the_folding_vertex_is_shortened():
    """One vertex pushed through the surface, every other moved a little outwards: the vertices off its faces
    keep their whole step, those on them at least half of it, the folding one part of its way, and no face
    turns unsound. Holding the vertices of the faces it folded (the former rule) kept none of their steps."""
    cage = _cage()
    V = cage.vertices
    step = 0.01 * V
    k = int(np.argmax(V[:, 0] + 0.1 * V[:, 1] + 0.01 * V[:, 2]))
    step[k] = -2.5 * V[k]  # through the middle of the cube: its faces would flip
    ref = cage.face_newell
    before = unsound_faces(cage, ref, _FIT_MARGIN)
    out = _sound_step(cage, V, step, ref, _FIT_MARGIN)
    assert out is not None
    assert not (unsound_faces(cage.with_vertices(out), ref, _FIT_MARGIN) & ~before).any()
    share = _shares(V, out, step)
    assert 0.0 <= share[k] < 1.0
    face_of = np.repeat(np.arange(cage.n_faces), cage.face_sizes)
    near = np.unique(cage.corners[np.isin(face_of, face_of[cage.corners == k])])
    far = np.setdiff1d(np.arange(len(V)), near)
    assert np.allclose(share[far], 1.0)
    assert np.all(share[np.setdiff1d(near, [k])] >= 0.5 - 1e-12)  # halved at most once with the folded faces
    # the steps are only shortened along themselves, never turned
    assert np.allclose(np.cross(out - V, step), 0.0, atol=1e-12)


def test_a_step_with_no_sound_share_is_refused():
    """One vertex's step so long that even its shortest share folds its faces, the others still: None (no
    round), not a move of less than ``_STEP_KEEP`` of the step."""
    cage = _cage(1)
    V = cage.vertices
    step = np.zeros_like(V)
    step[0] = -200.0 * V[0]
    assert _sound_step(cage, V, step, cage.face_newell, _FIT_MARGIN) is None


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.01, 1.0))
def test_random_steps_end_sound(seed, scale):
    """Random steps of a refined cube: the result is None or has no face newly unsound, and every vertex took
    its whole step, a power-of-two share of it (at most ``_HALVINGS`` halvings) or none of it."""
    cage = _cage()
    V = cage.vertices
    step = scale * np.random.default_rng(seed).normal(size=V.shape)
    ref = cage.face_newell
    before = unsound_faces(cage, ref, _FIT_MARGIN)
    out = _sound_step(cage, V, step, ref, _FIT_MARGIN)
    if out is None:
        return
    assert not (unsound_faces(cage.with_vertices(out), ref, _FIT_MARGIN) & ~before).any()
    share = _shares(V, out, step)
    allowed = np.array([0.0] + [0.5 ** h for h in range(_HALVINGS + 1)])
    assert np.all(np.min(np.abs(share[:, None] - allowed[None, :]), axis=1) < 1e-9)


def test_free_corners_allow_a_concave_corner_but_keep_the_margin():
    """A refined cube with one vertex pushed across the diagonal of a face's corner (that face's corner turns
    concave, the face stays star-shaped): the fit's margin refuses it with convex corners and accepts it with
    ``convex`` False; a face squeezed to a sliver is refused either way."""
    cage = _cage()
    V = cage.vertices.copy()
    ref = cage.face_newell
    assert not unsound_faces(cage, ref, _FIT_MARGIN).any()
    f = 0
    a, b, c, d = cage.faces[f]
    # b pushed towards the face's centre, past the diagonal a-c: the corner at b turns concave (reflex)
    centre = V[[a, b, c, d]].mean(axis=0)
    bent = V.copy()
    bent[b] = centre + 0.3 * (centre - V[b])
    moved = cage.with_vertices(bent)
    turn = np.cross(bent[b] - bent[a], bent[c] - bent[b]) @ (ref[f] / np.linalg.norm(ref[f]))
    assert turn < 0.0  # the corner at b is concave
    assert unsound_faces(moved, ref, _FIT_MARGIN)[f]
    assert not unsound_faces(moved, ref, _FIT_MARGIN, convex=False)[f]
    assert not unsound_faces(moved, ref)[f]  # the ops' own checks accept it: its moves replay
    # a sliver: b pushed onto a's place, but not quite
    thin = V.copy()
    thin[b] = V[a] + 1e-4 * (V[b] - V[a])
    assert unsound_faces(cage.with_vertices(thin), ref, _FIT_MARGIN, convex=False)[f]
    # the step that bends the corner is taken whole with free corners, shortened with convex ones
    step = bent - V
    free = _sound_step(cage, V, step, ref, _FIT_MARGIN, convex=False)
    kept = _sound_step(cage, V, step, ref, _FIT_MARGIN)
    assert free is not None and np.allclose(free, bent)
    assert kept is None or not np.allclose(kept, bent)
