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

:func:`~gsr_cad.reconstruct.starts.structured_start` grows it only where it pays.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy import ndimage

from ..geometry.polymesh import PolyMesh, unit_cube
from ..geometry.voxels import solid_voxels
from ..ops.mesh import Extrude, Inset
from .inputs import SurfaceTarget
from .refine import apply_ops, split_all

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
LEAD_PATH = "body and leads"
"""The refinement path (result.json ``refined_from``) that grew from :func:`lead_genomes`' legs."""


@dataclasses.dataclass(frozen=True)
class Leads:
    """The body's voxel centres and, per lead, ``(where it leaves the body, its farthest point from there)``."""

    body: np.ndarray
    leads: list[tuple[np.ndarray, np.ndarray]]
    seconds: float


def find_leads(target: SurfaceTarget) -> Leads | None:
    """The body and the leads of a closed mesh target (module docstring); None when it is not closed, has no body
    or no leads."""
    started = time.perf_counter()
    solid = solid_voxels(target.points, target.faces)
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


def cube_frame(template: PolyMesh) -> np.ndarray | None:
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
    axes = cube_frame(problem.template)
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
        built = apply_ops(ops, state)
        if built is None:
            continue
        used.add(face)
        state = built
        genome += ops
    return genome, len(used)
