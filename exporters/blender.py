"""Blender replay scripts: a genome becomes a readable Python script that rebuilds the control geometry
with Blender's own operators (bmesh), then adds a Subdivision Surface modifier; for curves, the control
polygon after every op (hidden objects) and the NURBS curve. :class:`BlenderExporter` (format "blender")
writes and validates both; :func:`surface_model` is the replayed surface every surface exporter shares.

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

import dataclasses
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from gsr_cad import genome as genome_mod
from gsr_cad.atomic import write_text
from gsr_cad.errors import ConfigError, ExportError, InputError, OpError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.ops.base import Op
from gsr_cad.ops.mesh import OPS_BY_LETTER, Scale
from gsr_cad.ops.mesh_kernel import bbox_centre

from . import hosts
from .base import (EXACT_TOL, SAMPLE_TOL, Check, CurveSpline, Exporter, curve_history, curve_spline, expect_equal,
                   failed, measured, num, point_deviation, scratch_dir, skipped)

MAX_LEVELS = 6
_BOUNDARY = {"all": "ALL", "corners": "PRESERVE_CORNERS"}

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
    mod.boundary_smooth = BOUNDARY
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


def _vec(v: Sequence[float]) -> str:
    return "(" + ", ".join(num(x) for x in v) + ")"


def _mesh_call(op: Op, state: PolyMesh) -> str:
    """The helper call for one op (the state is the mesh the op applies to)."""
    name = op.name
    if name == "translate_vertex":
        return f"translate_vertex(bm, V, F, vertex={op.vertex}, delta={_vec(op.delta)})"
    if name in ("extrude", "translate_face"):
        return f"{name}(bm, V, F, face={op.face}, distance={num(op.distance)})"
    if name == "inset":
        return f"inset(bm, V, F, face={op.face}, thickness={num(op.thickness)})"
    if name == "bevel":
        return f"bevel(bm, V, F, edge={op.edge}, offset={num(op.offset)})"
    if name == "edge_loop":
        return f"edge_loop(bm, V, F, edge={op.edge})"
    assert isinstance(op, Scale)
    return f"scale(bm, V, F, factor={num(op.factor)}, pivot={_vec(bbox_centre(state))})"


def _op_labels(genome: Sequence[Op]) -> list[str]:
    """``"00 template"``, then ``"03 extrude face 5 by 0.42"`` for every op (numbers padded to the genome)."""
    width = max(2, len(str(len(genome))))
    return [f"{0:0{width}d} template"] + [f"{i + 1:0{width}d} {op.describe()}" for i, op in enumerate(genome)]


def _mesh_script(genome: Sequence[Op], states: Sequence[PolyMesh], levels: int, use_limit_surface: bool,
                 title: str, file_name: str, boundary: str = "all") -> str:
    """The script text; ``states`` are the template and the mesh after every op of ``genome``."""
    template = states[0]
    name = title or "gsr_control_mesh"
    labels = _op_labels(genome)[1:]
    listing = "\n".join(f"    {label}" for label in labels) or "    (none)"
    blocks = [f"\n    # {label}\n    {_mesh_call(op, state)}" for label, op, state in zip(labels, genome, states)]
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
BOUNDARY = {_BOUNDARY[boundary]!r}

TEMPLATE_VERTICES = [
{verts}]
TEMPLATE_FACES = [
{faces}]
'''
    body = _MESH_COMMON + "".join("\n" + _MESH_HELPERS[h] for h in used)
    return header + body + "\n" + _MESH_MAIN.format(ops="".join(blocks))


def write_blender_script(genome: Sequence[Op], template: PolyMesh, path: str | os.PathLike[str], levels: int = 2,
                         use_limit_surface: bool = True, title: str = "", boundary: str = "all") -> Path:
    """Write a Blender 3.4 script that replays ``genome`` on ``template`` and adds a Subdivision Surface
    modifier (``levels`` for viewport and render, ``use_limit_surface`` set explicitly, ``boundary``
    "all" or "corners" as gsr_cad names Blender's boundary smoothing); atomically."""
    if boundary not in _BOUNDARY:
        raise ConfigError(f"boundary must be one of {', '.join(_BOUNDARY)}, got {boundary!r}")
    if isinstance(levels, bool) or not isinstance(levels, int) or not 0 <= levels <= MAX_LEVELS:
        raise ConfigError(f"subdivision levels must be an integer in [0, {MAX_LEVELS}], got {levels!r}")
    if not isinstance(template, PolyMesh):
        raise ExportError(f"no Blender writer for a {type(template).__name__} template")
    if title and not all(ch.isalnum() or ch in " -_." for ch in title):
        raise ConfigError(f"the title may hold letters, digits, spaces, '-', '_' and '.', got {title!r}")
    genome = tuple(genome)
    known = {cls.name for cls in OPS_BY_LETTER.values()}
    for op in genome:
        if op.name not in known:
            raise ExportError(f"the Blender writer knows only surface ops, got {op.name!r}")
    try:
        states = genome_mod.replay_states(template, genome)
    except OpError as exc:
        raise ExportError(f"the genome does not replay on the template: {exc}") from None
    text = _mesh_script(genome, states, levels, use_limit_surface, title, Path(path).name, boundary)
    return write_text(path, text)


# --- Curves ----------------------------------------------------------------------------------------------

_CURVE_SCRIPT = '''"""{title}

The modelling history is replayed below, one commented block per op, on the template polygon: after every
step a hidden poly-curve object named after it (in the collection "{name} history"; the last step stays
visible as the control polygon) shows the control polygon at that point. The result is "{name}", a NURBS
curve with endpoint knots and order {order} (degree {degree}): exactly the clamped uniform {scheme} B-spline.

Run it in Blender's Text Editor, or headless:
    blender -b --factory-startup --python {filename} -- --json what_blender_built.json
"""

import json
import sys

import bpy

NAME = {name!r}
ORDER = {order}
RESOLUTION = {resolution}  # evaluated points per control-polygon segment
TEMPLATE = [
{template}]


def add_point(points, index, position):
    """Insert a control point so that it becomes points[index]."""
    points.insert(index, tuple(position))


def move_point(points, index, delta):
    """Translate points[index] by delta."""
    x, y = points[index]
    points[index] = (x + delta[0], y + delta[1])


def curve_object(name, points, kind, collection):
    """A curve object through `points` (z = 0): kind "POLY" (control polygon) or "NURBS"."""
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new(kind)
    spline.points.add(len(points) - 1)
    for p, (x, y) in zip(spline.points, points):
        p.co = (x, y, 0.0, 1.0)
    if kind == "NURBS":
        spline.order_u = ORDER
        spline.use_endpoint_u = True
        spline.resolution_u = RESOLUTION
    obj = bpy.data.objects.new(name, data)
    collection.objects.link(obj)
    return obj


def build():
    """The history objects and the curve; returns (curve object, history objects)."""
    scene = bpy.context.scene
    history = bpy.data.collections.new(NAME + " history")
    scene.collection.children.link(history)
    steps = []
    points = [tuple(p) for p in TEMPLATE]

    def step(label):
        steps.append(curve_object(label, points, "POLY", history))

    step({first_label!r})
{ops}
    for obj in steps[:-1]:
        obj.hide_set(True)
        obj.hide_render = True
    curve = curve_object(NAME, points, "NURBS", scene.collection)
    bpy.context.view_layer.objects.active = curve
    curve.select_set(True)
    return curve, steps


def describe(curve, steps):
    """What Blender built, as JSON-ready data (control points, NURBS settings, evaluated points, history)."""
    spline = curve.data.splines[0]
    evaluated = curve.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    samples = [list(v.co) for v in mesh.vertices]
    evaluated.to_mesh_clear()
    return {{"name": curve.name, "type": spline.type, "order": spline.order_u,
             "endpoint": bool(spline.use_endpoint_u), "cyclic": bool(spline.use_cyclic_u),
             "resolution": spline.resolution_u, "poles": [list(p.co) for p in spline.points],
             "samples": samples,
             "history": [{{"name": o.name, "hidden": bool(o.hide_get()),
                          "points": [list(p.co) for p in o.data.splines[0].points]}} for o in steps]}}


def main(argv):
    import argparse

    parser = argparse.ArgumentParser(prog="blender -b --python this.py --")
    parser.add_argument("--json", help="write what Blender built to this JSON file")
    args = parser.parse_args(argv[argv.index("--") + 1:] if "--" in argv else [])
    curve, steps = build()
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(describe(curve, steps), fh)
    return curve


if __name__ == "__main__":
    main(sys.argv)
'''

CURVE_RESOLUTION = 12
BLENDER_NAME_LIMIT = 63  # bytes in an ID name


def _curve_call(op: dict) -> str:
    if op["op"] == "add_point":
        return f"add_point(points, {int(op['index'])}, {_vec(op['position'])})"
    if op["op"] == "move_point":
        return f"move_point(points, {int(op['index'])}, {_vec(op['delta'])})"
    raise ExportError(f"the Blender curve writer knows add_point and move_point, got {op['op']!r}")


def _blender_name(label: str) -> str:
    return label.encode("utf-8")[:BLENDER_NAME_LIMIT].decode("utf-8", "ignore")


def curve_script(result: Any, file_name: str, title: str = "") -> str:
    """The Blender script text for a curve result (history replay + NURBS curve)."""
    spline = curve_spline(result)
    history = curve_history(result)
    blocks = [f"\n    # {h.label}\n    {_curve_call(h.op)}\n    step({_blender_name(h.label)!r})"
              for h in history[1:]]
    scheme = str(result.config.get("scheme", "bspline"))
    name = title or "gsr_curve"
    return _CURVE_SCRIPT.format(
        title=f"{file_name}: a gsr_cad {scheme} curve with {len(result.genome)} modelling ops (Blender 3.4)",
        name=name, order=spline.degree + 1, degree=spline.degree, scheme=scheme, filename=file_name,
        resolution=CURVE_RESOLUTION, template="".join(f"    {_vec(p)},\n" for p in history[0].points.tolist()),
        first_label=_blender_name(history[0].label), ops="".join(blocks))


# --- Surfaces: what every surface exporter shares -------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class SurfaceModel:
    """A surface result as the exporters see it: the template, the control mesh after every op (labelled
    ``"03 extrude face 5 by 0.42"``), the subdivision settings and the limit mesh."""

    labels: tuple[str, ...]
    ops: tuple[dict[str, Any] | None, ...]
    states: tuple[PolyMesh, ...]
    levels: int
    boundary: str
    limit: PolyMesh

    @property
    def control(self) -> PolyMesh:
        return self.states[-1]

    @property
    def diagonal(self) -> float:
        """Bounding-box diagonal of the limit mesh: the unit of every surface tolerance."""
        d = self.limit.diagonal
        return d if d > 0 else 1.0


def surface_model(result: Any) -> SurfaceModel:
    """Replay a surface result's genome on its stored template; ExportError when the result has ops but
    no template, the genome does not replay, or the replay does not rebuild ``control_mesh`` exactly."""
    from gsr_cad.reconstruct.surface import template_from_config

    if result.kind != "surface" or result.control_mesh is None:
        raise ExportError(f"expected a surface result, got a {result.kind} result")
    cfg = result.config or {}
    try:
        # without ops the control mesh is its own template
        template = result.control_mesh if not result.genome and "template" not in cfg else template_from_config(cfg)
        states = genome_mod.replay_states(template, result.genome)
    except (OpError, InputError, TypeError, ValueError) as exc:
        raise ExportError(f"the genome does not replay on the stored template: {str(exc).splitlines()[0]}") from None
    final, want = states[-1], result.control_mesh
    if final.faces != want.faces or not np.array_equal(final.vertices, want.vertices):
        raise ExportError("replaying the genome does not rebuild control_mesh (a hand-edited result.json?)")
    levels, boundary = cfg.get("levels", 2), cfg.get("boundary", "all")
    if isinstance(levels, bool) or not isinstance(levels, int) or not 1 <= levels <= MAX_LEVELS:
        raise ExportError(f"config levels must be an integer in [1, {MAX_LEVELS}], got {levels!r}")
    if boundary not in _BOUNDARY:
        raise ExportError(f"config boundary must be one of {', '.join(_BOUNDARY)}, got {boundary!r}")
    ops = (None, *(op.to_json() for op in result.genome))
    return SurfaceModel(tuple(_op_labels(result.genome)), ops, tuple(states), levels, boundary,
                        limit_mesh(final, levels, boundary))


def same_mesh(ours: PolyMesh, theirs_vertices: np.ndarray, theirs_faces: Sequence[Sequence[int]]) -> tuple[float, str]:
    """``(largest vertex distance, problem)`` between our mesh and one read back in any element order:
    every vertex is matched to its nearest, the match must be one-to-one and map faces onto faces (as
    oriented cycles). ``problem`` is "" when the structure agrees (the distance is then meaningful)."""
    tv = np.asarray(theirs_vertices, dtype=float).reshape(-1, 3)
    if len(tv) != ours.n_vertices or len(theirs_faces) != ours.n_faces:
        return math.inf, (f"{len(tv)} vertices and {len(theirs_faces)} faces, "
                          f"expected {ours.n_vertices} and {ours.n_faces}")
    dist, match = cKDTree(tv).query(ours.vertices)
    if len(np.unique(match)) != ours.n_vertices:
        return float(dist.max()), "two vertices match the same vertex"
    mapped = sorted(_canonical([int(match[i]) for i in f]) for f in ours.faces)
    if mapped != sorted(_canonical([int(i) for i in f]) for f in theirs_faces):
        return float(dist.max()), "the faces differ"
    return float(dist.max()), ""


def triangle_faces(mesh: PolyMesh) -> list[tuple[int, int, int]]:
    """Fan triangles of every face, counter-clockwise seen from outside like the faces."""
    return [(f[0], f[i], f[i + 1]) for f in mesh.faces for i in range(1, len(f) - 1)]


def _canonical(cycle: Sequence[int]) -> tuple[int, ...]:
    i = int(np.argmin(cycle))
    return tuple(cycle[i:]) + tuple(cycle[:i])


def _read_obj(path: Path) -> tuple[np.ndarray, list[list[int]]]:
    verts, faces = [], []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:]])
    return np.array(verts, dtype=float).reshape(-1, 3), faces


# --- The exporter ----------------------------------------------------------------------------------------

class BlenderExporter(Exporter):
    """``*_blender.py``: a Blender 3.4 script that replays the modelling history with Blender's own tools.

    Surfaces: bmesh ops and a Subdivision Surface modifier on the limit surface (:func:`write_blender_script`).
    Curves: the control polygon after every op as hidden objects and the NURBS curve (endpoint knots).
    Validation runs the script in background Blender and compares what it built with our geometry: the
    control mesh (gsr_cad's order, within :data:`CONTROL_TOL` of the diagonal; Blender stores single
    precision) and the modifier's output (within :data:`EVALUATED_TOL`), or the curve's poles, NURBS
    settings, history polygons and Blender's own evaluated points.
    """

    name = "blender"
    kinds = ("curve", "surface")
    suffixes = ("_blender.py",)
    host = "blender"

    def export_surface(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        model = surface_model(result)  # replayed and checked: levels, boundary and states are valid
        filename = self.filename(stem)
        text = _mesh_script(tuple(result.genome), model.states, model.levels, True, _title(stem), filename,
                            model.boundary)
        return [write_text(out_dir / filename, text)]

    def export_curve(self, result: Any, out_dir: Path, stem: str) -> list[Path]:
        filename = self.filename(stem)
        return [write_text(out_dir / filename, curve_script(result, filename, _title(stem)))]

    def _run(self, path: Path, args: Sequence[str]) -> Check | None:
        try:
            hosts.run_blender(path, args, timeout=300)
        except ExportError as exc:
            return failed(path, self.host, "run script", str(exc))
        return None

    def validate_surface(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("blender"):
            return [skipped(path, self.host, "run script", reason)]
        try:
            model = surface_model(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        with scratch_dir() as tmp:
            control, evaluated = tmp / "control.obj", tmp / "evaluated.obj"
            crash = self._run(path, ["--control", control, "--evaluated", evaluated])
            if crash:
                return [crash]
            try:
                cv, cf = _read_obj(control)
                ev, ef = _read_obj(evaluated)
            except (OSError, ValueError) as exc:
                return [failed(path, self.host, "read output", f"the script wrote no usable OBJ: {exc}")]
        ours, diag = model.control, model.diagonal
        checks = [expect_equal(path, self.host, "control faces", [tuple(f) for f in cf], ours.faces)]
        checks.append(measured(path, self.host, "control vertices",
                               point_deviation(cv, ours.vertices) / diag, CONTROL_TOL,
                               f"relative to the diagonal; tolerance {CONTROL_TOL:.3g}"))
        dev, problem = same_mesh(model.limit, ev, ef)
        label = f"modifier (levels {model.levels}) vs our limit mesh"
        if problem:
            checks.append(failed(path, self.host, label, problem))
        else:
            checks.append(measured(path, self.host, label, dev / diag, EVALUATED_TOL,
                                   f"{model.limit.n_vertices} vertices, relative to the diagonal; "
                                   f"tolerance {EVALUATED_TOL:.3g}"))
        return checks

    def validate_curve(self, path: Path, result: Any) -> list[Check]:
        if reason := hosts.missing("blender"):
            return [skipped(path, self.host, "run script", reason)]
        spline = curve_spline(result)
        try:
            history = curve_history(result)
        except ExportError as exc:
            return [failed(path, self.host, "history", str(exc))]
        with scratch_dir() as tmp:
            out = tmp / "built.json"
            crash = self._run(path, ["--json", out])
            if crash:
                return [crash]
            try:
                data = json.loads(out.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                return [failed(path, self.host, "read output", f"the script wrote no usable JSON: {exc}")]
        return self._compare_curve(path, data, spline, history)

    def _compare_curve(self, path: Path, data: dict, spline: CurveSpline, history: list) -> list[Check]:
        host, diag = self.host, spline.diagonal
        tol = CONTROL_TOL * max(diag, spline.scale)
        poles = np.asarray(data["poles"], dtype=float)
        checks = [
            expect_equal(path, host, "NURBS settings", (data["type"], data["order"], data["endpoint"], data["cyclic"]),
                         ("NURBS", spline.degree + 1, True, False)),
            measured(path, host, "poles", point_deviation(poles[:, :3] if poles.ndim == 2 else poles,
                                                          np.column_stack([spline.poles, np.zeros(len(spline.poles))])),
                     tol, f"tolerance {tol:.3g} (single precision)"),
            measured(path, host, "weights", float(np.abs(poles[:, 3] - 1.0).max()) if poles.ndim == 2 else math.inf,
                     EXACT_TOL),
        ]
        steps = data.get("history") or []
        checks += [
            expect_equal(path, host, "one object per op", len(steps), len(history)),
            expect_equal(path, host, "op labels", [s["name"] for s in steps],
                         [_blender_name(h.label) for h in history]),
            expect_equal(path, host, "only the last step visible", [not s["hidden"] for s in steps],
                         [i == len(history) - 1 for i in range(len(history))]),
        ]
        if len(steps) == len(history):
            dev = max(point_deviation(np.asarray(s["points"], dtype=float)[:, :2], h.points)
                      for s, h in zip(steps, history))
            checks.append(measured(path, host, "history polygons", dev, tol, f"tolerance {tol:.3g}"))
        samples = np.asarray(data["samples"], dtype=float)
        params = np.linspace(0.0, 1.0, len(samples))
        want = np.column_stack([spline.points(params), np.zeros(len(params))])
        stol = SAMPLE_TOL * max(diag, spline.scale)
        checks.append(measured(path, host, f"{len(samples)} evaluated points", point_deviation(samples, want), stol,
                               f"Blender's own NURBS evaluation; tolerance {stol:.3g}"))
        return checks


CONTROL_TOL = 1e-6
"""Control geometry read back from Blender (single precision), relative to the diagonal."""
EVALUATED_TOL = 1e-5
"""Blender's Subdivision Surface output against our limit mesh, relative to the diagonal."""


def _title(stem: str) -> str:
    """A Blender object name from a file stem (letters, digits, ' -_.' only)."""
    return "".join(ch if ch.isalnum() or ch in " -_." else "_" for ch in stem) or "gsr"
