"""Replays of a few thousand seeded random op sequences pinned by a digest recorded before the op kernel
was optimised: which ops apply, which raise, and the resulting meshes (connectivity exactly, positions to
1e-9) must not change when the kernel is made faster."""

from __future__ import annotations

import hashlib

import numpy as np

from gsr_cad.errors import GsrError
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.ops.mesh import PAPER_RANGES, OpRanges, random_op

KINDS = ["VELBIFS", "LB", "EIL", "VBF", "BBLLE", "VELBIFS"]
GENOMES = 2000
ATTEMPTS = 12
DIGEST = "eed9d9ff3f9e0c036080e855bcd3f0089f4572662cf8223b593452086cd0c0c8"
"""sha256 of :func:`replay_digest` computed with the kernel of commit 016209a."""


def replay_digest(genomes: int, attempts: int) -> str:
    """Seeded random ops (all kinds, the default and the paper's wider ranges, so that many are invalid)
    applied in turn to the cube; each attempt logs the op letter or the error type, each sequence its
    final mesh."""
    cube = unit_cube()
    h = hashlib.sha256()
    for seed in range(genomes):
        rng = np.random.default_rng(seed)
        kinds = KINDS[seed % len(KINDS)]
        ranges = PAPER_RANGES if seed % 3 == 0 else OpRanges()
        state = cube
        for _ in range(attempts):
            op = random_op(rng, state, cube.diagonal, kinds, ranges)
            try:
                state = op.apply(state)
            except GsrError as e:
                h.update(b"-" + type(e).__name__.encode())
            else:
                h.update(b"+" + op.letter.encode())
        h.update(state.offsets.tobytes())
        h.update(state.corners.tobytes())
        h.update(np.round(state.vertices, 9).tobytes())
    return h.hexdigest()


def test_random_replays_match_the_recorded_digest():
    assert replay_digest(GENOMES, ATTEMPTS) == DIGEST


def test_mesh_views_stay_equal_to_a_fresh_computation():
    """What an op hands on to the next (positions, Newell vectors, bounds, connectivity) equals what a fresh
    view of the result would compute."""
    from gsr_cad.ops import mesh_kernel as K
    from gsr_cad.ops.mesh_conn import MeshConn, mesh_view

    cube = unit_cube()
    checked = 0
    for seed in range(150):
        rng = np.random.default_rng(seed)
        state = cube
        for _ in range(8):
            op = random_op(rng, state, cube.diagonal, KINDS[seed % len(KINDS)])
            try:
                state = op.apply(state)
            except GsrError:
                continue
            view = mesh_view(state)
            assert view.P == state.vertices.tolist()
            assert view.conn.faces == state.faces
            assert view.conn.half == MeshConn(state.faces, state.n_vertices).half
            for f, n in enumerate(view.newell):
                assert n is None or n == K._newell(view.P, state.faces[f])
            assert view.bounds is None or view.bounds == K._bounds(view.P)
            checked += sum(n is not None for n in view.newell)
    assert checked > 1000
