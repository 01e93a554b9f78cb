"""Blender replay scripts: a genome becomes a readable Python script that rebuilds the control geometry
with Blender's own operators (bmesh), then adds a Subdivision Surface modifier.

The script is self-contained (Blender 3.4, no gsr_cad needed). Run from Blender's Text Editor it just
builds the object; run headless as
``blender -b --factory-startup --python script.py -- --control OUT.obj --evaluated OUT2.obj`` it also
writes the control mesh (in gsr_cad's vertex and face order) and the modifier's evaluated mesh as plain
OBJ files, written by the script itself.

Surfaces (:class:`~gsr_cad.geometry.polymesh.PolyMesh` templates): the script keeps ``V`` (the BMVert
gsr_cad calls vertex ``i``) and ``F`` (gsr_cad's corner cycle of face ``f``); each op helper runs the
bmesh operator and then renumbers exactly as :mod:`gsr_cad.ops.mesh` documents, so later ops find their
elements through these references, never through Blender's indices (bmesh reuses freed slots). After
every op the script checks that ``V`` and ``F`` still describe the bmesh and stops with an error if not.
Blender keeps coordinates in single precision, so a replay matches gsr_cad to about ``1e-7`` of the
model's size; extruding a thin face far amplifies that (the face normal comes from Blender's geometry,
which keeps the script editable: change a number and run it again).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from gsr_cad.atomic import write_text
from gsr_cad.errors import ConfigError, ExportError, OpError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.ops.base import Op
from gsr_cad.ops.mesh import OPS_BY_LETTER, Scale
from gsr_cad.ops.mesh_kernel import bbox_centre

MAX_LEVELS = 6

# --- Blender-side code for surfaces (kept as source text, emitted into the script) ---------------------

_MESH_COMMON = '''
def face_of(bm, V, cycle):
    """The BMFace whose corners are gsr_cad's cycle."""
    face = bm.faces.get([V[i] for i in cycle])
    if face is None:
        raise RuntimeError(f"no face with corners {cycle}")
    return face


def edges_in_order(F):
    """gsr_cad's edge numbering: first appearance walking the faces' corners; returns (edges, index)."""
    edges, index = [], {}
    for cycle in F:
        for u, v in zip(cycle, cycle[1:] + cycle[:1]):
            key = (u, v) if u < v else (v, u)
            if key not in index:
                index[key] = len(edges)
                edges.append((u, v))
    return edges, index


def owners(F):
    """The face that holds each directed edge (u, v)."""
    return {(u, v): f for f, cycle in enumerate(F) for u, v in zip(cycle, cycle[1:] + cycle[:1])}


def check(bm, V, F):
    """Stop when the tracked numbering no longer describes the bmesh (a replay that diverged)."""
    if len(V) != len(bm.verts) or len(F) != len(bm.faces):
        raise RuntimeError(f"replay diverged: tracking {len(V)} vertices and {len(F)} faces, "
                           f"bmesh has {len(bm.verts)} and {len(bm.faces)}")
    for f, cycle in enumerate(F):
        corners = list(face_of(bm, V, cycle).verts)
        k = len(cycle)
        start = corners.index(V[cycle[0]]) if len(corners) == k else 0
        if len(corners) != k or any(corners[(start + j) % k] != V[cycle[j]] for j in range(k)):
            raise RuntimeError(f"replay diverged: face {f} is not the cycle {cycle}")
'''

_MESH_HELPERS = {
    "translate_vertex": '''
def translate_vertex(bm, V, F, vertex, delta):
    """V: move one vertex."""
    bmesh.ops.translate(bm, vec=Vector(delta), verts=[V[vertex]])
    check(bm, V, F)
''',
    "translate_face": '''
def translate_face(bm, V, F, face, distance):
    """F: move a face along its normal."""
    bm.normal_update()
    shift = face_of(bm, V, F[face]).normal * distance
    bmesh.ops.translate(bm, vec=shift, verts=[V[i] for i in F[face]])
    check(bm, V, F)
''',
    "scale": '''
def scale(bm, V, F, factor, pivot):
    """S: scale everything about the pivot (the bounding-box centre when the op ran)."""
    bmesh.ops.scale(bm, vec=(factor, factor, factor), space=Matrix.Translation(-Vector(pivot)),
                    verts=list(bm.verts))
    check(bm, V, F)
''',
    "_cap_and_ring": '''
def cap_and_ring(V, F, face, new_verts):
    """Renumber after extrude/inset: face keeps its index on the new vertices, one quad per edge appended."""
    cycle, k, n = F[face], len(F[face]), len(V)
    V.extend(new_verts)
    F[face] = tuple(range(n, n + k))
    F.extend((cycle[i], cycle[(i + 1) % k], n + (i + 1) % k, n + i) for i in range(k))


def linked_in(vert, candidates):
    """The vertex of `candidates` joined to `vert` by an edge."""
    return next(e.other_vert(vert) for e in vert.link_edges if e.other_vert(vert) in candidates)
''',
    "extrude": '''
def extrude(bm, V, F, face, distance):
    """E: extrude one face (its edges and vertices too, so the old face goes) along its normal."""
    cycle = F[face]
    bm.normal_update()
    old = face_of(bm, V, cycle)
    shift = old.normal * distance
    geom = bmesh.ops.extrude_face_region(bm, geom=[old, *old.edges, *old.verts], use_keep_orig=False)["geom"]
    new = {g for g in geom if isinstance(g, bmesh.types.BMVert)}
    copies = [linked_in(V[c], new) for c in cycle]
    bmesh.ops.translate(bm, vec=shift, verts=copies)
    cap_and_ring(V, F, face, copies)
    check(bm, V, F)
''',
    "inset": '''
def inset(bm, V, F, face, thickness):
    """I: inset one face, every inner edge `thickness` from its outer edge."""
    cycle = F[face]
    bm.normal_update()  # inset_individual silently does nothing on stale normals
    old = face_of(bm, V, cycle)
    bmesh.ops.inset_individual(bm, faces=[old], thickness=thickness, depth=0.0, use_even_offset=True,
                               use_interpolate=True, use_relative_offset=False)
    inner = set(old.verts)
    cap_and_ring(V, F, face, [linked_in(V[c], inner) for c in cycle])
    check(bm, V, F)
''',
    "edge_loop": '''
def edge_ring(F, edge):
    """gsr_cad's ring through `edge`: (ring edges, crossed quads as (face, corner), end faces)."""
    edges, index = edges_in_order(F)
    own = owners(F)
    ring, quads, ends, seen = [edge], [], [], set()
    for side in (0, 1):
        e = edge
        u, v = edges[edge]
        f = own[(u, v)] if side == 0 else own.get((v, u), -1)
        while f >= 0:
            cycle = F[f]
            if len(cycle) != 4:
                ends.append(f)
                break
            if f in seen:
                raise RuntimeError(f"edge ring through edge {edge} crosses itself")
            seen.add(f)
            u, v = edges[e]
            i = cycle.index(u) if own[(u, v)] == f else cycle.index(v)
            quads.append((f, i))
            a, b = cycle[(i + 2) % 4], cycle[(i + 3) % 4]
            e = index[(a, b) if a < b else (b, a)]
            if e == edge:
                return [edges[r] for r in ring], quads, ends
            ring.append(e)
            f = own.get((b, a), -1)
    return [edges[r] for r in ring], quads, ends


def edge_loop(bm, V, F, edge):
    """L: cut the ring of opposite edges through `edge` in the middle (subdivide_edgering, one cut)."""
    ring, quads, ends = edge_ring(F, edge)
    old = set(V)
    bmesh.ops.subdivide_edgering(bm, edges=[bm.edges.get((V[u], V[v])) for u, v in ring], cuts=1,
                                 interp_mode="LINEAR", smooth=0.0, profile_shape="SMOOTH",
                                 profile_shape_factor=0.0)
    mid = {}
    for u, v in ring:
        near_u = {e.other_vert(V[u]) for e in V[u].link_edges}
        m = next(e.other_vert(V[v]) for e in V[v].link_edges
                 if e.other_vert(V[v]) in near_u and e.other_vert(V[v]) not in old)
        mid[(u, v)] = mid[(v, u)] = len(V)
        V.append(m)
    for f, i in quads:
        c = F[f]
        m0, m1 = mid[(c[i], c[(i + 1) % 4])], mid[(c[(i + 2) % 4], c[(i + 3) % 4])]
        h1 = (c[i], m0, m1, c[(i + 3) % 4])
        h2 = (m0, c[(i + 1) % 4], c[(i + 2) % 4], m1)
        keep, other = (h1, h2) if i < 2 else (h2, h1)
        r = keep.index(c[0])
        F[f] = keep[r:] + keep[:r]
        F.append(other)
    for f in dict.fromkeys(ends):
        out = []
        for u, v in zip(F[f], F[f][1:] + F[f][:1]):
            out.append(u)
            if (u, v) in mid:
                out.append(mid[(u, v)])
        F[f] = tuple(out)
    check(bm, V, F)
''',
    "bevel": '''
def fan(F, own, v, start):
    """Faces around vertex v from face `start` as (face, previous corner, next corner)."""
    out, f = [], start
    while True:
        cycle = F[f]
        i = cycle.index(v)
        out.append((f, cycle[i - 1], cycle[(i + 1) % len(cycle)]))
        f = own[(v, cycle[i - 1])]
        if f == start:
            return out


def bevel(bm, V, F, edge, offset):
    """B: bevel one edge, one segment, `offset` measured from the edge within each adjacent face."""
    edges, _ = edges_in_order(F)
    own = owners(F)
    a, b = edges[edge]
    fans = {a: fan(F, own, a, own[(a, b)]), b: fan(F, own, b, own[(b, a)])}
    ends = {v: V[v].co.copy() for v in (a, b)}
    bm.normal_update()
    new = set(bmesh.ops.bevel(bm, geom=[bm.edges.get((V[a], V[b]))], offset=offset, offset_type="OFFSET",
                              segments=1, profile=0.5, affect="EDGES")["verts"])

    def on_edge(v, x):  # the new vertex on the old edge v-x
        line = (V[x].co - ends[v]).normalized()
        cands = [e.other_vert(V[x]) for e in V[x].link_edges if e.other_vert(V[x]) in new]
        return min(cands, key=lambda p: (p.co - ends[v]).cross(line).length)

    # boundary vertices in end-polygon order, starting on the side of the edge's first face
    order = {a: [p for _, p, _ in fans[a][:-1]]}
    order[b] = [p for _, p, _ in fans[b][:-1]]
    order[b] = order[b][-1:] + order[b][:-1]
    index = {a: {}, b: {}}
    for v in (a, b):
        index[v][order[v][0]] = v
        V[v] = on_edge(v, order[v][0])
    for v in (a, b):
        for x in order[v][1:]:
            index[v][x] = len(V)
            V.append(on_edge(v, x))
    for f in dict.fromkeys(f for f, _, _ in fans[a] + fans[b]):
        cycle, out = F[f], []
        for i, c in enumerate(cycle):
            if c in (a, b):
                other = b if c == a else a
                p, n = cycle[i - 1], cycle[(i + 1) % len(cycle)]
                out += [index[c][x] for x in (p, n) if x != other]
            else:
                out.append(c)
        F[f] = tuple(out)
    a_first, a_last = fans[a][0][1], fans[a][-2][1]
    b_first, b_last = fans[b][0][1], fans[b][-2][1]
    F.append((index[a][a_first], index[a][a_last], index[b][b_first], index[b][b_last]))
    for v in (a, b):
        if len(order[v]) >= 3:
            F.append(tuple(index[v][x] for x in order[v]))
    check(bm, V, F)
''',
}
_MESH_HELPER_NEEDS = {"extrude": ("_cap_and_ring",), "inset": ("_cap_and_ring",)}

_MESH_MAIN = '''
def build():
    """Template, then the modelling history; returns (bm, V, F)."""
    bm = bmesh.new()
    V = [bm.verts.new(p) for p in TEMPLATE_VERTICES]
    F = [tuple(cycle) for cycle in TEMPLATE_FACES]
    for cycle in F:
        bm.faces.new([V[i] for i in cycle])
    check(bm, V, F)
{ops}
    return bm, V, F


def write_obj(path, vertices, faces, comment):
    """A plain OBJ file (1-based faces)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(f"# {{comment}}\\n")
        fh.writelines(f"v {{x!r}} {{y!r}} {{z!r}}\\n" for x, y, z in vertices)
        fh.writelines("f " + " ".join(str(i + 1) for i in face) + "\\n" for face in faces)


def make_object(bm):
    """Link a new object with the control mesh and its Subdivision Surface modifier to the scene."""
    mesh = bpy.data.meshes.new(NAME)
    bm.to_mesh(mesh)
    obj = bpy.data.objects.new(NAME, mesh)
    bpy.context.scene.collection.objects.link(obj)
    mod = obj.modifiers.new("Subdivision", "SUBSURF")
    mod.subdivision_type = "CATMULL_CLARK"
    mod.levels = LEVELS
    mod.render_levels = LEVELS
    mod.use_limit_surface = USE_LIMIT_SURFACE
    mod.boundary_smooth = "ALL"
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj


def main(argv):
    import argparse

    parser = argparse.ArgumentParser(prog="blender -b --python this.py --")
    parser.add_argument("--control", help="write the control mesh (gsr_cad order) to this OBJ file")
    parser.add_argument("--evaluated", help="write the subdivided (evaluated) mesh to this OBJ file")
    args = parser.parse_args(argv[argv.index("--") + 1:] if "--" in argv else [])
    bm, V, F = build()
    obj = make_object(bm)
    if args.control:
        write_obj(args.control, [tuple(v.co) for v in V], F, f"{{NAME}}: control mesh")
    if args.evaluated:
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        write_obj(args.evaluated, [tuple(v.co) for v in mesh.vertices], [tuple(p.vertices) for p in mesh.polygons],
                  f"{{NAME}}: Subdivision Surface, levels {{LEVELS}}, limit surface {{USE_LIMIT_SURFACE}}")
        evaluated.to_mesh_clear()
    bm.free()
    return obj


if __name__ == "__main__":
    main(sys.argv)
'''


def _num(x: float) -> str:
    return repr(float(x))


def _vec(v: Sequence[float]) -> str:
    return "(" + ", ".join(_num(x) for x in v) + ")"


def _mesh_call(op: Op, state: PolyMesh) -> str:
    """The helper call for one op (the state is the mesh the op applies to)."""
    name = op.name
    if name == "translate_vertex":
        return f"translate_vertex(bm, V, F, vertex={op.vertex}, delta={_vec(op.delta)})"
    if name in ("extrude", "translate_face"):
        return f"{name}(bm, V, F, face={op.face}, distance={_num(op.distance)})"
    if name == "inset":
        return f"inset(bm, V, F, face={op.face}, thickness={_num(op.thickness)})"
    if name == "bevel":
        return f"bevel(bm, V, F, edge={op.edge}, offset={_num(op.offset)})"
    if name == "edge_loop":
        return f"edge_loop(bm, V, F, edge={op.edge})"
    assert isinstance(op, Scale)
    return f"scale(bm, V, F, factor={_num(op.factor)}, pivot={_vec(bbox_centre(state))})"


def _mesh_script(genome: Sequence[Op], template: PolyMesh, levels: int, use_limit_surface: bool, title: str,
                 file_name: str) -> str:
    known = {cls.name for cls in OPS_BY_LETTER.values()}
    for op in genome:
        if op.name not in known:
            raise ExportError(f"the Blender writer knows only surface ops, got {op.name!r}")
    states = [template]
    try:
        for op in genome:
            states.append(op.apply(states[-1]))
    except OpError as exc:
        raise ExportError(f"the genome does not replay on the template: {exc}") from None
    name = title or "gsr_control_mesh"
    width = max(2, len(str(len(genome))))
    listing = "\n".join(f"    {i + 1:0{width}d} {op.describe()}" for i, op in enumerate(genome)) or "    (none)"
    blocks = []
    for i, op in enumerate(genome):
        blocks.append(f"\n    # {i + 1:0{width}d} {op.describe()}\n    {_mesh_call(op, states[i])}")
    used: list[str] = []
    for op in genome:
        for helper in (*_MESH_HELPER_NEEDS.get(op.name, ()), op.name):
            if helper not in used:
                used.append(helper)
    verts = "".join(f"    {_vec(p)},\n" for p in template.vertices.tolist())
    faces = "".join(f"    {tuple(f)!r},\n" for f in template.faces)
    header = f'''"""{name}: a gsr_cad modelling history replayed with Blender's bmesh (Blender 3.4).

Run it in Blender's Text Editor to build the object, or headless:
    blender -b --factory-startup --python {file_name} -- --control control.obj --evaluated evaluated.obj
The template has {template.n_vertices} vertices and {template.n_faces} faces; the ops, in order:
{listing}
The result has {states[-1].n_vertices} vertices and {states[-1].n_faces} faces. V[i] is the BMVert gsr_cad calls
vertex i and F[f] gsr_cad's corner cycle of face f; every op helper renumbers them the way gsr_cad does, so
ops find their elements through them, never through Blender's indices.
"""

import sys

import bmesh
import bpy
from mathutils import Matrix, Vector

NAME = {name!r}
LEVELS = {levels}
USE_LIMIT_SURFACE = {bool(use_limit_surface)}

TEMPLATE_VERTICES = [
{verts}]
TEMPLATE_FACES = [
{faces}]
'''
    body = _MESH_COMMON + "".join("\n" + _MESH_HELPERS[h] for h in used)
    return header + body + "\n" + _MESH_MAIN.format(ops="".join(blocks))


def write_blender_script(genome: Sequence[Op], template: PolyMesh, path: str | os.PathLike[str], levels: int = 2,
                         use_limit_surface: bool = True, title: str = "") -> Path:
    """Write a Blender 3.4 script that replays ``genome`` on ``template`` and adds a Subdivision Surface
    modifier (``levels`` for viewport and render, ``use_limit_surface`` set explicitly); atomically."""
    if isinstance(levels, bool) or not isinstance(levels, int) or not 0 <= levels <= MAX_LEVELS:
        raise ConfigError(f"subdivision levels must be an integer in [0, {MAX_LEVELS}], got {levels!r}")
    if not isinstance(template, PolyMesh):
        raise ExportError(f"no Blender writer for a {type(template).__name__} template")
    if title and not all(ch.isalnum() or ch in " -_." for ch in title):
        raise ConfigError(f"the title may hold letters, digits, spaces, '-', '_' and '.', got {title!r}")
    text = _mesh_script(tuple(genome), template, levels, use_limit_surface, title, Path(path).name)
    return write_text(path, text)
