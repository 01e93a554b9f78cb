"""The seven surface modelling ops as pure functions ``PolyMesh -> PolyMesh`` (see :mod:`gsr_cad.ops.mesh`).

Each function validates its element reference and parameters, builds the new vertex list and face
cycles in the documented order with plain Python (small meshes), checks the faces it touched and
raises :class:`~gsr_cad.errors.OpError` when the result would be invalid. The checks are local: every
touched face keeps edges of at least ``MIN_EDGE_REL`` times the mesh diagonal, a non-negligible area,
stays star-shaped about its centroid (no bow-tie or folded polygon), keeps the orientation of the face
it came from (no flip), and meets each neighbour at an opening angle above ``FOLD_DEG`` (no fin or
folded-back sheet). Intersections between faces that share no edge are not looked for.

Replays run these thousands of times, so each op works on the :class:`~gsr_cad.ops.mesh_conn.MeshView` of
its input (plain-float positions, the Newell vectors already known, the connectivity) and hands one on to
the next op; every number that decides validity or geometry is computed with exactly the same float
operations, in the same order, as a fresh computation would be.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from ..errors import OpError
from ..geometry.polymesh import SHARPNESS_INFINITE, Creases, PolyMesh, sorted_creases
from .mesh_conn import (MeshConn, MeshView, cache_connectivity, cached_connectivity, face_arrays, mesh_view,
                        remember_view)

MIN_EDGE_REL = 1e-4
"""Shortest allowed edge, as a fraction of the mesh's bounding-box diagonal."""
MIN_AREA_REL = 1e-8
"""Smallest allowed face area, as a fraction of the squared diagonal."""
FAN_MIN_FRAC = 1e-3
"""Each centroid-fan triangle of a face must hold at least this share of the face's mean fan area."""
FOLD_DEG = 2.0
"""Smallest opening angle (degrees) between two faces sharing an edge."""
BEVEL_MIN_DEG = 15.0
"""Bevel needs every corner between the bevelled edge and its neighbours in ``[15, 165]`` degrees,
clearly convex: Blender switches to other constructions near 0 and 180 degrees and on reflex corners."""
INSET_MIN_DEG = 15.0
"""Inset needs every corner of the face in ``[15, 345]`` degrees: at a spike the inner vertex runs off
by ``thickness / sin(angle / 2)`` and single-precision replays drift."""

CONVEX_SIN = math.sin(math.radians(3.0))
"""With a margin, :func:`unsound_faces` wants every corner to turn by at least this sine (clearly convex)."""
_FOLD_COS = math.cos(math.radians(FOLD_DEG))
_BEVEL_MIN_SIN = math.sin(math.radians(BEVEL_MIN_DEG))
_INSET_MIN_COS = math.sin(math.radians(INSET_MIN_DEG / 2))

Vec = tuple[float, float, float]


# --- small vector helpers on tuples (faster than numpy for a handful of points) -------------------------

def _sub(p: Sequence[float], q: Sequence[float]) -> Vec:
    return (p[0] - q[0], p[1] - q[1], p[2] - q[2])


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: Sequence[float]) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _unit(a: Sequence[float]) -> Vec | None:
    n = _norm(a)
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0.0 else None


def _newell(P: list[list[float]], cyc: Sequence[int]) -> Vec:
    """Newell area vector of a face (twice its vector area), the same as PolyMesh.face_newell."""
    nx = ny = nz = 0.0
    px, py, pz = P[cyc[-1]]
    for i in cyc:
        qx, qy, qz = P[i]
        nx += (py - qy) * (pz + qz)
        ny += (pz - qz) * (px + qx)
        nz += (px - qx) * (py + qy)
        px, py, pz = qx, qy, qz
    return (nx, ny, nz)


def _bounds(P: Sequence[Sequence[float]]) -> tuple[float, ...]:
    """``(xmin, ymin, zmin, xmax, ymax, zmax)`` of the points."""
    xs, ys, zs = zip(*P)
    return (min(xs), min(ys), min(zs), max(xs), max(ys), max(zs))


def _extended(bounds: tuple[float, ...] | None, pts: list[list[float]]) -> tuple[float, ...] | None:
    """Bounds after appending ``pts``: equal to :func:`_bounds` of the longer list (min and max are exact)."""
    if bounds is None:
        return None
    xs, ys, zs = zip(*pts)
    return (min(bounds[0], *xs), min(bounds[1], *ys), min(bounds[2], *zs),
            max(bounds[3], *xs), max(bounds[4], *ys), max(bounds[5], *zs))


def _diagonal(view: MeshView) -> float:
    """Bounding-box diagonal of the view's positions (bounds memoised in the view)."""
    b = view.bounds
    if b is None:
        b = view.bounds = _bounds(view.P)
    return math.sqrt((b[3] - b[0]) ** 2 + (b[4] - b[1]) ** 2 + (b[5] - b[2]) ** 2)


def _face_newell(view: MeshView, f: int) -> Vec:
    """Newell vector of face ``f`` of the view's mesh, as :func:`_newell` computes it (memoised in the view)."""
    n = view.newell[f]
    if n is None:
        n = view.newell[f] = _newell(view.P, view.conn.faces[f])
    return n


# --- validity ------------------------------------------------------------------------------------------

def _check(what: str, P: list[list[float]], conn: MeshConn, touched: Iterable[int], refs: dict[int, Vec | None],
           diag: float, newell: list) -> None:
    """Raise OpError unless every touched face of the new mesh (positions ``P``, connectivity ``conn``) is
    sound (see the module docstring).

    ``refs`` maps a face to the unit normal it must not flip against (the face it came from). ``newell``
    is the new mesh's list of Newell vectors: set entries of untouched faces must be right (their cycle and
    vertices did not change); the touched faces' entries are (re)computed here, neighbours' filled in when
    missing. The arithmetic is written out on floats: this runs once per op in every GA replay.
    """
    faces = conn.faces
    min_len2 = (MIN_EDGE_REL * diag) ** 2
    min_area2 = 2.0 * MIN_AREA_REL * diag * diag
    min_area4 = min_area2 * min_area2
    length: dict[int, float] = {}
    touched = list(touched)
    for f in touched:
        pts = [P[c] for c in faces[f]]
        k = len(pts)
        nx = ny = nz = sx = sy = sz = 0.0
        px, py, pz = pts[-1]
        for qx, qy, qz in pts:
            nx += (py - qy) * (pz + qz)
            ny += (pz - qz) * (px + qx)
            nz += (px - qx) * (py + qy)
            sx += qx
            sy += qy
            sz += qz
            ex, ey, ez = qx - px, qy - py, qz - pz
            if ex * ex + ey * ey + ez * ez < min_len2:
                raise OpError(f"{what}: face {f} would get a (nearly) zero-length edge")
            px, py, pz = qx, qy, qz
        n2 = nx * nx + ny * ny + nz * nz
        if n2 < min_area4:
            raise OpError(f"{what}: face {f} would have (nearly) zero area")
        newell[f] = (nx, ny, nz)
        length[f] = math.sqrt(n2)
        # centroid fan: each triangle (c, p, q) must turn the same way as the face, by a margin
        fan_min = FAN_MIN_FRAC * n2 / k
        cx, cy, cz = sx / k, sy / k, sz / k
        px, py, pz = pts[-1]
        ax, ay, az = px - cx, py - cy, pz - cz
        for qx, qy, qz in pts:
            bx, by, bz = qx - cx, qy - cy, qz - cz
            if (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz < fan_min:
                raise OpError(f"{what}: face {f} would fold over itself")
            ax, ay, az = bx, by, bz
        ref = refs.get(f)
        if ref is not None and nx * ref[0] + ny * ref[1] + nz * ref[2] <= 0.0:
            raise OpError(f"{what}: face {f} would flip")
    half = conn.half
    for f in touched:
        cyc = faces[f]
        fx, fy, fz = newell[f]
        threshold = -_FOLD_COS * length[f]
        for u, v in zip(cyc, cyc[1:] + cyc[:1]):
            g = half.get((v, u), -1)
            if g < 0:
                continue
            ng = newell[g]
            if ng is None:
                ng = newell[g] = _newell(P, faces[g])
            lg = length.get(g)
            if lg is None:
                lg = length[g] = math.sqrt(ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2])
            if fx * ng[0] + fy * ng[1] + fz * ng[2] < threshold * lg:
                raise OpError(f"{what}: faces {f} and {g} would fold onto each other")


def unsound_faces(mesh: PolyMesh, reference_normals: np.ndarray, margin: float = 1.0,
                   convex: bool = True) -> np.ndarray:
    """Per face, True when it fails the mesh ops' own checks (:func:`_check`), for every face at once: a (nearly)
    zero-length edge or zero area, not star-shaped about its centroid, flipped against
    ``reference_normals`` or folded onto a neighbour; with ``margin`` > 1, that many times stricter on edge
    lengths, areas and star shapes and convex at every corner (by ``CONVEX_SIN``), so that the vertex
    moves to the mesh replay one by one through the states between and the structural ops apply to it
    (``convex`` False: corners may turn concave, for a cage no op will be applied to)."""
    diag = mesh.diagonal
    newell = mesh.face_newell
    twice_area = np.linalg.norm(newell, axis=1)
    bad = twice_area < 2.0 * margin * MIN_AREA_REL * diag * diag
    normal = newell / np.maximum(twice_area, 1e-300)[:, None]
    bad |= np.einsum("ij,ij->i", normal, reference_normals) <= 0.0
    topo = mesh.topology
    v = mesh.vertices
    p, q = v[topo.he_origin], v[topo.he_dest]
    c = mesh.face_centroids[topo.he_face]
    fan = np.einsum("ij,ij->i", np.cross(p - c, q - c), normal[topo.he_face])
    he_bad = ((np.einsum("ij,ij->i", q - p, q - p) < (margin * MIN_EDGE_REL * diag) ** 2)
              | (fan < margin * FAN_MIN_FRAC * (twice_area / mesh.face_sizes)[topo.he_face]))
    if margin > 1.0 and convex:  # and every corner clearly convex: the ops (an edge loop's halves, an inset) then apply
        r = v[topo.he_dest[topo.he_next]] - q
        turn = np.einsum("ij,ij->i", np.cross(q - p, r), normal[topo.he_face])
        he_bad |= turn < CONVEX_SIN * np.linalg.norm(q - p, axis=1) * np.linalg.norm(r, axis=1)
    bad[topo.he_face[he_bad]] = True
    inner = topo.edge_faces[:, 1] >= 0
    f, g = topo.edge_faces[inner, 0], topo.edge_faces[inner, 1]
    fold = np.einsum("ij,ij->i", normal[f], normal[g]) < -math.cos(math.radians(FOLD_DEG))
    bad[f[fold]] = True
    bad[g[fold]] = True
    return bad


def _index(value: int, count: int, what: str, kind: str) -> int:
    if not 0 <= value < count:
        raise OpError(f"{what}: {kind} {value} does not exist (the mesh has {count})")
    return value


def _moved(view: MeshView, P: list[list[float]], moved: Iterable[int], newell: list) -> PolyMesh:
    """The input mesh with the ``moved`` rows of ``P``: same connectivity, topology and key."""
    mesh = view.mesh
    moved = tuple(moved)
    vertices = mesh.vertices.copy()
    for c in moved:
        vertices[c] = P[c]
    vertices.setflags(write=False)
    out = PolyMesh._trusted(vertices, mesh.corners, mesh.offsets, mesh._topology, mesh.connectivity_key,
                            mesh._creases)
    remember_view(MeshView(out, P, newell, view.conn, _moved_bounds(view, P, moved)))
    return out


def _moved_bounds(view: MeshView, P: list[list[float]], moved: tuple[int, ...]) -> tuple[float, ...] | None:
    """The bounds after moving the ``moved`` rows, when known without a full pass: every old position was strictly
    inside the old bounds (so none of them set a min or max), and the new ones extend them exactly; None
    (computed again when needed) otherwise. A cage's vertex moves are most often inside."""
    b = view.bounds
    if b is None:
        return None
    for c in moved:
        x, y, z = view.P[c]
        if not (b[0] < x < b[3] and b[1] < y < b[4] and b[2] < z < b[5]):
            return None
    return _extended(b, [P[c] for c in moved])


def _carried(mesh: PolyMesh, conn: MeshConn, inherit: dict[tuple[int, int], tuple[int, int]],
             drop: tuple[int, int] | None) -> Creases | None:
    """The creases of an op's result: every creased vertex pair of ``mesh`` that is still an edge of ``conn``
    keeps its sharpness (old vertices keep their indices), except ``drop``; each new edge in ``inherit``
    (``new pair -> old pair``) takes the sharpness of its old pair."""
    old = mesh.creases
    half = conn.half
    out = {p: s for p, s in old.items() if p != drop and (p in half or p[::-1] in half)}
    for new, src in inherit.items():
        s = old.get(src if src[0] < src[1] else src[::-1])
        if s and (new in half or new[::-1] in half):
            out[new] = s
    if not out:
        return None
    return sorted_creases(np.array(list(out), dtype=np.int64), np.array(list(out.values())))


def _finish(what: str, view: MeshView, P: list[list[float]], faces: list[tuple[int, ...]], touched: list[int],
            refs: dict[int, Vec | None], diag: float, newell: list, moved: Iterable[int] = (),
            bounds: tuple[float, ...] | None = None, inherit: dict[tuple[int, int], tuple[int, int]] | None = None,
            drop: tuple[int, int] | None = None) -> PolyMesh:
    """Check and build the result of an op that changed the ``touched`` faces (and appended vertices).

    The connectivity comes from the cache when this face list was met before, else the input's is
    patched. Op results need no validation: every face keeps at least three corners, all on vertices of
    ``P``, by construction. Creases are carried by :func:`_carried` (``inherit``, ``drop``).
    """
    corners, offsets, key = face_arrays(len(P), faces)
    conn = cached_connectivity(key)
    fresh = conn is None
    if fresh:
        conn = MeshConn.updated(view.conn, faces, touched, len(P))
    _check(what, P, conn, touched, refs, diag, newell)
    if fresh:
        cache_connectivity(key, conn)
    old = view.mesh.vertices
    n = len(old)
    vertices = np.empty((len(P), 3))
    vertices[:n] = old
    if len(P) > n:
        vertices[n:] = P[n:]
    for c in moved:
        vertices[c] = P[c]
    vertices.setflags(write=False)
    creases = None if view.mesh._creases is None else _carried(view.mesh, conn, inherit or {}, drop)
    out = PolyMesh._trusted(vertices, corners, offsets, None, key, creases)
    remember_view(MeshView(out, P, newell, conn, bounds))
    return out


# --- V, F, S: vertex moves -----------------------------------------------------------------------------

def translate_vertex(mesh: PolyMesh, vertex: int, delta: Sequence[float]) -> PolyMesh:
    """V: move one vertex by ``delta``."""
    what = f"translate_vertex {vertex}"
    view = mesh_view(mesh)
    conn = view.conn
    _index(vertex, mesh.n_vertices, what, "vertex")
    around = conn.vertex_faces(vertex)
    if not around:
        raise OpError(f"{what}: vertex {vertex} is on no face")
    diag = _diagonal(view)
    refs = {f: _unit(_face_newell(view, f)) for f in around}
    P = list(view.P)
    p = P[vertex]
    P[vertex] = [p[0] + delta[0], p[1] + delta[1], p[2] + delta[2]]
    newell = list(view.newell)
    _check(what, P, conn, around, refs, diag, newell)
    return _moved(view, P, (vertex,), newell)


def _face_op(mesh: PolyMesh, face: int, what: str) -> tuple[MeshView, tuple[int, ...], Vec]:
    """The view of ``mesh``, the cycle of ``face`` and its unit normal, for the ops on one face (F, E, I)."""
    view = mesh_view(mesh)
    conn = view.conn
    cyc = conn.faces[_index(face, conn.n_faces, what, "face")]
    n = _unit(_face_newell(view, face))
    if n is None:
        raise OpError(f"{what}: face {face} has zero area")
    return view, cyc, n


def translate_face(mesh: PolyMesh, face: int, distance: float) -> PolyMesh:
    """F: move a face's vertices by ``distance`` along its unit Newell normal."""
    what = f"translate_face {face}"
    view, cyc, n = _face_op(mesh, face, what)
    conn = view.conn
    around = sorted({g for c in cyc for g in conn.vertex_faces(c)})
    refs = {g: _unit(_face_newell(view, g)) for g in around}
    P = list(view.P)
    dx, dy, dz = n[0] * distance, n[1] * distance, n[2] * distance
    for c in cyc:
        p = P[c]
        P[c] = [p[0] + dx, p[1] + dy, p[2] + dz]
    newell = list(view.newell)
    _check(what, P, conn, around, refs, _diagonal(view), newell)
    return _moved(view, P, cyc, newell)


def scale(mesh: PolyMesh, factor: float) -> PolyMesh:
    """S: scale every vertex by ``factor > 0`` about the centre of the bounding box.

    No face is checked, and none needs to be: scaling by ``factor > 0`` about a point is a similarity, so
    every edge length and the diagonal change by ``factor``, every Newell vector and area by ``factor**2``
    without turning, and centroids map to centroids. Each rule of :func:`_check` compares quantities of the
    same degree (edge**2 with diagonal**2, area**2 with diagonal**4, fan areas with the face area, normal
    dot products with products of lengths), so the factor cancels: a valid mesh stays valid.
    """
    if not factor > 0.0:
        raise OpError(f"scale {factor}: the factor must be positive")
    centre = mesh.bbox.mean(axis=0)
    vertices = centre + factor * (mesh.vertices - centre)
    vertices.setflags(write=False)
    return PolyMesh._trusted(vertices, mesh.corners, mesh.offsets, mesh._topology, mesh.connectivity_key,
                             mesh._creases)


def bbox_centre(mesh: PolyMesh) -> tuple[float, float, float]:
    """The pivot of :func:`scale` (centre of the bounding box) as plain floats."""
    c = mesh.bbox.mean(axis=0)
    return (float(c[0]), float(c[1]), float(c[2]))


# --- C: crease ------------------------------------------------------------------------------------------

def _with_sharpness(view: MeshView, pairs: list[tuple[int, int]], sharpness: float) -> PolyMesh:
    """The view's mesh with ``sharpness`` on the sorted vertex ``pairs`` (same positions and connectivity)."""
    mesh = view.mesh
    creases = mesh.creases
    creases.update(dict.fromkeys(pairs, sharpness))
    new = sorted_creases(np.array(list(creases), dtype=np.int64), np.array(list(creases.values())))
    out = PolyMesh._trusted(mesh.vertices, mesh.corners, mesh.offsets, mesh._topology, mesh.connectivity_key, new)
    remember_view(MeshView(out, view.P, view.newell, view.conn, view.bounds))
    return out


def _check_sharpness(what: str, sharpness: float) -> None:
    if not 0.0 <= sharpness <= SHARPNESS_INFINITE:
        raise OpError(f"{what}: the sharpness must lie in [0, {SHARPNESS_INFINITE:g}], got {sharpness!r}")


def crease(mesh: PolyMesh, edge: int, sharpness: float) -> PolyMesh:
    """C: set the sharpness of interior edge ``edge`` (``0`` smooth, ``10`` infinitely sharp; OpenSubdiv's
    meaning). Positions and connectivity stay; a boundary edge (always sharp) is refused."""
    what = f"crease {edge}"
    _check_sharpness(what, sharpness)
    view = mesh_view(mesh)
    conn = view.conn
    _index(edge, len(conn.edges), what, "edge")
    u, v = conn.edges[edge]
    if (v, u) not in conn.half:
        raise OpError(f"{what}: the edge is on the boundary (always sharp)")
    return _with_sharpness(view, [(u, v) if u < v else (v, u)], sharpness)


def crease_rim(mesh: PolyMesh, face: int, sharpness: float) -> PolyMesh:
    """R: set the sharpness of every interior edge of face ``face``'s rim (Blender: select the face, set the
    crease of its edges). A face with no interior edge is refused."""
    what = f"crease_rim {face}"
    _check_sharpness(what, sharpness)
    view = mesh_view(mesh)
    conn = view.conn
    cyc = conn.faces[_index(face, conn.n_faces, what, "face")]
    pairs = [(u, v) if u < v else (v, u) for u, v in zip(cyc, cyc[1:] + cyc[:1]) if (v, u) in conn.half]
    if not pairs:
        raise OpError(f"{what}: the face has no interior edge")
    return _with_sharpness(view, pairs, sharpness)


# --- H: hole ---------------------------------------------------------------------------------------------

def facing(view: MeshView, face_a: int, face_b: int) -> bool:
    """Whether faces ``a`` and ``b`` of the view's mesh face each other across the solid: each lies behind
    the other (``n_a . (c_b - c_a) < 0 < n_b . (c_b - c_a)``) and their normals are opposed (dot < -0.5)."""
    faces = view.conn.faces
    na, nb = _unit(_face_newell(view, face_a)), _unit(_face_newell(view, face_b))
    if na is None or nb is None:
        return False
    P = view.P
    ca = [sum(P[c][j] for c in faces[face_a]) / len(faces[face_a]) for j in range(3)]
    cb = [sum(P[c][j] for c in faces[face_b]) / len(faces[face_b]) for j in range(3)]
    d = _sub(cb, ca)
    return _dot(na, d) < 0.0 < _dot(nb, d) and _dot(na, nb) < -0.5


def hole(mesh: PolyMesh, face_a: int, face_b: int) -> PolyMesh:
    """H: a through-hole: faces ``a`` and ``b`` (facing each other, as many corners, no shared vertex) are
    removed and their rims bridged by quads (Blender's bridge edge loops between the two faces).

    Corner ``i`` of ``a`` pairs with corner ``r - i`` of ``b`` (``b`` runs the other way round the tunnel),
    ``r`` the rotation with the least sum of squared distances between paired corners (the first on ties);
    bridge quad ``i`` is ``(a_i, a_{i+1}, b_{r-i-1}, b_{r-i})``. Quad 0 takes face ``a``'s index, quad 1 face
    ``b``'s, the others are appended in order; vertices keep their indices. The genus grows by one.
    """
    what = f"hole {face_a} {face_b}"
    view = mesh_view(mesh)
    conn = view.conn
    _index(face_a, conn.n_faces, what, "face")
    _index(face_b, conn.n_faces, what, "face")
    A, B = conn.faces[face_a], conn.faces[face_b]
    k = len(A)
    if face_a == face_b or len(B) != k or set(A) & set(B):
        raise OpError(f"{what}: the faces must differ, have as many corners and share no vertex")
    if not facing(view, face_a, face_b):
        raise OpError(f"{what}: the faces do not face each other across the solid")
    P = view.P

    def cost(r: int) -> float:
        return sum(sum((P[A[i]][j] - P[B[(r - i) % k]][j]) ** 2 for j in range(3)) for i in range(k))

    r = min(range(k), key=cost)
    quads = [(A[i], A[(i + 1) % k], B[(r - i - 1) % k], B[(r - i) % k]) for i in range(k)]
    half = conn.half
    for i in range(k):
        u, v = A[i], B[(r - i) % k]
        if (u, v) in half or (v, u) in half:
            raise OpError(f"{what}: vertices {u} and {v} are already joined by an edge")
    faces = list(conn.faces)
    faces[face_a], faces[face_b] = quads[0], quads[1]
    faces.extend(quads[2:])
    touched = [face_a, face_b, *range(conn.n_faces, conn.n_faces + k - 2)]
    newell = view.newell + [None] * (k - 2)
    newell[face_a] = newell[face_b] = None
    return _finish(what, view, list(P), faces, touched, {}, _diagonal(view), newell, (), view.bounds)


# --- E, I: a face on new vertices plus a ring of quads -----------------------------------------------------

def _cap_and_ring(what: str, view: MeshView, face: int, new_points: list[list[float]], ref: Vec | None,
                  cap_creases: bool) -> PolyMesh:
    """E and I: ``face`` moved onto the appended ``new_points``, joined to its old rim by one quad per edge
    (checked; ``ref``, when given, is the normal the new faces must not flip against). The old rim keeps its
    creases; with ``cap_creases`` each new cap edge takes the sharpness of the rim edge it came from."""
    cyc = view.conn.faces[face]
    k = len(cyc)
    base = len(view.P)
    diag = _diagonal(view)
    new = tuple(range(base, base + k))
    faces = list(view.conn.faces)
    faces[face] = new
    first = len(faces)
    faces.extend((cyc[i], cyc[(i + 1) % k], new[(i + 1) % k], new[i]) for i in range(k))
    touched = [face, *range(first, first + k)]
    refs = {} if ref is None else dict.fromkeys(touched, ref)
    inherit = None
    if cap_creases and view.mesh._creases is not None:
        inherit = {(new[i], new[(i + 1) % k]): (cyc[i], cyc[(i + 1) % k]) for i in range(k)}
    return _finish(what, view, view.P + new_points, faces, touched, refs, diag, view.newell + [None] * k, (),
                   _extended(view.bounds, new_points), inherit)


def extrude(mesh: PolyMesh, face: int, distance: float) -> PolyMesh:
    """E: move ``face`` to new vertices ``distance`` along its normal, joined to the old rim by quads."""
    what = f"extrude {face}"
    view, cyc, n = _face_op(mesh, face, what)
    P = view.P
    dx, dy, dz = n[0] * distance, n[1] * distance, n[2] * distance
    return _cap_and_ring(what, view, face, [[P[c][0] + dx, P[c][1] + dy, P[c][2] + dz] for c in cyc], None, True)


def inset_points(P: list[list[float]], cyc: Sequence[int], thickness: float, n: Vec,
                 what: str = "inset") -> list[list[float]]:
    """Blender's ``inset_individual`` with even offset: each corner moves along the bisector of the inward
    edge tangents ``n x edge`` so that both adjacent inner edges lie ``thickness`` from the outer ones."""
    k = len(cyc)
    tangents = []
    for i in range(k):
        t = _unit(_cross(n, _sub(P[cyc[(i + 1) % k]], P[cyc[i]])))
        if t is None:
            raise OpError(f"{what}: an edge is parallel to the face normal")
        tangents.append(t)
    out = []
    for i in range(k):
        a, b = tangents[i - 1], tangents[i]
        m = _unit((a[0] + b[0], a[1] + b[1], a[2] + b[2]))
        cos_half = _dot(m, a) if m is not None else 0.0  # sin(corner angle / 2)
        if cos_half < _INSET_MIN_COS:
            raise OpError(f"{what}: corner {i} of the face is a spike (under {INSET_MIN_DEG:g} degrees)")
        s = thickness / cos_half
        p = P[cyc[i]]
        out.append([p[0] + s * m[0], p[1] + s * m[1], p[2] + s * m[2]])
    return out


def inset(mesh: PolyMesh, face: int, thickness: float) -> PolyMesh:
    """I: shrink ``face`` onto new inner vertices, every inner edge ``thickness`` from its outer edge."""
    what = f"inset {face}"
    if not thickness > 0.0:
        raise OpError(f"{what}: the thickness must be positive")
    view, cyc, n = _face_op(mesh, face, what)
    return _cap_and_ring(what, view, face, inset_points(view.P, cyc, thickness, n, what), n, False)


# --- X, N: a region of faces moved onto new rim vertices, joined by a ring of quads -------------------------

def region_rim(view: MeshView, faces: Sequence[int], what: str) -> tuple[list[tuple[int, int]], list[int], Vec]:
    """Check that ``faces`` is a region the region ops accept and describe its rim.

    A region is a non-empty, edge-connected set of faces that is not the whole surface, touches no boundary of
    the mesh, and meets each of its rim vertices in one fan of faces (no two regions touching at a corner).
    Returns ``(rim half-edges (u, v) of the region's faces in the order met walking the faces in the given order
    and their corners, rim vertices in order of first appearance in that walk, the unit sum of the faces' Newell
    vectors)``.
    """
    conn = view.conn
    if not faces:
        raise OpError(f"{what}: the region has no face")
    inside = set()
    for f in faces:
        inside.add(_index(f, conn.n_faces, what, "face"))
    if len(inside) != len(faces):
        raise OpError(f"{what}: a face is listed twice")
    half = conn.half
    rim: list[tuple[int, int]] = []
    links: dict[int, list[int]] = {f: [] for f in faces}
    for f in faces:
        cyc = conn.faces[f]
        for u, v in zip(cyc, cyc[1:] + cyc[:1]):
            g = half.get((v, u), -1)
            if g < 0:
                raise OpError(f"{what}: face {f} is on the boundary of the mesh")
            if g in inside:
                links[f].append(g)
            else:
                rim.append((u, v))
    if not rim:
        raise OpError(f"{what}: the region is the whole surface")
    seen, todo = {faces[0]}, [faces[0]]
    while todo:
        for g in links[todo.pop()]:
            if g not in seen:
                seen.add(g)
                todo.append(g)
    if len(seen) != len(faces):
        raise OpError(f"{what}: the region's faces are not joined by edges")
    starts = [u for u, _ in rim]
    if len(set(starts)) != len(starts):
        raise OpError(f"{what}: the region meets itself at a vertex")
    on_rim = set(starts)
    rim_vertices = list(dict.fromkeys(c for f in faces for c in conn.faces[f] if c in on_rim))
    return rim, rim_vertices, _mean_normal(view, faces, f"{what}: the region's faces have no mean normal")


def _mean_normal(view: MeshView, faces: Iterable[int], error: str) -> Vec:
    """The unit sum of the Newell vectors of ``faces``; OpError with ``error`` when it is zero."""
    sx = sy = sz = 0.0
    for f in faces:
        nx, ny, nz = _face_newell(view, f)
        sx, sy, sz = sx + nx, sy + ny, sz + nz
    n = _unit((sx, sy, sz))
    if n is None:
        raise OpError(error)
    return n


def _region_result(what: str, view: MeshView, faces: Sequence[int], rim: list[tuple[int, int]],
                   rim_vertices: list[int], P: list[list[float]], new_points: list[list[float]],
                   refs: dict[int, Vec | None], moved: tuple[int, ...], cap_creases: bool) -> PolyMesh:
    """The region's faces on the appended rim vertices (``new_points``, in ``rim_vertices`` order), one quad
    ``(u, v, v', u')`` per rim half-edge appended in rim order; checked and built by :func:`_finish`."""
    conn = view.conn
    base = len(P)
    copy = {v: base + j for j, v in enumerate(rim_vertices)}
    out = list(conn.faces)
    for f in faces:
        out[f] = tuple(copy.get(c, c) for c in conn.faces[f])
    first = len(out)
    out.extend((u, v, copy[v], copy[u]) for u, v in rim)
    touched = [*faces, *range(first, first + len(rim))]
    newell = view.newell + [None] * len(rim)
    for f in faces:
        newell[f] = None
    inherit = None
    if cap_creases and view.mesh._creases is not None:
        inherit = {}
        for f in faces:
            cyc = conn.faces[f]
            for u, v in zip(cyc, cyc[1:] + cyc[:1]):
                if u in copy or v in copy:
                    inherit[(copy.get(u, u), copy.get(v, v))] = (u, v)
    return _finish(what, view, P + new_points, out, touched, refs, _diagonal(view), newell, moved, None, inherit)


def extrude_region(mesh: PolyMesh, faces: Sequence[int], distance: float) -> PolyMesh:
    """X: move a region of faces (see :func:`_region`) by ``distance`` along its mean normal (the unit sum of
    its faces' Newell vectors), its rim vertices copied and joined to the old rim by one quad per rim edge."""
    what = f"extrude_region {list(faces)}"
    view = mesh_view(mesh)
    rim, rim_vertices, n = region_rim(view, faces, what)
    dx, dy, dz = n[0] * distance, n[1] * distance, n[2] * distance
    P = list(view.P)
    on_rim = set(rim_vertices)
    inner = tuple(dict.fromkeys(c for f in faces for c in view.conn.faces[f] if c not in on_rim))
    for c in inner:
        p = P[c]
        P[c] = [p[0] + dx, p[1] + dy, p[2] + dz]
    new_points = [[P[c][0] + dx, P[c][1] + dy, P[c][2] + dz] for c in rim_vertices]
    refs = {f: _unit(_face_newell(view, f)) for f in faces}
    return _region_result(what, view, faces, rim, rim_vertices, P, new_points, refs, inner, True)


def _inset_corner(P: list[list[float]], u: int, v: int, w: int, thickness: float, n: Vec, what: str) -> list[float]:
    """Corner ``v`` between edges ``u -> v`` and ``v -> w`` moved as :func:`inset_points` moves a face's corner."""
    a = _unit(_cross(n, _sub(P[v], P[u])))
    b = _unit(_cross(n, _sub(P[w], P[v])))
    if a is None or b is None:
        raise OpError(f"{what}: a rim edge at vertex {v} is parallel to the region's normal")
    m = _unit((a[0] + b[0], a[1] + b[1], a[2] + b[2]))
    cos_half = _dot(m, a) if m is not None else 0.0
    if cos_half < _INSET_MIN_COS:
        raise OpError(f"{what}: the rim has a spike at vertex {v} (under {INSET_MIN_DEG:g} degrees)")
    s = thickness / cos_half
    p = P[v]
    return [p[0] + s * m[0], p[1] + s * m[1], p[2] + s * m[2]]


def inset_region(mesh: PolyMesh, faces: Sequence[int], thickness: float) -> PolyMesh:
    """N: shrink a region of faces (see :func:`_region`) onto new rim vertices, each ``thickness`` inside the
    rim as :func:`inset_points` places a face's corners, in the plane of the unit sum of the Newell vectors
    of the region's faces at that vertex; inner vertices stay. One ring quad per rim edge."""
    what = f"inset_region {list(faces)}"
    if not thickness > 0.0:
        raise OpError(f"{what}: the thickness must be positive")
    view = mesh_view(mesh)
    rim, rim_vertices, _ = region_rim(view, faces, what)
    conn = view.conn
    inside = set(faces)
    after = dict(rim)
    before = {v: u for u, v in rim}
    new_points = []
    for v in rim_vertices:
        n = _mean_normal(view, (f for f in conn.vertex_faces(v) if f in inside),
                         f"{what}: the region has no normal at vertex {v}")
        new_points.append(_inset_corner(view.P, before[v], v, after[v], thickness, n, what))
    refs: dict[int, Vec | None] = {f: _unit(_face_newell(view, f)) for f in faces}
    first = conn.n_faces
    owner = [conn.half[e] for e in rim]
    refs.update({first + i: refs[f] for i, f in enumerate(owner)})
    return _region_result(what, view, faces, rim, rim_vertices, list(view.P), new_points, refs, (), False)


# --- L: edge loop ----------------------------------------------------------------------------------------

def edge_ring(conn: MeshConn, edge: int) -> tuple[list[int], list[tuple[int, int]], list[int], bool]:
    """The ring of opposite edges through quads that ``edge_loop`` cuts.

    Returns ``(ring edges, crossed quads as (face, corner of the entering edge), end faces, closed)``:
    ``edge`` first, then the edges met walking across its first face, then (open rings) those met
    walking across its second face. A walk stops at a non-quad face (an end face, which gets a
    T-vertex) or at a boundary. A quad crossed twice (a self-crossing ring) raises OpError.
    """
    faces, half, edge_id = conn.faces, conn.half, conn.edge_id
    ring = [edge]
    quads: list[tuple[int, int]] = []
    ends: list[int] = []
    seen: set[int] = set()
    for side in (0, 1):
        e = edge
        f = conn.edge_faces(edge)[side]
        while f >= 0:
            cyc = faces[f]
            if len(cyc) != 4:
                ends.append(f)
                break
            if f in seen:
                raise OpError(f"edge_loop {edge}: the edge ring crosses itself")
            seen.add(f)
            u, v = conn.edges[e]
            i = cyc.index(u) if half.get((u, v)) == f else cyc.index(v)
            quads.append((f, i))
            a, b = cyc[(i + 2) % 4], cyc[(i + 3) % 4]
            e = edge_id[(a, b) if a < b else (b, a)]
            if e == edge:
                return ring, quads, ends, True
            ring.append(e)
            f = half.get((b, a), -1)
    return ring, quads, ends, False


def distinct_rings(conn: MeshConn) -> list[tuple[int, list[int], list[tuple[int, int]]]]:
    """Every distinct ring an edge loop could cut, once: ``(its lowest edge, ring edges, crossed quads)`` as
    :func:`edge_ring` gives them; self-crossing rings are left out."""
    seen: set[int] = set()
    out = []
    for e in range(len(conn.edges)):
        if e in seen:
            continue
        try:
            ring, quads, _, _ = edge_ring(conn, e)
        except OpError:
            continue
        seen.update(ring)
        out.append((e, ring, quads))
    return out


def _sides_joined(conn: MeshConn, ring: list[int], quads: list[tuple[int, int]]) -> bool:
    """Whether an edge that is not in ``ring`` joins a vertex on one side of the ring to one on the other
    (around a tunnel: Blender's subdivide_edgering splits every edge between its two rim loops)."""
    u, v = conn.edges[ring[0]]
    side = {u: 0, v: 1}
    for f, i in quads:
        c = conn.faces[f]
        side[c[(i + 3) % 4]] = side[c[i]]
        side[c[(i + 2) % 4]] = side[c[(i + 1) % 4]]
    cut = set(ring)
    return any(side.get(a, s) != s for e, (a, b) in enumerate(conn.edges)
               if e not in cut and (s := side.get(b)) is not None)


def edge_loop(mesh: PolyMesh, edge: int) -> PolyMesh:
    """L: cut the ring of opposite edges through ``edge`` at their midpoints and join the cuts across quads."""
    what = f"edge_loop {edge}"
    view = mesh_view(mesh)
    conn = view.conn
    _index(edge, len(conn.edges), what, "edge")
    ring, quads, ends, _ = edge_ring(conn, edge)
    if not quads:
        raise OpError(f"{what}: the edge has no quad to cut across")
    ends_of_ring = [v for e in ring for v in conn.edges[e]]
    if len(set(ends_of_ring)) != len(ends_of_ring):  # Blender's subdivide_edgering builds something else
        raise OpError(f"{what}: the edge ring touches itself at a vertex")
    if _sides_joined(conn, ring, quads):  # Blender's subdivide_edgering cuts that edge too
        raise OpError(f"{what}: an edge outside the ring joins its two sides")
    diag = _diagonal(view)
    faces = list(conn.faces)
    refs = {f: _unit(_face_newell(view, f)) for f, _ in quads}
    refs.update((f, _unit(_face_newell(view, f))) for f in ends)
    P = list(view.P)
    base = len(P)
    mid: dict[tuple[int, int], int] = {}
    for j, e in enumerate(ring):
        u, v = conn.edges[e]
        pu, pv = P[u], P[v]
        P.append([0.5 * (pu[0] + pv[0]), 0.5 * (pu[1] + pv[1]), 0.5 * (pu[2] + pv[2])])
        mid[(u, v)] = mid[(v, u)] = base + j
    touched = []
    for f, i in quads:
        c = faces[f]
        m0 = mid[(c[i], c[(i + 1) % 4])]
        m1 = mid[(c[(i + 2) % 4], c[(i + 3) % 4])]
        h1 = (c[i], m0, m1, c[(i + 3) % 4])
        h2 = (m0, c[(i + 1) % 4], c[(i + 2) % 4], m1)
        keep, other = (h1, h2) if i < 2 else (h2, h1)
        r = keep.index(c[0])
        faces[f] = keep[r:] + keep[:r]
        faces.append(other)
        touched += (f, len(faces) - 1)
        refs[len(faces) - 1] = refs[f]
    for f in ends:
        cyc = list(faces[f])
        out = []
        for u, v in zip(cyc, cyc[1:] + cyc[:1]):
            out.append(u)
            m = mid.get((u, v))
            if m is not None:
                out.append(m)
        faces[f] = tuple(out)
        touched.append(f)
    touched = list(dict.fromkeys(touched))
    newell = view.newell + [None] * (len(faces) - len(conn.faces))
    inherit = None
    if view.mesh._creases is not None:
        inherit = {}
        for e in ring:
            u, v = conn.edges[e]
            m = mid[(u, v)]
            inherit[(min(u, m), max(u, m))] = inherit[(min(v, m), max(v, m))] = (u, v)
    return _finish(what, view, P, faces, touched, refs, diag, newell, (), _extended(view.bounds, P[base:]), inherit)


# --- B: bevel --------------------------------------------------------------------------------------------

def _fan(conn: MeshConn, v: int, start: int, what: str) -> list[tuple[int, int, int]]:
    """Faces around vertex ``v`` from face ``start`` as ``(face, prev vertex, next vertex)``, walking
    from a face with corner ``(p, v, n)`` to the face that holds the directed edge ``v -> p``."""
    out = []
    f = start
    while True:
        cyc = conn.faces[f]
        i = cyc.index(v)
        p = cyc[i - 1]
        out.append((f, p, cyc[(i + 1) % len(cyc)]))
        f = conn.half.get((v, p), -1)
        if f < 0:
            raise OpError(f"{what}: vertex {v} is on the boundary")
        if f == start:
            return out
        if len(out) > len(conn.faces):
            raise OpError(f"{what}: vertex {v} is not manifold")


def _bevel_end(P: list[list[float]], normals: dict[int, Vec | None], fan: list[tuple[int, int, int]],
               v: int, w: int, offset: float, what: str) -> list[tuple[int, list[float]]]:
    """Boundary points replacing end ``v`` of the bevelled edge ``v-w``, one per other edge at ``v`` in
    fan order, as ``(neighbour, point)``. The two edges next to ``v-w`` get the point at distance
    ``offset`` from the line ``v-w`` in the plane of the two edges (Blender's offset_meet); any further
    edge gets the point ``offset`` along it (Blender's slide_dist for a terminal edge). ``normals`` holds
    the unit normals of the fan's faces."""
    pv = P[v]
    e_dir = _unit(_sub(P[w], pv))
    k = len(fan)
    out = []
    for j in range(k - 1):
        x = fan[j][1]
        d_vec = _sub(P[x], pv)
        length = _norm(d_vec)
        if e_dir is None or length == 0.0:
            raise OpError(f"{what}: an edge at vertex {v} has zero length")
        u = (d_vec[0] / length, d_vec[1] / length, d_vec[2] / length)
        if j == 0 or j == k - 2:
            f = fan[0][0] if j == 0 else fan[-1][0]
            n = normals[f]
            prev_dir, next_dir = (u, e_dir) if j == 0 else (e_dir, u)
            # corner (prev, v, next) of face f: (v - prev) x (next - v) must point along its normal
            turn = _dot(_cross((-prev_dir[0], -prev_dir[1], -prev_dir[2]), next_dir), n) if n else 0.0
            if turn < _BEVEL_MIN_SIN:
                raise OpError(f"{what}: the corner at vertex {v} in face {f} is too flat, too sharp or reflex")
            slide = offset / _norm(_cross(u, e_dir))
        else:
            slide = offset
        if slide >= length:
            raise OpError(f"{what}: the offset runs past the end of edge {v}-{x}")
        out.append((x, [pv[0] + slide * u[0], pv[1] + slide * u[1], pv[2] + slide * u[2]]))
    return out


def bevel(mesh: PolyMesh, edge: int, offset: float) -> PolyMesh:
    """B: replace ``edge`` by a quad whose long edges lie ``offset`` from it in each adjacent face."""
    what = f"bevel {edge}"
    if not offset > 0.0:
        raise OpError(f"{what}: the offset must be positive")
    view = mesh_view(mesh)
    conn = view.conn
    _index(edge, len(conn.edges), what, "edge")
    a, b = conn.edges[edge]
    f1, f2 = conn.edge_faces(edge)
    if f2 < 0:
        raise OpError(f"{what}: the edge is on the boundary")
    fan_a = _fan(conn, a, f1, what)
    fan_b = _fan(conn, b, f2, what)
    if len(fan_a) < 3 or len(fan_b) < 3:
        raise OpError(f"{what}: an end vertex has fewer than three edges")
    if {f for f, _, _ in fan_a} & {f for f, _, _ in fan_b} != {f1, f2}:
        raise OpError(f"{what}: a face other than the edge's two holds both its ends")
    diag = _diagonal(view)
    faces = list(conn.faces)
    normals = {f: _unit(_face_newell(view, f)) for f, _, _ in fan_a + fan_b}
    pts_a = _bevel_end(view.P, normals, fan_a, a, b, offset, what)
    pts_b = _bevel_end(view.P, normals, fan_b, b, a, offset, what)
    P = list(view.P)
    refs: dict[int, Vec] = {}
    vertex_normal = []
    for fan in (fan_a, fan_b):
        acc = [0.0, 0.0, 0.0]
        for f, _, _ in fan:
            n = normals[f]
            if n is None:
                raise OpError(f"{what}: face {f} has zero area")
            refs[f] = n
            acc = [acc[0] + n[0], acc[1] + n[1], acc[2] + n[2]]
        vertex_normal.append(_unit(acc))
    # boundary vertices: at end a the f1-side one (first in fan order) takes a's index; at end b the f1-side
    # one (last in fan order) takes b's index; the others are appended, end a first, in polygon order
    order_a = pts_a
    order_b = pts_b[-1:] + pts_b[:-1]
    index_a: dict[int, int] = {}
    index_b: dict[int, int] = {}
    for end_v, order, index in ((a, order_a, index_a), (b, order_b, index_b)):
        x0, p0 = order[0]
        P[end_v] = p0
        index[x0] = end_v
    for order, index in ((order_a, index_a), (order_b, index_b)):
        for x, p in order[1:]:
            index[x] = len(P)
            P.append(p)
    for f in dict.fromkeys(f for f, _, _ in fan_a + fan_b):
        cyc = faces[f]
        k = len(cyc)
        out = []
        for i, c in enumerate(cyc):
            if c == a or c == b:
                index, other = (index_a, b) if c == a else (index_b, a)
                prv, nxt = cyc[i - 1], cyc[(i + 1) % k]
                if prv != other:
                    out.append(index[prv])
                if nxt != other:
                    out.append(index[nxt])
            else:
                out.append(c)
        faces[f] = tuple(out)
    a1, a2 = index_a[pts_a[0][0]], index_a[pts_a[-1][0]]
    b2, b1 = index_b[pts_b[0][0]], index_b[pts_b[-1][0]]
    faces.append((a1, a2, b2, b1))
    quad = len(faces) - 1
    n1, n2 = refs[f1], refs[f2]
    touched = list(dict.fromkeys(f for f, _, _ in fan_a + fan_b)) + [quad]
    refs[quad] = _unit((n1[0] + n2[0], n1[1] + n2[1], n1[2] + n2[2])) or n1
    for order, index, vn in ((order_a, index_a, vertex_normal[0]), (order_b, index_b, vertex_normal[1])):
        if len(order) >= 3:
            faces.append(tuple(index[x] for x, _ in order))
            touched.append(len(faces) - 1)
            if vn is not None:
                refs[len(faces) - 1] = vn
    # _check recomputes the touched faces' Newell vectors; a face at a or b outside the two fans (only
    # possible at a pinched vertex) keeps its cycle but not its positions: its vector is dropped
    newell = view.newell + [None] * (len(faces) - len(conn.faces))
    for f in (*conn.vertex_faces(a), *conn.vertex_faces(b)):
        newell[f] = None
    inherit = None
    if view.mesh._creases is not None:  # an edge at an end, now ending at its boundary vertex, keeps its sharpness
        inherit = {(min(i, x), max(i, x)): (end, x) for end, index in ((a, index_a), (b, index_b))
                   for x, i in index.items()}
    return _finish(what, view, P, faces, touched, refs, diag, newell, (a, b), None, inherit,
                   (min(a, b), max(a, b)))
