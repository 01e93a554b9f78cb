"""Leaded parts: a body with thin pieces (pins, leads, legs) leaving it, and the start a designer builds for them.

A leg is structure from the start, not a bump a fit pulls out of a converged grid (session 24: extruding the faces
of most residual on TCMT1107's converged 386-vertex cage gained at most 0.8 %). So the refinement may grow, beside
the search's winner, a start with the legs in it:

* :func:`find_leads`: the target's voxel solid, opened by a ball of :data:`OPENING_SHARE` of its thinnest extent;
  the largest piece left is the body; the pieces of the solid outside the dilated body that reach :data:`REACH`
  opening radii beyond it are the leads, each as where it leaves the body and its farthest point from there.
* :func:`lead_genomes`: ops on the placed cube template: moves to the body's box (in the template's own frame),
  two splits (edge loops: the box's 98-vertex grid; three where pins crowd a side), then per lead an inset of the
  face it leaves from and :data:`SEGMENTS` extrusions along it.
* :func:`lead_start`: that start when it pays: fitted alike, the cage with its legs must gain on the body's box
  alone at least :data:`MIN_GAIN` (log distance per log control vertices; a split gains about 0.3-0.5) and
  :data:`MIN_RATIO`, so that a blob or a slotted part whose "leads" are ribs keeps the plain template.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
from scipy import ndimage

from ..errors import GsrError, OpError
from ..geometry.polymesh import PolyMesh, unit_cube
from ..ops.mesh import Extrude, Inset
from .inputs import SurfaceTarget
from .refine import split_all

RESOLUTION = 120
"""Voxels along the target's longest extent."""
OPENING_SHARE = 0.15
"""Radius of the opening that strips the leads off the body, a share of the target's thinnest extent."""
MIN_LEAD = 0.002
"""A lead's least volume, a share of the solid's: smaller pieces are voxel noise on the body's rim."""
REACH = 1.5
"""How far a lead reaches from the body at least, in opening radii."""
SPLITS = 2
MAX_SPLITS = 3
SEGMENTS = 3
INSET = 0.25
"""The inset of a lead's face, a share of the face's size (its corners' least distance from its centre). Against
0.25, after 60 fit rounds: 0.1 was 8 % closer on TCMT1107 and 2 % farther on MSOP-10; 0.4 2.0x farther on TCMT1107,
and refused on MSOP-10."""
MIN_GAIN = 0.5
"""The legs' least gain: as much as the best splits gain per added vertex (TSSOP-8's eight legs, 0.59 at the gate,
grew to 678 control vertices at 7.2e-4 of the diagonal both ways, where the baseline has 2.0e-3 at 755)."""
MIN_RATIO = 1.5
"""And the legs must bring the cage this many times closer (a single short "lead" adds few vertices: LetterBlock's
letter, 98 -> 114 control vertices, 2.1e-2 -> 1.7e-2 of the diagonal, a gain of 1.5 that is no leg)."""
GATE_ROUNDS = 20
LEAD_PATH = "body and leads"
"""The refinement path (result.json ``refined_from``) that grew from :func:`lead_start`'s genome."""


@dataclasses.dataclass(frozen=True)
class Leads:
    """The body's voxel centres and, per lead, ``(where it leaves the body, its farthest point from there)``."""

    body: np.ndarray
    leads: list[tuple[np.ndarray, np.ndarray]]
    seconds: float


def _surface_points(points: np.ndarray, faces: np.ndarray, spacing: float) -> np.ndarray:
    """Points on every triangle, no two neighbours farther apart than ``spacing``: each triangle's vertices
    subdivided ``n`` times along its edges (barycentric grid), ``n`` from its longest edge."""
    tri = points[faces]
    longest = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    splits = np.maximum(np.ceil(longest / spacing).astype(np.int64), 1)
    out = [points]
    for n in np.unique(splits):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        bary = np.stack([n - i[keep] - j[keep], i[keep], j[keep]], axis=1) / n
        out.append(np.einsum("pk,tkd->tpd", bary, tri[splits == n]).reshape(-1, 3))
    return np.concatenate(out)


def _solid(target: SurfaceTarget) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The target's solid as voxels: ``(filled matrix, the position of voxel (0, 0, 0)'s centre, pitch)``; None for
    a cloud or a mesh that is not closed. The surface's voxels are those of points on it half a pitch apart (which
    keeps them 6-connected), filled (as trimesh's subdividing voxeliser does, at a fraction of its time: 14.5 s ->
    well under one on an 11,884-triangle OpenSCAD part)."""
    import trimesh

    if target.faces is None:
        return None
    if not trimesh.Trimesh(target.points, target.faces, process=False).is_watertight:
        return None
    extents = np.ptp(target.points, axis=0)
    pitch = float(extents.max()) / RESOLUTION
    if pitch <= 0:
        return None
    hit = np.round(_surface_points(target.points, target.faces, 0.5 * pitch) / pitch).astype(np.int64)
    low = hit.min(axis=0) - 1
    hit -= low
    matrix = np.zeros(tuple(hit.max(axis=0) + 2), dtype=bool)
    matrix[hit[:, 0], hit[:, 1], hit[:, 2]] = True
    return ndimage.binary_fill_holes(matrix), low * pitch, pitch


def find_leads(target: SurfaceTarget) -> Leads | None:
    """The body and the leads of a closed mesh target (module docstring); None when it is not closed, has no body
    or no leads."""
    started = time.perf_counter()
    solid = _solid(target)
    if solid is None:
        return None
    matrix, origin, pitch = solid
    ball = ndimage.generate_binary_structure(3, 1)
    thinnest = float(np.ptp(target.points, axis=0).min())
    radius = max(1, round(OPENING_SHARE * thinnest / pitch))
    opened = ndimage.binary_opening(matrix, structure=ball, iterations=radius)
    labels, count = ndimage.label(opened)
    if not count:
        return None
    body = labels == 1 + int(np.argmax(ndimage.sum(opened, labels, range(1, count + 1))))
    labels, count = ndimage.label(matrix & ~ndimage.binary_dilation(body, ball, iterations=1))
    near = ndimage.binary_dilation(body, ball, iterations=2)
    away = ndimage.distance_transform_edt(~body)
    total = float(matrix.sum())
    index = np.arange(1, count + 1)
    sizes = ndimage.sum_labels(matrix, labels, index)
    # the opening's ball cuts the body's edges and corners off too (a diamond of voxels: at most 1.2 radii deep):
    # a lead reaches farther from the body
    reach = ndimage.maximum(away, labels, index) if count else np.zeros(0)
    leads = []
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None or sizes[k - 1] < MIN_LEAD * total or reach[k - 1] < REACH * radius:
            continue
        corner = np.array([b.start for b in box])
        piece = labels[box] == k
        root = np.argwhere(piece & near[box])
        if not len(root):
            continue
        start = origin + pitch * (corner + root.mean(axis=0))
        cells = origin + pitch * (corner + np.argwhere(piece))
        leads.append((start, cells[int(np.argmax(np.linalg.norm(cells - start, axis=1)))]))
    if not leads:
        return None
    return Leads(origin + pitch * np.argwhere(body), leads, time.perf_counter() - started)


def _frame(template: PolyMesh) -> np.ndarray | None:
    """The placed cube's axes (columns: its edges from vertex 0 along x, y, z, unit length), or None when the
    template is not a box with the unit cube's connectivity."""
    cube = unit_cube()
    if template.n_vertices != 8 or [tuple(f) for f in template.faces] != [tuple(f) for f in cube.faces]:
        return None
    v = template.vertices
    axes = np.stack([v[1] - v[0], v[2] - v[0], v[4] - v[0]], axis=1)
    lengths = np.linalg.norm(axes, axis=0)
    if np.any(lengths <= 0):
        return None
    axes = axes / lengths
    if np.abs(axes.T @ axes - np.eye(3)).max() > 1e-6:
        return None
    return axes


def lead_genomes(problem, leads: Leads) -> tuple[tuple, tuple] | None:
    """``(the body's box split, that plus the leads)`` as genomes on ``problem``'s template (module docstring), or
    None when the template is not a placed cube, the ops refuse or no lead gets its leg. The box is split
    :data:`SPLITS` times, once more (up to :data:`MAX_SPLITS`) while leads share a face (a row of many pins on a
    side four faces wide); the split that gives most leads their leg is kept."""
    axes = _frame(problem.template)
    if axes is None:
        return None
    local = leads.body @ axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    bits = unit_cube().vertices + 0.5
    # the cage on the body's box: after two splits its limit surface hugs it (a cage 5 % larger fitted TCMT1107's
    # legs 2.4x farther)
    box = (lo + bits * (hi - lo)) @ axes.T
    moves, state, refused = problem._moves(problem.template, box)
    if refused:
        return None
    genome = tuple(moves)
    best: tuple[tuple, tuple, int] | None = None
    for splits in range(1, MAX_SPLITS + 1):
        split = split_all(state, state)
        if split is None:
            break
        genome += split[0]
        state = split[1]
        if splits < SPLITS:
            continue
        legs, count = _legs(state, genome, leads.leads)
        if count and (best is None or count > best[2]):
            best = (genome, legs, count)
        if count == len(leads.leads):
            break
    return None if best is None else best[:2]


def _legs(state: PolyMesh, genome: tuple, leads: list[tuple[np.ndarray, np.ndarray]]) -> tuple[tuple, int]:
    """``genome`` (which builds ``state``) followed by an inset and :data:`SEGMENTS` extrusions per lead, and how
    many leads got theirs (a lead whose face another took, or whose ops refuse, is left out)."""
    used: set[int] = set()
    for start, far in leads:
        along = far - start
        length = float(np.linalg.norm(along))
        # the face nearest where the lead leaves, preferring faces that look along it (when another lead has it,
        # the grid is too coarse there)
        score = (np.linalg.norm(state.face_centroids - start, axis=1)
                 - 0.5 * np.maximum(state.face_normals @ along, 0.0))
        face = int(np.argmin(score))
        if face in used or length <= 0:
            continue
        corners = state.vertices[list(state.faces[face])]
        size = float(np.linalg.norm(corners - corners.mean(axis=0), axis=1).min())
        ops = (Inset(face, INSET * size),) + tuple(Extrude(face, length / SEGMENTS) for _ in range(SEGMENTS))
        try:
            built = state
            for op in ops:
                built = op.apply(built)
        except OpError:
            continue
        used.add(face)
        state = built
        genome += ops
    return genome, len(used)


def lead_start(problem, deadline: float | None = None) -> tuple[tuple, dict[str, Any]] | None:
    """``(the leads' genome, what was measured)`` (:func:`lead_genomes`; result.json ``lead_start``), the genome
    empty unless its cage, fitted, gains on the body's box alone at least :data:`MIN_GAIN` (module docstring);
    None when no lead is found, the template is not a placed cube or time (``deadline``, a ``perf_counter``
    value) runs out."""
    leads = find_leads(problem.target)
    if leads is None:
        return None
    genomes = lead_genomes(problem, leads)
    if genomes is None:
        return None
    costs = []
    sizes = []
    for genome in genomes:
        if deadline is not None and time.perf_counter() >= deadline:
            return None
        try:
            mesh = problem.control_mesh(genome)
            costs.append(problem.fit(mesh, GATE_ROUNDS, min_gain=1.0, adaptive=True, deadline=deadline)[1])
        except GsrError:
            return None
        sizes.append(mesh.n_vertices)
    if not all(math.isfinite(c) and c > 0 for c in costs):
        return None
    gain = math.log(costs[0] / costs[1]) / math.log(sizes[1] / sizes[0])
    info = {"leads": len(leads.leads), "legs": sum(isinstance(op, Inset) for op in genomes[1][len(genomes[0]):]),
            "body_vertices": sizes[0], "body_distance": costs[0],
            "lead_vertices": sizes[1], "lead_distance": costs[1], "gain": gain,
            "seconds": leads.seconds}
    info["kept"] = bool(gain >= MIN_GAIN and costs[1] * MIN_RATIO <= costs[0])
    return (genomes[1] if info["kept"] else (), info)
