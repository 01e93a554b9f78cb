"""A gsr_cad result for FreeCAD: the modelling history, and the curve or the limit surface and mesh.

Written by gsr_cad's "fcmacro" exporter; everything specific to this result is in DATA below.

Curves (DATA["kind"] == "curve") get a parametric history: the group "History" holds one FeaturePython
object per step, the template, then one per op, each linked to the step before it ("Base"). An op's
parameters are properties you can edit in FreeCAD ("Index", and "Position" or "Delta"; a corner op has only
"Index"); recomputing the document replays every later op and rebuilds "Curve", the exact B-spline of degree
DATA["degree"] on the last step's points and corners: clamped with evenly spaced distinct knots when open,
periodic when DATA["closed"], every corner a knot of multiplicity degree. Points may be (x, y) or (x, y, z)
(DATA["dimension"]). Every step shows its control polygon (closed when the curve is; all hidden but the last)
and keeps its points in "Points", its corners in "Corners" and its op as JSON in "Op".

Surfaces get a parametric history too, on the connectivity gsr_cad found: one FeaturePython object per
step (the template, then the control mesh after each op, shown as the compound of its face polygons; all
hidden but the last), each linked to the step before; a run of vertex moves is one object ("Vertices",
"Deltas": one entry per move, "Labels"). An op's numbers are editable properties ("Delta",
"Distance", "Thickness", "Offset", "Factor"; its element indices are read-only); recomputing replays every
later op with this file's own copy of gsr_cad's op geometry and rebuilds "LimitMesh", the Catmull-Clark
limit mesh, as fixed weighted sums of the control vertices (DATA["limit_rows"]). "LimitSurface" is the
limit surface as the exported B-spline patches (the same as gsr_cad's STEP export; DATA["patch_deviation"]
is their largest deviation from the exact limit surface), sewn into a shell and, when closed, a solid; it
is not recomputed.

Run: freecadcmd this_file.FCMacro      (GSR_FCSTD=/path/to/file.FCStd, or GSR_ARGS=path, to save the document)
 or: FreeCAD > Macro > Macros... > Execute, or build("/path/to/file.FCStd") from FreeCAD's Python console.
Under freecadcmd an error exits with code 1 (FreeCAD itself would exit 0).
"""
import json
import os
import sys

import FreeCAD as App
import Part
from curve_knots import check_index, distinct, form_knots, periodic_form, with_corner  # gsr:inline

DATA = {}


def _vector(p):
    return App.Vector(p[0], p[1], p[2] if len(p) > 2 else 0.0)


def _pair(v):
    return [v.x, v.y] if DATA["dimension"] == 2 else [v.x, v.y, v.z]


# --- curves: a parametric history ---------------------------------------------------------------------------

def add_point(points, corners, index, position):
    """Insert a control point so that it becomes points[index] (1 <= index <= n - 1, closed: <= n); later
    corners keep their points."""
    check_index("add_point", index, len(points), DATA["closed"])
    return points[:index] + [list(position)] + points[index:], [c + (c >= index) for c in corners]


def move_point(points, corners, index, delta):
    """Translate points[index] by delta (an open curve's end points stay: 1 <= index <= n - 2)."""
    check_index("move_point", index, len(points), DATA["closed"])
    moved = [c + d for c, d in zip(points[index], delta)]
    return points[:index] + [moved] + points[index + 1:], list(corners)


def corner(points, corners, index, _=None):
    """Make points[index] a C0 corner: an interior knot of multiplicity degree (the curve passes through it);
    corners lie at least degree points apart and, on an open curve, degree points from the ends."""
    return list(points), with_corner(corners, index, len(points), DATA["degree"], DATA["closed"])


OPS = {"add_point": (add_point, "Position"), "move_point": (move_point, "Delta"), "corner": (corner, None)}


def curve_form(poles, k, closed, corners):
    """(poles, knots, multiplicities, periodic) of the curve as FreeCAD builds it: clamped when open, periodic on
    one period [0, 1] when closed."""
    if closed:
        return periodic_form(poles, k, corners) + (True,)
    knots, mults = distinct(form_knots(len(poles), k, False, corners))
    return poles, knots, mults, False


class Step:
    """One step of the curve history: the template (no Base) or an op applied to its Base's points."""

    def __init__(self, obj, op=None, points=None):
        obj.addProperty("App::PropertyVectorList", "Points", "gsr_cad", "the control polygon after this step")
        obj.addProperty("App::PropertyIntegerList", "Corners", "gsr_cad", "the corner points after this step")
        obj.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        obj.setEditorMode("Corners", 1)
        if op is not None:
            field = OPS[op["op"]][1]
            obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the step this op applies to")
            obj.addProperty("App::PropertyString", "Kind", "gsr_cad", "add_point, move_point or corner")
            obj.addProperty("App::PropertyInteger", "Index", "gsr_cad", "the control point the op adds, moves or "
                                                                        "makes a corner")
            obj.Kind = op["op"]
            obj.Index = op["index"]
            if field:
                obj.addProperty("App::PropertyVector", field, "gsr_cad", "where to add, or how far to move")
                setattr(obj, field, _vector(op[field.lower()]))
        else:
            obj.Points = [_vector(p) for p in points]
        obj.Proxy = self

    def execute(self, obj):
        if hasattr(obj, "Base"):
            fn, field = OPS[obj.Kind]
            value = _pair(getattr(obj, field)) if field else None
            points, corners = fn([_pair(v) for v in obj.Base.Points], list(obj.Base.Corners), obj.Index, value)
            record = {"op": obj.Kind, "index": obj.Index}
            if field:
                record[field.lower()] = value
            obj.Op = json.dumps(record)
            obj.Points = [_vector(p) for p in points]
            obj.Corners = corners
        pts = list(obj.Points)
        obj.Shape = Part.makePolygon(pts + pts[:1] if DATA["closed"] else pts)


class Curve:
    """The exact B-spline on the points and corners of its Base step: clamped when open, periodic when closed,
    corners as knots of multiplicity Degree."""

    def __init__(self, obj, base):
        obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the last step of the history")
        obj.addProperty("App::PropertyInteger", "Degree", "gsr_cad", "the B-spline degree (3 bspline, 2 chaikin)")
        obj.addProperty("App::PropertyBool", "Closed", "gsr_cad", "a closed (periodic) curve")
        obj.Base = base
        obj.Degree = DATA["degree"]
        obj.Closed = DATA["closed"]
        obj.setEditorMode("Closed", 1)
        obj.Proxy = self

    def execute(self, obj):
        poles, knots, mults, periodic = curve_form(list(obj.Base.Points), obj.Degree, obj.Closed,
                                                   list(obj.Base.Corners))
        spline = Part.BSplineCurve()
        spline.buildFromPolesMultsKnots(poles, mults, knots, periodic, obj.Degree)
        obj.Shape = spline.toShape()


def history_chain(doc, make):
    """One FeaturePython object per step of DATA["steps"] in a "History" group, each linked to the one
    before as its Base; make(obj, number, step) gives each its properties. Returns the steps in order."""
    history = doc.addObject("App::DocumentObjectGroup", "History")
    steps = []
    for number, step in enumerate(DATA["steps"]):
        obj = doc.addObject("Part::FeaturePython", "Step%03d" % number)
        obj.Label = step["label"]
        make(obj, number, step)
        if steps:
            obj.Base = steps[-1]
        history.addObject(obj)
        steps.append(obj)
    return steps


def build_curve(doc):
    steps = history_chain(doc, lambda obj, number, step: Step(obj, step["op"], step["points"]))
    curve = doc.addObject("Part::FeaturePython", "Curve")
    curve.Label = "curve (%s, degree %d)" % (DATA["scheme"], DATA["degree"])
    Curve(curve, steps[-1])
    return steps


# --- surfaces: a parametric history on a fixed connectivity ------------------------------------------------

def _sub(p, q):
    return [p[0] - q[0], p[1] - q[1], p[2] - q[2]]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _norm(a):
    return (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) ** 0.5


def _unit(a):
    n = _norm(a)
    if n == 0.0:
        raise ValueError("a zero-length vector has no direction")
    return [a[0] / n, a[1] / n, a[2] / n]


def _newell(P, cycle):
    """The Newell vector of a face (twice its area along its normal, for a flat face)."""
    nx = ny = nz = 0.0
    px, py, pz = P[cycle[-1]]
    for i in cycle:
        qx, qy, qz = P[i]
        nx += (py - qy) * (pz + qz)
        ny += (pz - qz) * (px + qx)
        nz += (px - qx) * (py + qy)
        px, py, pz = qx, qy, qz
    return [nx, ny, nz]


def _normal(P, cycle):
    """The unit Newell normal of a face."""
    return _unit(_newell(P, cycle))


def _mean_normal(P, cycles):
    """The unit sum of the Newell vectors of faces (a region's normal)."""
    total = [0.0, 0.0, 0.0]
    for cycle in cycles:
        n = _newell(P, cycle)
        total = [total[0] + n[0], total[1] + n[1], total[2] + n[2]]
    return _unit(total)


def _along(P, cycle, distance):
    n = _normal(P, cycle)
    dx, dy, dz = n[0] * distance, n[1] * distance, n[2] * distance
    return [[P[c][0] + dx, P[c][1] + dy, P[c][2] + dz] for c in cycle]


def replay_translate_vertex(P, recipe, vertex, delta):
    p = P[vertex]
    P[vertex] = [p[0] + delta[0], p[1] + delta[1], p[2] + delta[2]]


def replay_translate_face(P, recipe, face, distance):
    for c, q in zip(recipe["cycle"], _along(P, recipe["cycle"], distance)):
        P[c] = q


def replay_scale(P, recipe, factor):
    centre = [(min(p[i] for p in P) + max(p[i] for p in P)) / 2 for i in range(3)]
    P[:] = [[centre[i] + factor * (p[i] - centre[i]) for i in range(3)] for p in P]


def replay_extrude(P, recipe, face, distance):
    P += _along(P, recipe["cycle"], distance)


def replay_inset(P, recipe, face, thickness):
    """Every inner edge `thickness` from its outer edge: corners move along the bisectors of the inward
    edge tangents (Blender's inset_individual with even offset)."""
    cycle = recipe["cycle"]
    n, k = _normal(P, cycle), len(cycle)
    tangents = [_unit(_cross(n, _sub(P[cycle[(i + 1) % k]], P[cycle[i]]))) for i in range(k)]
    inner = []
    for i in range(k):
        a, b = tangents[i - 1], tangents[i]
        m = _unit([a[0] + b[0], a[1] + b[1], a[2] + b[2]])
        s = thickness / (m[0] * a[0] + m[1] * a[1] + m[2] * a[2])
        p = P[cycle[i]]
        inner.append([p[0] + s * m[0], p[1] + s * m[1], p[2] + s * m[2]])
    P += inner


def replay_extrude_region(P, recipe, faces, distance):
    """X: the region's inner vertices move along its mean normal; copies of its rim vertices are appended there."""
    n = _mean_normal(P, recipe["cycles"])
    d = [n[0] * distance, n[1] * distance, n[2] * distance]
    for c in recipe["inner"]:
        P[c] = [P[c][0] + d[0], P[c][1] + d[1], P[c][2] + d[2]]
    P += [[P[c][0] + d[0], P[c][1] + d[1], P[c][2] + d[2]] for c in recipe["rim"]]


def replay_inset_region(P, recipe, faces, thickness):
    """N: each rim corner's copy `thickness` inside both rim edges at it, in the plane of the region's mean
    normal there."""
    inner = []
    for (u, v, w), cycles in zip(recipe["corners"], recipe["around"]):
        n = _mean_normal(P, cycles)
        a = _unit(_cross(n, _sub(P[v], P[u])))
        b = _unit(_cross(n, _sub(P[w], P[v])))
        m = _unit([a[0] + b[0], a[1] + b[1], a[2] + b[2]])
        s = thickness / (m[0] * a[0] + m[1] * a[1] + m[2] * a[2])
        inner.append([P[v][0] + s * m[0], P[v][1] + s * m[1], P[v][2] + s * m[2]])
    P += inner


def replay_edge_loop(P, recipe, edge):
    P += [[0.5 * (P[u][0] + P[v][0]), 0.5 * (P[u][1] + P[v][1]), 0.5 * (P[u][2] + P[v][2])]
          for u, v in recipe["ring"]]


def replay_bevel(P, recipe, edge, offset):
    """Each end of the edge becomes points on its other edges: `offset` from the edge's line on the two edges
    next to it, `offset` along any further edge."""
    a, b = recipe["a"], recipe["b"]

    def end(v, w, entries):
        pv, e_dir, out = P[v], _unit(_sub(P[w], P[v])), []
        for x, adjacent in entries:
            d = _sub(P[x], pv)
            length = _norm(d)
            u = [d[0] / length, d[1] / length, d[2] / length]
            slide = offset / _norm(_cross(u, e_dir)) if adjacent else offset
            out.append([pv[0] + slide * u[0], pv[1] + slide * u[1], pv[2] + slide * u[2]])
        return out

    at_a, at_b = end(a, b, recipe["ends"][0]), end(b, a, recipe["ends"][1])
    at_b = at_b[-1:] + at_b[:-1]
    P[a], P[b] = at_a[0], at_b[0]
    P += at_a[1:] + at_b[1:]


def replay_crease(P, recipe, edge, sharpness):
    """C: an edge's sharpness changes the limit surface, not the control points."""


def replay_crease_rim(P, recipe, face, sharpness):
    """R: the sharpness of a face's rim, likewise."""


def replay_hole(P, recipe, face_a, face_b):
    """H: two faces give way to the bridge quads between their rims; no control point moves or is added."""


# the editable numbers of each op and their property types (other values are read-only: element indices, and
# sharpness, which the fixed limit stencil of the final control mesh already holds)
PARAMETERS = {"translate_vertex": {"delta": "App::PropertyVector"},
              "translate_face": {"distance": "App::PropertyFloat"},
              "scale": {"factor": "App::PropertyFloat"}, "extrude": {"distance": "App::PropertyFloat"},
              "inset": {"thickness": "App::PropertyFloat"}, "edge_loop": {},
              "bevel": {"offset": "App::PropertyFloat"}, "crease": {}, "crease_rim": {}, "hole": {},
              "extrude_region": {"distance": "App::PropertyFloat"}, "inset_region": {"thickness": "App::PropertyFloat"}}


class MeshStep:
    """One step of the surface history: the template (no Base), an op replayed on its Base's control mesh, or
    a run of vertex moves (one object for the run: "Vertices" read-only, "Deltas" editable, "Labels" and, after
    a recompute, "Op" the JSON list of the moves). An op's numbers are editable properties; its element
    indices are fixed (read-only)."""

    def __init__(self, obj, number):
        step = DATA["steps"][number]
        obj.addProperty("App::PropertyInteger", "Number", "gsr_cad", "the step's number in the history")
        obj.addProperty("App::PropertyVectorList", "Points", "gsr_cad", "the control mesh's vertices after this step")
        obj.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        obj.Number = number
        obj.setEditorMode("Number", 1)
        op = step.get("op")
        if "moves" in step:
            obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the step these moves apply to")
            obj.addProperty("App::PropertyStringList", "Labels", "gsr_cad", "each move of the run")
            obj.addProperty("App::PropertyIntegerList", "Vertices", "gsr_cad", "the vertex each move translates")
            obj.addProperty("App::PropertyVectorList", "Deltas", "gsr_cad", "each move's translation (editable)")
            obj.Labels = step["labels"]
            obj.Vertices = [m["vertex"] for m in step["moves"]]
            obj.Deltas = [App.Vector(*m["delta"]) for m in step["moves"]]
            obj.setEditorMode("Labels", 1)
            obj.setEditorMode("Vertices", 1)
        elif op is None:
            obj.Points = [App.Vector(*p) for p in step["vertices"]]
        else:
            obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the step this op applies to")
            for name, value in op.items():
                if name == "op":
                    continue
                kind = PARAMETERS[op["op"]].get(name) or ("App::PropertyFloat" if isinstance(value, float)
                                                          else "App::PropertyIntegerList" if isinstance(value, list)
                                                          else "App::PropertyInteger")
                prop = name.capitalize()
                obj.addProperty(kind, prop, "gsr_cad", "op parameter %s" % name)
                setattr(obj, prop, App.Vector(*value) if kind == "App::PropertyVector" else value)
                if name not in PARAMETERS[op["op"]]:
                    obj.setEditorMode(prop, 1)
        obj.Proxy = self

    def execute(self, obj):
        step = DATA["steps"][obj.Number]
        op = step.get("op")
        if "moves" in step:
            P = [[v.x, v.y, v.z] for v in obj.Base.Points]
            moves = []
            for vertex, d in zip(obj.Vertices, obj.Deltas):
                replay_translate_vertex(P, {}, vertex, [d.x, d.y, d.z])
                moves.append({"op": "translate_vertex", "vertex": vertex, "delta": [d.x, d.y, d.z]})
            obj.Points = [App.Vector(*p) for p in P]
            obj.Op = json.dumps(moves)
        elif op is not None:
            params = {}
            for name in op:
                if name != "op":
                    value = getattr(obj, name.capitalize())
                    params[name] = [value.x, value.y, value.z] if isinstance(value, App.Vector) else value
            P = [[v.x, v.y, v.z] for v in obj.Base.Points]
            globals()["replay_" + op["op"]](P, step["recipe"], **params)
            obj.Points = [App.Vector(*p) for p in P]
            obj.Op = json.dumps(dict({"op": op["op"]}, **params))
        pts = list(obj.Points)
        faces = DATA["topologies"][step["topology"]]
        obj.Shape = Part.Compound([Part.makePolygon([pts[i] for i in f] + [pts[f[0]]]) for f in faces])


class LimitMesh:
    """The Catmull-Clark limit mesh of its Base's control mesh: every limit point is a fixed weighted sum of
    control vertices (the limit stencil of this connectivity), so it follows any edit of the history."""

    def __init__(self, obj, base):
        obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the last step of the history")
        obj.Base = base
        obj.Proxy = self

    def execute(self, obj):
        import Mesh

        P = list(obj.Base.Points)
        points = []
        for cols, weights in DATA["limit_rows"]:
            x = y = z = 0.0
            for c, w in zip(cols, weights):
                x, y, z = x + w * P[c].x, y + w * P[c].y, z + w * P[c].z
            points.append(App.Vector(x, y, z))
        obj.Mesh = Mesh.Mesh((points, [tuple(t) for t in DATA["limit_triangles"]]))


def limit_surface():
    """The exported B-spline patches sewn into a shell (a solid when the shell is closed)."""
    faces = []
    for patch in DATA["patches"]:
        surface = Part.BSplineSurface()
        surface.buildFromPolesMultsKnots([[App.Vector(*p) for p in row] for row in patch["poles"]],
                                         patch["umults"], patch["vmults"], patch["uknots"], patch["vknots"],
                                         False, False, patch["udegree"], patch["vdegree"])
        faces.append(surface.toShape())
    sewn = Part.Compound(faces)
    sewn.sewShape(DATA["sew_tolerance"])
    shell = Part.Shell(sewn.Faces)
    if shell.isClosed():
        solid = Part.Solid(shell)
        if solid.Volume < 0:
            solid.reverse()
        return solid
    return shell


def build_surface(doc):
    steps = history_chain(doc, lambda obj, number, step: MeshStep(obj, number))
    surface = doc.addObject("Part::Feature", "LimitSurface")
    surface.Label = "limit surface (%d B-spline patches, as exported)" % len(DATA["patches"])
    surface.Shape = limit_surface()
    mesh = doc.addObject("Mesh::FeaturePython", "LimitMesh")
    mesh.Label = "limit mesh (%d triangles)" % len(DATA["limit_triangles"])
    LimitMesh(mesh, steps[-1])
    mesh.Visibility = False
    return steps


def build(fcstd_path=None):
    """Make the document; save it to fcstd_path when one is given."""
    doc = App.newDocument(DATA["doc_name"])
    steps = (build_curve if DATA["kind"] == "curve" else build_surface)(doc)
    doc.recompute()
    broken = [obj.Label for obj in doc.Objects if not obj.isValid()]
    if broken:
        raise RuntimeError("recompute failed for %s" % ", ".join(broken))
    for obj in steps[:-1]:
        obj.Visibility = False
    if App.GuiUp:
        import FreeCADGui

        FreeCADGui.SendMsgToActiveView("ViewFit")
    if fcstd_path:
        doc.saveAs(str(fcstd_path))
    return doc


def summary(doc):
    """What was built, as a JSON-ready dict."""
    labels = [label for step in DATA["steps"] for label in step.get("labels", [step["label"]])]
    out = {"document": doc.Name, "file": doc.FileName or None, "kind": DATA["kind"], "steps": len(labels),
           "objects": len(DATA["steps"]), "labels": labels}
    if DATA["kind"] == "curve":
        curve = doc.getObject("Curve").Shape
        out.update(degree=DATA["degree"], poles=len(doc.getObject("Curve").Base.Points), curve_length=curve.Length)
    else:
        shape = doc.getObject("LimitSurface").Shape
        out.update(patches=len(DATA["patches"]), shape=shape.ShapeType, valid=shape.isValid(),
                   volume=shape.Volume if shape.ShapeType == "Solid" else None, area=shape.Area)
    return out


def _path_from_environment():
    args = [a for a in os.environ.get("GSR_ARGS", "").split(os.pathsep) if a]
    return args[0] if args else os.environ.get("GSR_FCSTD")


try:
    print("\n" + json.dumps(summary(build(_path_from_environment()))))
except Exception as exc:
    if App.GuiUp:
        raise
    print("error: %s: %s" % (type(exc).__name__, exc), file=sys.stderr)
    raise SystemExit(1)
