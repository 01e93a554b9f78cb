"""Block parts: a box body with thick blocks standing on its faces (an E core's prongs, a power package's tab, a
boss), and the start a designer builds for them.

Leads (module :mod:`.leads`) are found by an opening that strips thin pieces off the body; a prong as thick as the
plate it stands on survives any opening. Blocks are found the other way round:

* :func:`find_blocks`: the target's voxel solid in the template's frame; its bounding box is peeled, the least
  filled face layer first, while some face layer is less than :data:`FILL` full: what is left is the body's box.
  The pieces of the solid outside it (:data:`MIN_BLOCK` of the volume, :data:`MIN_HEIGHT` tall) are the blocks,
  each as the box face it stands on, its footprint there and its height.
* :func:`block_genomes`: ops on the placed cube template: moves to the body's box, an edge loop at each side of
  every footprint (slid onto it by vertex moves), loops at midpoints until every axis has :data:`MIN_LINES`, then
  per block a region extrusion (X) of the faces under its footprint by its height.

:func:`~gsr_cad.reconstruct.starts.structured_start` gates this start as it gates the legs.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy import ndimage

from ..errors import OpError
from ..geometry.polymesh import PolyMesh, unit_cube
from ..geometry.voxels import solid_voxels
from ..ops.mesh import EdgeLoop, ExtrudeRegion
from .inputs import SurfaceTarget
from .refine import apply_ops

FILL = 0.9
"""A face layer of the body's box is at least this full (the peel's stop)."""
MIN_BLOCK = 0.005
"""A block's least volume, a share of the solid's."""
MIN_HEIGHT = 3
"""Voxels beyond the box's face where blocks are told apart and their footprints measured: nearer the face a
drafted wall or a fillet joins them."""
REACH = 0.1
"""A block's least height, a share of the box's extent across the face it stands on."""
MIN_LINES = 3
"""Loops across each axis of the body's box at least (its faces four wide, as two splits make them)."""
MAX_LINES = 9
"""Loops across one axis at most: the smallest blocks are left out until their footprints' sides fit."""
SEGMENTS = 1
BLOCK_PATH = "body and blocks"
"""The refinement path (result.json ``refined_from``) that grew from the blocks' genome."""


@dataclasses.dataclass(frozen=True)
class Block:
    """A block on face ``side`` (0: low, 1: high) of axis ``axis`` of the body's box; ``low``/``high``: its
    footprint in the template's frame (the axis's own coordinate the face's), ``height`` its reach off the face."""

    axis: int
    side: int
    low: np.ndarray
    high: np.ndarray
    height: float
    volume: float


@dataclasses.dataclass(frozen=True)
class Blocks:
    """The body's box (``low``, ``high``: corners in the template's frame) and its blocks, largest first."""

    low: np.ndarray
    high: np.ndarray
    blocks: list[Block]
    seconds: float


def _peel(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The body's box in voxels, ``[low, high)`` per axis (module docstring)."""
    found = np.argwhere(matrix)
    low, high = found.min(axis=0), found.max(axis=0) + 1
    while np.all(high - low > 2):
        box = matrix[low[0]:high[0], low[1]:high[1], low[2]:high[2]]
        fills = []
        for axis in range(3):
            layers = np.moveaxis(box, axis, 0)
            fills += [layers[0].mean(), layers[-1].mean()]
        worst = int(np.argmin(fills))
        if fills[worst] >= FILL:
            break
        axis, side = divmod(worst, 2)
        if side:
            high[axis] -= 1
        else:
            low[axis] += 1
    return low, high


def find_blocks(target: SurfaceTarget, axes: np.ndarray) -> Blocks | None:
    """The body's box and its blocks in the frame ``axes`` (columns: unit axes; module docstring); None when the
    target is not a closed mesh or no block stands on the box."""
    started = time.perf_counter()
    solid = solid_voxels(target.points @ axes, target.faces)
    if solid is None:
        return None
    matrix, origin, pitch = solid
    low, high = _peel(matrix)
    total = float(matrix.sum())
    blocks = []
    for axis in range(3):
        for side in (0, 1):
            # the solid beyond this face of the box and over it: a block stands there
            slab = [slice(low[a], high[a]) for a in range(3)]
            slab[axis] = slice(high[axis], None) if side else slice(0, low[axis])
            corner = np.array([s.start for s in slab])
            part = matrix[tuple(slab)]
            depth = np.arange(part.shape[axis]) if side else np.arange(part.shape[axis])[::-1]
            depth = np.broadcast_to(np.expand_dims(depth, [a for a in range(3) if a != axis]), part.shape)
            # a drafted wall or a fillet along the face joins the blocks on it: they are told apart beyond it
            labels, _ = ndimage.label(part & (depth >= MIN_HEIGHT))
            for k, box in enumerate(ndimage.find_objects(labels), start=1):
                if box is None:
                    continue
                mine = labels[box] == k
                cells = np.argwhere(mine) + [b.start for b in box] + corner
                height = 1 + int(depth[box][mine].max())
                if len(cells) < MIN_BLOCK * total or height < REACH * (high[axis] - low[axis]):
                    continue
                near = cells[depth[box][mine] < 2 * MIN_HEIGHT]
                if not len(near):  # it stands on something else beyond the face
                    continue
                foot_low = near.min(axis=0).astype(float)
                foot_high = near.max(axis=0) + 1.0
                foot_low[axis] = foot_high[axis] = high[axis] if side else low[axis]
                blocks.append(Block(axis, side, origin + pitch * (foot_low - 0.5),
                                    origin + pitch * (foot_high - 0.5), float(height * pitch), float(len(cells))))
    if not blocks:
        return None
    blocks.sort(key=lambda b: -b.volume)
    return Blocks(origin + pitch * (low - 0.5), origin + pitch * (high - 0.5), blocks,
                  time.perf_counter() - started)


def _lines(found: Blocks) -> tuple[list[list[float]], list[Block]]:
    """Per axis the loops' positions (footprint sides, then midpoints of the widest gaps) and the blocks they
    serve (the smallest left out while an axis needs more than :data:`MAX_LINES`)."""
    extent = found.high - found.low
    blocks = list(found.blocks)
    while True:
        lines: list[list[float]] = [[], [], []]
        for b in blocks:
            for a in range(3):
                if a == b.axis:
                    continue
                for x in (b.low[a], b.high[a]):
                    t = (x - found.low[a]) / extent[a]
                    if 0.02 < t < 0.98 and all(abs(t - s) > 0.02 for s in lines[a]):
                        lines[a].append(float(t))
        if all(len(x) <= MAX_LINES for x in lines) or len(blocks) == 1:
            break
        blocks.pop()
    return [sorted(x) for x in lines], blocks


def _column_edge(mesh: PolyMesh, local: np.ndarray, axis: int, a: float, b: float) -> int | None:
    """An edge along ``axis`` from level ``a`` to level ``b`` (local coordinates), or None."""
    edges = mesh.topology.edges
    p, q = local[edges[:, 0], axis], local[edges[:, 1], axis]
    tol = 1e-6 * max(1.0, abs(b - a))
    hit = np.flatnonzero(((np.abs(p - a) < tol) & (np.abs(q - b) < tol)) | ((np.abs(p - b) < tol)
                                                                          & (np.abs(q - a) < tol)))
    return int(hit[0]) if len(hit) else None


def block_genomes(problem, found: Blocks, axes: np.ndarray) -> tuple[tuple, tuple, int] | None:
    """``(the body's box with its loops, that plus the blocks, how many blocks got theirs)`` as genomes on
    ``problem``'s template (module docstring), or None when the ops refuse or no block gets its extrusion."""
    extent = found.high - found.low
    corners = (found.low + (unit_cube().vertices + 0.5) * extent) @ axes.T
    moves, state, refused = problem._moves(problem.template, corners)
    if refused:
        return None
    genome = tuple(moves)
    lines, blocks = _lines(found)
    for axis in range(3):
        levels = [0.0, 1.0]
        wanted = list(lines[axis])
        fills = max(0, MIN_LINES - len(wanted))
        while wanted or fills:
            if wanted:
                t = wanted.pop(0)
                a = max(x for x in levels if x < t)
                b = min(x for x in levels if x > t)
            else:
                gaps = np.diff(levels)
                i = int(np.argmax(gaps))
                a, b = levels[i], levels[i + 1]
                t = 0.5 * (a + b)
                fills -= 1
            local = (state.vertices @ axes - found.low) / extent
            edge = _column_edge(state, local, axis, a, b)
            if edge is None:
                return None
            try:
                state = EdgeLoop(edge).apply(state)
            except OpError:
                return None
            genome += (EdgeLoop(edge),)
            levels = sorted(levels + [t])
            if abs(t - 0.5 * (a + b)) > 1e-9:
                local = (state.vertices @ axes - found.low) / extent
                new = np.abs(local[:, axis] - 0.5 * (a + b)) < 1e-9
                goal = local.copy()
                goal[new, axis] = t
                moves, state, refused = problem._moves(state, (found.low + goal * extent) @ axes.T)
                if refused:
                    return None
                genome += tuple(moves)
    body = genome
    used: set[int] = set()
    count = 0
    for b in blocks:
        centres = (state.face_centroids @ axes - found.low) / extent
        normals = state.face_normals @ axes
        others = [a for a in range(3) if a != b.axis]
        lo = (b.low - found.low) / extent
        hi = (b.high - found.low) / extent
        sign = 1.0 if b.side else -1.0
        on = ((normals[:, b.axis] * sign > 0.99) & (np.abs(centres[:, b.axis] - b.side) < 1e-6)
              & np.all((centres[:, others] > lo[others]) & (centres[:, others] < hi[others]), axis=1))
        faces = tuple(int(f) for f in np.flatnonzero(on))
        if not faces or used & set(faces):
            continue
        ops = tuple(ExtrudeRegion(faces, b.height / SEGMENTS) for _ in range(SEGMENTS))
        built = apply_ops(ops, state)
        if built is None:
            continue
        used |= set(faces)
        state = built
        genome += ops
        count += 1
    return (body, genome, count) if count else None
