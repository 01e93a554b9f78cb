"""Genus-``n`` templates and the genus of a target.

:func:`genus_template` builds, with the surface ops themselves, a box with ``n`` through-holes in a row: ``n - 1``
edge loops cut the box into ``n`` equal strips along x, every top (+z) and bottom (-z) face is inset, and each
bottom face is bridged to the top face above it (the hole op H). :func:`fitted_template` places it on the target's
box (axis-aligned, or on its principal axes when that box is clearly smaller): the holes along the axis the
target's own holes run along (the axis with the most empty columns through its voxelised solid, else its thinnest
one), the row along the longest other axis, each template hole moved and sized onto one of the target's
through-holes when it shows as many (:func:`target_holes`), scaled so that its limit surface spans the box. A
genus-5 target bored along all three axes (one central through-hole seen along each: a block with crossing bores, a
cube minus a sphere) gets :func:`window_box` instead, a hollow box with a window in each wall sized to the bores.

:func:`target_genus` estimates the genus: exactly from the Euler characteristic ``V - E + F`` of a closed mesh
target (coincident vertices welded first; ``genus = components - chi / 2``); for a cloud or an open mesh from a
voxel solid: the target's points (a mesh's triangles sampled) mark the cells of a grid, the marked shell is closed
by one dilation and its cavities filled, and ``genus = components - chi`` of that cubical complex. The voxel
estimate closes holes narrower than about three cells (``resolution`` cells along the longest axis, a cloud's cells
no finer than its points' spacing), counts a gap in an open mesh wider than that as one more handle, and is marked
``"voxels"`` in :func:`genus_metrics`.

:func:`feature_genomes` builds starts for the search from the target's feature lines (a greedy sequence of rim
creases, creases and edge loops, each kept when the search's own cost falls).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import ConfigError, GsrError
from ..geometry.polymesh import SHARPNESS_INFINITE, PolyMesh, unit_cube
from ..geometry.subdivision import get_catmull_clark
from ..geometry.surface_distance import area_samples
from ..ops.mesh import Crease, CreaseRim, EdgeLoop, edge_loop, hole, inset
from ..ops.mesh_conn import mesh_view
from ..ops.mesh_kernel import distinct_rings
from .features import CreaseProposals
from .inputs import SurfaceTarget
from .placement import oriented_box

MAX_TEMPLATE_GENUS = 8
VOXEL_RESOLUTION = 48
_SAMPLES = 60_000
_SEED = 1313


def genus_template(genus: int) -> PolyMesh:
    """A box ``genus`` long in x (unit strips), unit in y and z, with one through-hole along z per strip
    (the unit cube for genus 0); built with the ops L, I and H, so every face is a quad."""
    if isinstance(genus, bool) or not isinstance(genus, (int, np.integer)) or not 0 <= genus <= MAX_TEMPLATE_GENUS:
        raise ConfigError(f"template genus must be a whole number in [0, {MAX_TEMPLATE_GENUS}], got {genus!r}")
    mesh = unit_cube()
    if genus == 0:
        return mesh
    for _ in range(genus - 1):  # cut the strip holding vertex 0 across x
        edges = mesh.topology.edges
        v = mesh.vertices
        along_x = np.flatnonzero((edges == 0).any(axis=1) & np.all(np.isclose(v[edges[:, 0], 1:], v[edges[:, 1], 1:]),
                                                                     axis=1))
        mesh = edge_loop(mesh, int(along_x[0]))
    xs = np.unique(mesh.vertices[:, 0])
    v = mesh.vertices.copy()
    v[:, 0] = np.searchsorted(xs, v[:, 0]) - genus / 2.0
    mesh = mesh.with_vertices(v)
    normals, centroids = mesh.face_normals, mesh.face_centroids
    bottom = [int(f) for f in np.flatnonzero(normals[:, 2] < -0.99)]
    top = [int(f) for f in np.flatnonzero(normals[:, 2] > 0.99)]
    pairs = [(f, min(top, key=lambda g: abs(centroids[g, 0] - centroids[f, 0]))) for f in bottom]
    for f in bottom + top:
        mesh = inset(mesh, f, 0.25)  # the inner face keeps the index
    for f, g in pairs:
        mesh = hole(mesh, f, g)
    return mesh


def window_box(outer: np.ndarray, inner: np.ndarray, windows: np.ndarray) -> PolyMesh:
    """The genus-5 quad mesh of a hollow box with a window in each of its six walls (a block bored along all
    three axes, a cube minus a sphere): the outer box ``[-outer, outer]``, the cavity ``[-inner, inner]``
    (per axis, ``inner < outer``), and the window through the walls across axis ``k`` spanning ``windows[k]``
    (the half-widths along the two other axes, in order, each below ``inner`` there); 64 vertices, 72 quads."""
    outer, inner, windows = (np.asarray(a, dtype=np.float64) for a in (outer, inner, windows))
    vid: dict[tuple, int] = {}
    points: list[np.ndarray] = []

    def v(key: tuple, point: np.ndarray) -> int:
        if key not in vid:
            vid[key] = len(points)
            points.append(point)
        return vid[key]

    square = ((-1, -1), (1, -1), (1, 1), (-1, 1))
    faces = []
    for k in range(3):
        u, w = (k + 1) % 3, (k + 2) % 3  # e_u x e_w = e_k
        for sign in (1, -1):
            order = square if sign > 0 else tuple((b, a) for a, b in square)  # counter-clockwise from outside
            rings = []
            for layer, half in (("outer", outer), ("inner", inner)):
                corners, window = [], []
                for a, b in order:
                    c = np.empty(3)
                    c[k], c[u], c[w] = sign * half[k], a * half[u], b * half[w]
                    key = tuple(int(np.sign(c[j])) for j in range(3))
                    corners.append(v((layer, key), c))
                    p = c.copy()
                    p[u], p[w] = a * windows[k][0], b * windows[k][1]
                    window.append(v((layer, k, sign, a, b), p))
                rings.append((corners, window))
            (c_out, w_out), (c_in, w_in) = rings
            for i in range(4):
                j = (i + 1) % 4
                faces += [(c_out[i], c_out[j], w_out[j], w_out[i]), (w_in[i], w_in[j], c_in[j], c_in[i]),
                          (w_out[i], w_out[j], w_in[j], w_in[i])]
    return PolyMesh.from_faces(np.array(points), faces)


# --- genus of a target ---------------------------------------------------------------------------------------

def _welded(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangles on welded vertices (coincident within 1e-9 of the diagonal), degenerate ones dropped."""
    diag = float(np.linalg.norm(np.ptp(points, axis=0))) or 1.0
    _, index = np.unique(np.round(points / (1e-9 * diag)), axis=0, return_inverse=True)
    tri = index.ravel()[faces]
    keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
    return tri[keep]


def mesh_genus(points: np.ndarray, faces: np.ndarray) -> int | None:
    """Genus of a closed triangle mesh from its Euler characteristic (summed over its components), or None when
    it is open or not edge-manifold."""
    tri = _welded(np.asarray(points, dtype=np.float64), np.asarray(faces, dtype=np.int64).reshape(-1, 3))
    if not len(tri):
        return None
    pairs = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    edges, counts = np.unique(pairs, axis=0, return_counts=True)
    if np.any(counts != 2):
        return None
    used = np.unique(tri)
    n = int(used.max()) + 1
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    components = len(np.unique(labels[used]))
    chi = len(used) - len(edges) + len(tri)
    return int(components - chi // 2)


def _surface_samples(points: np.ndarray, faces: np.ndarray | None) -> np.ndarray:
    if faces is None:
        return points
    rng = np.random.default_rng(_SEED)
    a, b, c = (points[faces[:, i]] for i in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if area.sum() <= 0:
        return points
    pick = rng.choice(len(faces), _SAMPLES, p=area / area.sum())
    u, w = rng.random((2, _SAMPLES))
    flip = u + w > 1
    u, w = np.where(flip, 1 - u, u), np.where(flip, 1 - w, w)
    return np.concatenate([points, a[pick] + u[:, None] * (b - a)[pick] + w[:, None] * (c - a)[pick]])


def _cell(samples: np.ndarray, faces: np.ndarray | None, resolution: int) -> float:
    """The voxel side: ``resolution`` cells along the longest axis, but for a cloud no finer than its points'
    spacing (90th percentile of the nearest-neighbour distances), so that one dilation closes the gaps between
    them (a sparse cloud would otherwise count them as holes)."""
    h = float(np.ptp(samples, axis=0).max()) / resolution or 1.0
    if faces is None and len(samples) > 1:
        gap = cKDTree(samples).query(samples, k=2)[0][:, 1]
        h = max(h, float(np.percentile(gap, 90)))
    return h


def voxel_solid(points: np.ndarray, faces: np.ndarray | None = None,
                resolution: int = VOXEL_RESOLUTION) -> np.ndarray:
    """Boolean grid (one cell of padding) of the solid the target bounds: cells holding its points, closed by
    one dilation, cavities filled."""
    samples = _surface_samples(np.asarray(points, dtype=np.float64), faces)
    lo, hi = samples.min(axis=0), samples.max(axis=0)
    h = _cell(samples, faces, resolution)
    shape = np.ceil((hi - lo) / h).astype(int) + 3
    cells = np.floor((samples - lo) / h).astype(int) + 1
    grid = np.zeros(shape, dtype=bool)
    grid[tuple(np.minimum(cells, shape - 2).T)] = True
    grid = ndimage.binary_dilation(grid, structure=ndimage.generate_binary_structure(3, 3))
    return ndimage.binary_fill_holes(grid)


def _euler(solid: np.ndarray) -> int:
    """Euler characteristic of the union of the closed unit cubes of ``solid`` (padded by a free cell)."""
    s = np.pad(solid, 1)

    def any_of(shifts) -> int:  # grid elements touching an occupied cell among the shifted copies
        acc = np.zeros(tuple(n - 1 for n in s.shape), dtype=bool)
        for dx, dy, dz in shifts:
            acc |= s[dx:s.shape[0] - 1 + dx, dy:s.shape[1] - 1 + dy, dz:s.shape[2] - 1 + dz]
        return int(acc.sum())

    corners = [(a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)]
    vertices = any_of(corners)
    edges = sum(any_of([c for c in corners if c[axis] == 0]) for axis in range(3))
    faces = sum(any_of([c for c in corners if c[axis] == 0 and c[(axis + 1) % 3] == 0]) for axis in range(3))
    return vertices - edges + faces - int(s.sum())


def voxel_genus(solid: np.ndarray) -> int:
    """``components - chi`` of a voxel solid without cavities (each component: 1 - its number of tunnels)."""
    _, components = ndimage.label(solid, structure=ndimage.generate_binary_structure(3, 3))
    return int(components - _euler(solid))


def target_genus(target: SurfaceTarget) -> tuple[int, str]:
    """``(genus, method)``: ``"euler"`` for a closed mesh, ``"voxels"`` otherwise (see the module docstring)."""
    if target.faces is not None:
        g = mesh_genus(target.points, target.faces)
        if g is not None:
            return g, "euler"
    return max(voxel_genus(voxel_solid(target.points, target.faces)), 0), "voxels"


def genus_metrics(control: PolyMesh, genus: int, method: str) -> dict[str, Any]:
    """``target_genus``, ``target_genus_method``, ``result_genus`` (of a closed control mesh; None for an open
    one) and, when the two differ, ``genus_warning``."""
    topo = control.topology
    closed = topo.is_closed
    out: dict[str, Any] = {"target_genus": int(genus), "target_genus_method": method,
                           "result_genus": int((2 - topo.euler_characteristic) // 2) if closed else None}
    if closed and out["result_genus"] != out["target_genus"]:
        out["genus_warning"] = (f"the control mesh has genus {out['result_genus']} but the target has genus "
                                f"{out['target_genus']} ({method}): through-holes are missing or extra")
    return out


# --- placing a template ----------------------------------------------------------------------------------------

def _hole_columns(solid: np.ndarray) -> tuple[int, np.ndarray]:
    """The axis of ``solid`` with the most empty columns that its projection surrounds, and that boolean
    projection of the enclosed empty columns (the through-holes seen along it); the axis is -1 when none is."""
    best, axis, holes = 0, -1, np.zeros((1, 1), dtype=bool)
    for k in range(3):
        shadow = solid.any(axis=k)
        empty = ndimage.binary_fill_holes(shadow) & ~shadow
        if empty.sum() > best:
            best, axis, holes = int(empty.sum()), k, empty
    return axis, holes


def hole_axis(target: SurfaceTarget) -> int:
    """The axis the target's through-holes run along: the one with the most empty columns of its voxel solid
    that the solid surrounds (its projection covers them on every side); the thinnest axis when none is."""
    axis, _ = _hole_columns(voxel_solid(target.points, target.faces))
    return axis if axis >= 0 else int(np.argmin(np.ptp(target.points, axis=0)))


HOLE_REACH = 1.04
"""A template hole's control half-width over the target hole's: a 4-sided control hole's limit rim runs about
4 % inside it at its sides (cubic B-spline of a square: 23/24 of the half-width)."""


def target_holes(points: np.ndarray, faces: np.ndarray | None, axis: int, plane: tuple[int, int]
                 ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The through-holes of a target along ``axis`` (its points in the frame they are given in): one ``(centre,
    half-widths)`` per hole, both along the two ``plane`` axes. Holes are the enclosed empty columns of its voxel
    solid seen along ``axis`` (labelled); each one's walls are then found on the points themselves: the nearest
    points beyond its centre along each ``plane`` axis, within a cell of the line through it."""
    points = np.asarray(points, dtype=np.float64)
    solid = voxel_solid(points, faces)
    shadow = solid.any(axis=axis)
    empty = ndimage.binary_fill_holes(shadow) & ~shadow
    labels, count = ndimage.label(empty)
    samples = _surface_samples(points, faces)
    lo = samples.min(axis=0)
    h = _cell(samples, faces, VOXEL_RESOLUTION)
    cell_axes = [k for k in range(3) if k != axis]  # the projection's axes, in order
    flat = samples[:, cell_axes]
    out = []
    for index in range(1, count + 1):
        cells = np.argwhere(labels == index)
        centre = lo[cell_axes] + (cells.mean(axis=0) - 1 + 0.5) * h
        half = np.empty(2)
        for j in range(2):
            other = 1 - j
            band = np.abs(flat[:, other] - centre[other]) <= h
            offsets = flat[band, j] - centre[j]
            above, below = offsets[offsets > 0], -offsets[offsets < 0]
            if not above.size or not below.size:
                break
            a, b = float(above.min()), float(below.min())
            centre[j] += (a - b) / 2.0
            half[j] = (a + b) / 2.0
        else:
            order = [cell_axes.index(k) for k in plane]
            out.append((centre[order], half[order]))
    return out


def _frame(target: SurfaceTarget) -> tuple[np.ndarray, np.ndarray]:
    """Centre and axes (columns) of the box a template is placed on
    (:func:`~gsr_cad.reconstruct.placement.oriented_box`: the principal axes when that box is clearly smaller)."""
    samples = None
    if target.faces is not None and len(target.faces):
        samples = area_samples(target.points, target.faces, 4000, _SEED)
    centre, axes, _, _ = oriented_box(target.points, samples)
    return centre, axes


def _placed_holes(mesh: PolyMesh, unit: np.ndarray, genus: int, holes: list[tuple[np.ndarray, np.ndarray]],
                  x: int, y: int) -> PolyMesh:
    """``mesh`` (the placed :func:`genus_template`, ``unit`` its vertices as built) with each strip's hole rim
    moved onto the target's hole (``holes``: centre and half-widths along ``x``, ``y``, in the row's order) and the
    cuts between strips halfway between neighbouring holes; ``mesh`` itself when the holes do not follow one
    another along ``x`` (side by side across the row)."""
    v = mesh.vertices.copy()
    ux, uy = unit[:, 0] + genus / 2.0, unit[:, 1]
    strip = np.clip(np.floor(ux).astype(int), 0, genus - 1)
    rim = ~np.isclose(ux, np.round(ux))  # the insets' vertices
    outer_x = (v[:, x].min(), v[:, x].max())
    outer_y = (v[:, y].min(), v[:, y].max())
    centres = np.array([c for c, _ in holes])
    halves = np.array([w for _, w in holes]) * HOLE_REACH
    cuts = np.concatenate([[outer_x[0]], (centres[1:, 0] - halves[1:, 0] + centres[:-1, 0] + halves[:-1, 0]) / 2.0,
                           [outer_x[1]]])
    if np.any(centres[:, 0] - halves[:, 0] <= cuts[:-1]) or np.any(centres[:, 0] + halves[:, 0] >= cuts[1:]):
        return mesh  # the holes overlap along the row (not one after another): the even strips stand
    inner_cut = ~rim & (np.round(ux) > 0) & (np.round(ux) < genus)
    v[inner_cut, x] = cuts[np.round(ux[inner_cut]).astype(int)]
    for i in range(genus):
        on = rim & (strip == i)
        side_x = np.sign(ux[on] - (i + 0.5))
        side_y = np.sign(uy[on])
        margin_x = 0.1 * (cuts[i + 1] - cuts[i])
        margin_y = 0.05 * (outer_y[1] - outer_y[0])
        v[on, x] = np.clip(centres[i, 0] + side_x * halves[i, 0], cuts[i] + margin_x, cuts[i + 1] - margin_x)
        v[on, y] = np.clip(centres[i, 1] + side_y * halves[i, 1], outer_y[0] + margin_y, outer_y[1] - margin_y)
    return mesh.with_vertices(v)


def fitted_template(target: SurfaceTarget, genus: int) -> PolyMesh:
    """:func:`genus_template` on the target's box (:func:`_frame`: axis-aligned, or its principal axes when that
    box is clearly smaller), turned so that its holes follow the target's hole axis in that frame and its row the
    longest other axis, scaled and moved so that its level-2 limit surface spans the box. When the target shows
    as many through-holes along that axis as ``genus`` (:func:`target_holes`), each template hole is then moved
    and sized onto one of them (in the row's order) and the strips cut between them, and the whole rescaled to
    the box again."""
    unit_mesh = genus_template(genus)
    centre, axes = _frame(target)
    local = (np.asarray(target.points, dtype=np.float64) - centre) @ axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    extent = hi - lo
    solid = voxel_solid(local, target.faces) if genus else None
    axis = _hole_columns(solid)[0] if genus else -1
    z = axis if axis >= 0 else int(np.argmin(extent))
    others = [k for k in range(3) if k != z]
    x = max(others, key=lambda k: extent[k])
    y = next(k for k in others if k != x)
    v = np.empty_like(unit_mesh.vertices)
    v[:, x], v[:, y], v[:, z] = unit_mesh.vertices[:, 0], unit_mesh.vertices[:, 1], unit_mesh.vertices[:, 2]
    mesh = _spanning(unit_mesh.with_vertices(v), lo, hi)
    bored = _bored_box(local, target.faces, lo, hi) if genus == 5 else None
    if bored is not None:
        mesh = bored
    elif genus:
        holes = sorted(target_holes(local, target.faces, z, (x, y)), key=lambda hole: hole[0][0])
        if len(holes) == genus:
            mesh = _spanning(_placed_holes(mesh, unit_mesh.vertices, genus, holes, x, y), lo, hi)
    return mesh.with_vertices(mesh.vertices @ axes.T + centre)


def _bored_box(local: np.ndarray, faces: np.ndarray | None, lo: np.ndarray, hi: np.ndarray) -> PolyMesh | None:
    """The :func:`window_box` of a target (points ``local`` in its box frame, box ``lo``-``hi``) bored along all
    three axes, one through-hole seen along each (:func:`target_holes`), else None: windows sized to the holes
    (``HOLE_REACH``), the cavity a quarter wider than the widest window across it, the outer walls spanning the
    box (the limit surface, as :func:`_spanning`)."""
    windows = np.empty((3, 2))
    for k in range(3):
        holes = target_holes(local, faces, k, ((k + 1) % 3, (k + 2) % 3))
        if len(holes) != 1 or np.any(np.abs(holes[0][0]) > 0.25 * (hi - lo)[[(k + 1) % 3, (k + 2) % 3]]):
            return None  # not one central hole along this axis
        windows[k] = holes[0][1] * HOLE_REACH
    outer = (hi - lo) / 2.0
    across = np.zeros(3)  # the widest window half-width along each axis
    for k in range(3):
        across[(k + 1) % 3] = max(across[(k + 1) % 3], windows[k, 0])
        across[(k + 2) % 3] = max(across[(k + 2) % 3], windows[k, 1])
    inner = np.minimum(1.25 * across, 0.8 * outer)
    for k in range(3):
        windows[k] = np.minimum(windows[k], 0.85 * inner[[(k + 1) % 3, (k + 2) % 3]])
    mesh = window_box(outer, inner, windows)
    for _ in range(2):  # the outer walls spanning the box, the cavity and windows kept
        spanned = _spanning(mesh, lo - (lo + hi) / 2.0, hi - (lo + hi) / 2.0)
        mesh = window_box(np.ptp(spanned.vertices, axis=0) / 2.0, inner, windows)
    return _spanning(mesh, lo, hi)


def _spanning(mesh: PolyMesh, lo: np.ndarray, hi: np.ndarray) -> PolyMesh:
    """``mesh`` scaled per axis and moved so that its level-2 limit surface spans the box ``lo``-``hi``."""
    v = mesh.vertices
    limit = get_catmull_clark(mesh, 2).limit_matrix @ v
    llo, lhi = limit.min(axis=0), limit.max(axis=0)
    extent = hi - lo
    size = np.maximum(extent, 1e-6 * float(extent.max()))
    factor = size / np.maximum(lhi - llo, 1e-12)
    return mesh.with_vertices((v - (llo + lhi) / 2.0) * factor + (lo + hi) / 2.0)


# --- feature-driven starts --------------------------------------------------------------------------------------

GREEDY_GAIN = 0.98
"""A greedy step is kept when it lowers the cost below this fraction of the current one."""
GREEDY_STEPS = 8
"""Greedy steps at most (each adds one op, or one crease per proposed edge)."""
GREEDY_EVALUATIONS = 60
"""Candidate genomes scored at most, over all steps."""
GREEDY_CANDIDATES = 6
"""Proposed faces (R) and edges (C) tried per greedy step, nearest to the feature lines first."""


def _ring_representatives(mesh: PolyMesh) -> list[int]:
    """One edge (op index) per distinct ring of opposite edges that an edge loop (L) could cut."""
    return [e for e, _, _ in distinct_rings(mesh_view(mesh).conn)]


def _op_edges(mesh: PolyMesh, topology_edges: list[int]) -> list[int]:
    """Topology edge indices as the ops number edges (by vertex pair)."""
    conn = mesh_view(mesh).conn
    pairs = mesh.topology.edges[np.asarray(topology_edges, dtype=np.int64)].tolist() if topology_edges else []
    return [conn.edge_id[(min(a, b), max(a, b))] for a, b in pairs if (min(a, b), max(a, b)) in conn.edge_id]


def feature_genomes(template: PolyMesh, proposals: CreaseProposals,
                    score: Callable[[tuple], tuple[float, PolyMesh | None]], kinds: str, seconds: float | None = None,
                    steps: int = GREEDY_STEPS, evaluations: int = GREEDY_EVALUATIONS) -> list[tuple]:
    """Starts for the search built greedily from the target's feature lines: from ``template``, each step
    tries an infinitely sharp rim crease (R) on each proposed face, an infinitely sharp crease (C) on each
    proposed edge and on all of them at once, and an edge loop (L) across each distinct edge ring (the
    letters in ``kinds`` only), and keeps the ops whose genome ``score`` likes best while it gains
    (``GREEDY_GAIN``), for at most ``steps`` steps, ``evaluations`` scored candidates and ``seconds`` (None:
    no time limit, the result then depends on the inputs alone). ``score(genome)`` is the search's cost and the
    control mesh after its polish (None when the genome fails), on which the next step's edges are proposed.
    Returns the genomes of the steps kept, longest first (empty when none gains)."""
    started = time.perf_counter()
    deadline = math.inf if seconds is None else started + seconds
    genome: tuple = ()
    best, polished = score(())
    mesh = template
    kept: list[tuple] = []
    while len(kept) < steps and time.perf_counter() < deadline:
        candidates: list[tuple] = []
        if "R" in kinds:
            candidates += [(CreaseRim(f, SHARPNESS_INFINITE),) for f in proposals.faces(polished or mesh)
                           [:GREEDY_CANDIDATES]]
        if "C" in kinds:
            open_edges = [e for e in proposals.edges(polished or mesh) if mesh.edge_sharpness[e] < SHARPNESS_INFINITE]
            creases = [Crease(e, SHARPNESS_INFINITE) for e in _op_edges(mesh, open_edges)]
            candidates += [(op,) for op in creases[:GREEDY_CANDIDATES]]
            if len(creases) > 1:
                candidates.append(tuple(creases))
        if "L" in kinds:
            candidates += [(EdgeLoop(e),) for e in _ring_representatives(mesh)]
        step = None
        for ops in candidates:
            if time.perf_counter() > deadline or evaluations <= 0:
                break
            try:
                nxt = mesh
                for op in ops:
                    nxt = op.apply(nxt)
            except GsrError:
                continue
            if nxt.creases == mesh.creases and nxt.n_vertices == mesh.n_vertices:
                continue  # creases already there
            evaluations -= 1
            cost, after = score(genome + ops)
            if cost < GREEDY_GAIN * best and (step is None or cost < step[0]):
                step = (cost, ops, nxt, after)
        if step is None:
            break
        best, ops, mesh, polished = step
        genome += ops
        kept.append(genome)
    return kept[::-1]
