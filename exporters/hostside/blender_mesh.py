"""A gsr_cad modelling history replayed with Blender's bmesh (Blender 3.4), then a Subdivision Surface modifier.

Written by gsr_cad's "blender" exporter; everything specific to this model is in DATA below: the template,
then one step per op (its label and its parameters, as in result.json). V[i] is the BMVert gsr_cad calls
vertex i and F[f] gsr_cad's corner cycle of face f; every op helper runs Blender's bmesh operator and then
renumbers them the way gsr_cad does, so later ops find their elements through them, never through
Blender's indices. The control mesh after every step is kept as a hidden object named after the step (in
the collection "<name> history"); the visible object carries the Subdivision Surface modifier. Edit an op
in DATA["steps"] and run the script again.

Run it in Blender's Text Editor to build the object, or headless:
    blender -b --factory-startup --python this_file.py -- [--control c.obj] [--evaluated e.obj] [--blend out.blend]
"""

import argparse
import sys

import bmesh
import bpy
from mathutils import Matrix, Vector

DATA = {}


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


def translate_vertex(bm, V, F, vertex, delta):
    """V: move one vertex."""
    bmesh.ops.translate(bm, vec=Vector(delta), verts=[V[vertex]])
    check(bm, V, F)


def translate_face(bm, V, F, face, distance):
    """F: move a face along its normal."""
    bm.normal_update()
    shift = face_of(bm, V, F[face]).normal * distance
    bmesh.ops.translate(bm, vec=shift, verts=[V[i] for i in F[face]])
    check(bm, V, F)


def scale(bm, V, F, factor, pivot):
    """S: scale everything about the pivot (the bounding-box centre when the op ran)."""
    bmesh.ops.scale(bm, vec=(factor, factor, factor), space=Matrix.Translation(-Vector(pivot)),
                    verts=list(bm.verts))
    check(bm, V, F)


def cap_and_ring(V, F, face, new_verts):
    """Renumber after extrude/inset: face keeps its index on the new vertices, one quad per edge appended."""
    cycle, k, n = F[face], len(F[face]), len(V)
    V.extend(new_verts)
    F[face] = tuple(range(n, n + k))
    F.extend((cycle[i], cycle[(i + 1) % k], n + (i + 1) % k, n + i) for i in range(k))


def linked_in(vert, candidates):
    """The vertex of `candidates` joined to `vert` by an edge."""
    return next(e.other_vert(vert) for e in vert.link_edges if e.other_vert(vert) in candidates)


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


def crease_of(sharpness):
    """Blender's edge crease of an OpenSubdiv sharpness (Blender hands OpenSubdiv 10 * crease**2)."""
    return min(float(sharpness), 10.0) ** 0.5 / 10.0 ** 0.5


def set_creases(bm, V, rows):
    """Edge creases from ``(a, b, sharpness)`` rows (vertex indices as gsr_cad numbers them)."""
    layer = bm.edges.layers.crease.verify()
    for a, b, sharpness in rows:
        edge = bm.edges.get([V[a], V[b]])
        if edge is None:
            raise RuntimeError("no edge %d-%d to crease" % (a, b))
        edge[layer] = crease_of(sharpness)


def crease(bm, V, F, edge, sharpness):
    """C: the crease of one edge (gsr_cad's edge numbering)."""
    u, v = edges_in_order(F)[0][edge]
    set_creases(bm, V, [(u, v, sharpness)])
    check(bm, V, F)


def crease_rim(bm, V, F, face, sharpness):
    """R: the crease of every interior edge around a face."""
    own = owners(F)
    cycle = F[face]
    set_creases(bm, V, [(u, v, sharpness) for u, v in zip(cycle, cycle[1:] + cycle[:1]) if (v, u) in own])
    check(bm, V, F)


def hole(bm, V, F, face_a, face_b, quads):
    """H: delete two facing faces (keeping their edges) and bridge their rims with gsr_cad's quads (quad 0 takes
    face_a's place, quad 1 face_b's, the others are appended)."""
    bmesh.ops.delete(bm, geom=[face_of(bm, V, F[face_a]), face_of(bm, V, F[face_b])], context="FACES_ONLY")
    for quad in quads:
        bm.faces.new([V[i] for i in quad])
    F[face_a], F[face_b] = tuple(quads[0]), tuple(quads[1])
    F.extend(tuple(q) for q in quads[2:])
    check(bm, V, F)


def newell(V, cycle):
    """The Newell vector of a face (gsr_cad's face normal, unnormalised) from the tracked vertices."""
    nx = ny = nz = 0.0
    px, py, pz = V[cycle[-1]].co
    for i in cycle:
        qx, qy, qz = V[i].co
        nx, ny, nz = nx + (py - qy) * (pz + qz), ny + (pz - qz) * (px + qx), nz + (px - qx) * (py + qy)
        px, py, pz = qx, qy, qz
    return Vector((nx, ny, nz))


def region_rim(F, faces):
    """gsr_cad's rim of a region: its faces' half-edges whose other side is outside, in face and corner order,
    and the rim vertices in order of first appearance."""
    own, inside = owners(F), set(faces)
    rim = [(u, v) for f in faces for u, v in zip(F[f], F[f][1:] + F[f][:1]) if own[(v, u)] not in inside]
    starts = {u for u, _ in rim}
    return rim, list(dict.fromkeys(c for f in faces for c in F[f] if c in starts))


def renumber_region(V, F, faces, rim, rim_vertices, copies):
    """Rim vertex copies appended in rim order, the region's faces onto them, one ring quad per rim edge."""
    index = {}
    for v in rim_vertices:
        index[v] = len(V)
        V.append(copies[v])
    for f in faces:
        F[f] = tuple(index.get(c, c) for c in F[f])
    F.extend((u, v, index[v], index[u]) for u, v in rim)


def extrude_region(bm, V, F, faces, distance):
    """X: extrude a region of faces together (extrude_face_region), moved along the unit sum of their Newell
    vectors; inner vertices keep their numbers on Blender's copies of them."""
    rim, rim_vertices = region_rim(F, faces)
    total = Vector((0.0, 0.0, 0.0))
    for f in faces:
        total += newell(V, F[f])
    shift = total.normalized() * distance
    region = [face_of(bm, V, F[f]) for f in faces]
    verts = list(dict.fromkeys(c for f in faces for c in F[f]))
    at = {tuple(V[c].co): c for c in verts}
    edges = list({e for r in region for e in r.edges})
    geom = bmesh.ops.extrude_face_region(bm, geom=region + edges + [V[c] for c in verts], use_keep_orig=False)["geom"]
    new = [g for g in geom if isinstance(g, bmesh.types.BMVert)]
    copies = {at[tuple(n.co)]: n for n in new}
    bmesh.ops.translate(bm, vec=shift, verts=new)
    on_rim = set(rim_vertices)
    for c in verts:
        if c not in on_rim:
            V[c] = copies[c]
    renumber_region(V, F, faces, rim, rim_vertices, copies)
    check(bm, V, F)


def inset_region(bm, V, F, faces, thickness):
    """N: inset a region of faces together (inset_region); each new rim corner is then put where gsr_cad puts it:
    ``thickness`` inside both rim edges at it, in the plane of the unit sum of the Newell vectors of the region's
    faces there (Blender's even offset follows its own rule where the region bends)."""
    rim, rim_vertices = region_rim(F, faces)
    after, before = dict(rim), {v: u for u, v in rim}
    places = {}
    for v in rim_vertices:
        n = Vector((0.0, 0.0, 0.0))
        for f in faces:
            if v in F[f]:
                n += newell(V, F[f])
        n.normalize()
        p = V[v].co.copy()
        a = n.cross(p - V[before[v]].co).normalized()
        b = n.cross(V[after[v]].co - p).normalized()
        m = (a + b).normalized()
        places[v] = p + m * (thickness / m.dot(a))
    at = {v: tuple(V[v].co) for v in rim_vertices}
    region = [face_of(bm, V, F[f]) for f in faces]
    bm.normal_update()
    bmesh.ops.inset_region(bm, faces=region, use_boundary=True, use_even_offset=True, use_interpolate=True,
                           use_relative_offset=False, use_edge_rail=False, thickness=thickness, depth=0.0,
                           use_outset=False)
    on_region = {x for r in region for x in r.verts}
    outer = {}
    for x in bm.verts:  # the outer rim stays where the rim was (Blender keeps the old vertex there or inside)
        if x not in on_region:
            outer.setdefault(tuple(x.co), x)
    copies = {}
    for v in rim_vertices:
        out = outer.get(at[v])
        inner = [e.other_vert(out) for e in out.link_edges if e.other_vert(out) in on_region] if out else []
        if len(inner) != 1:
            raise RuntimeError(f"inset_region: no single inner copy of vertex {v}")
        V[v], copies[v] = out, inner[0]
        copies[v].co = places[v]
    renumber_region(V, F, faces, rim, rim_vertices, copies)
    check(bm, V, F)


def sync_creases(bm, V, rows):
    """Every edge's crease as gsr_cad carried it through the history (Blender's own ops copy creases their
    way): the listed ones, all others 0."""
    layer = bm.edges.layers.crease.verify()
    for edge in bm.edges:
        edge[layer] = 0.0
    set_creases(bm, V, rows)


OPS = {"translate_vertex": translate_vertex, "translate_face": translate_face, "scale": scale, "extrude": extrude,
       "inset": inset, "edge_loop": edge_loop, "bevel": bevel, "crease": crease, "crease_rim": crease_rim,
       "hole": hole, "extrude_region": extrude_region, "inset_region": inset_region}


def snapshot(bm, label, collection):
    """A hidden mesh object holding the control mesh as it is now (one per step of the history)."""
    mesh = bpy.data.meshes.new(label)
    bm.to_mesh(mesh)
    obj = bpy.data.objects.new(label, mesh)
    collection.objects.link(obj)
    obj.hide_set(True)
    obj.hide_render = True
    return obj


def build():
    """Template, then the modelling history (a hidden object per step in the collection "<name> history");
    returns (bm, V, F)."""
    history = bpy.data.collections.new(DATA["name"] + " history")
    bpy.context.scene.collection.children.link(history)
    bm = bmesh.new()
    V = [bm.verts.new(p) for p in DATA["template_vertices"]]
    F = [tuple(cycle) for cycle in DATA["template_faces"]]
    for cycle in F:
        bm.faces.new([V[i] for i in cycle])
    check(bm, V, F)
    snapshot(bm, DATA["template_label"], history)
    for step in DATA["steps"]:
        op = dict(step["op"])
        OPS[op.pop("op")](bm, V, F, **op)
        snapshot(bm, step["label"], history)
    sync_creases(bm, V, DATA.get("creases", []))
    return bm, V, F


def write_obj(path, vertices, faces, comment):
    """A plain OBJ file (1-based faces)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("# %s\n" % comment)
        fh.writelines("v %r %r %r\n" % (x, y, z) for x, y, z in vertices)
        fh.writelines("f " + " ".join(str(i + 1) for i in face) + "\n" for face in faces)


def make_object(bm):
    """Link a new object with the control mesh and its Subdivision Surface modifier to the scene."""
    name = DATA["name"]
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    mod = obj.modifiers.new("Subdivision", "SUBSURF")
    mod.subdivision_type = "CATMULL_CLARK"
    mod.levels = DATA["levels"]
    mod.render_levels = DATA["levels"]
    mod.use_limit_surface = DATA["use_limit_surface"]
    mod.boundary_smooth = DATA["boundary"]
    mod.use_creases = True
    mod.quality = DATA.get("quality", 3)  # 10 with creases: 3 isolates them too little (limit off by 1e-3)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj


def clear_scene():
    """Remove every object of the current file (the factory scene's cube, camera and light)."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)


def main(argv):
    parser = argparse.ArgumentParser(prog="blender -b --python this.py --")
    parser.add_argument("--control", help="write the control mesh (gsr_cad order) to this OBJ file")
    parser.add_argument("--evaluated", help="write the subdivided (evaluated) mesh to this OBJ file")
    parser.add_argument("--blend", help="save the Blender file here")
    args = parser.parse_args(argv[argv.index("--") + 1:] if "--" in argv else [])
    if bpy.app.background:
        clear_scene()
    bm, V, F = build()
    obj = make_object(bm)
    if args.control:
        write_obj(args.control, [tuple(v.co) for v in V], F, "control mesh")
    if args.evaluated:
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        write_obj(args.evaluated, [tuple(v.co) for v in mesh.vertices], [tuple(p.vertices) for p in mesh.polygons],
                  "Subdivision Surface, levels %d" % DATA["levels"])
        evaluated.to_mesh_clear()
    bm.free()
    if args.blend:
        bpy.ops.wm.save_as_mainfile(filepath=args.blend)
    return obj


if __name__ == "__main__":
    main(sys.argv)
