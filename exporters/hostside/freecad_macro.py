"""A gsr_cad result for FreeCAD: the modelling history, and the curve or the limit surface and mesh.

Written by gsr_cad's "fcmacro" exporter; everything specific to this result is in DATA below.

Curves (DATA["kind"] == "curve") get a parametric history: the group "History" holds one FeaturePython
object per step, the template, then one per op, each linked to the step before it ("Base"). An op's
parameters are properties you can edit in FreeCAD ("Index", and "Position" or "Delta"); recomputing the
document replays every later op and rebuilds "Curve", the exact clamped uniform B-spline of degree
DATA["degree"] on the last step's points. Every step shows its control polygon (all hidden but the last)
and keeps its points in "Points" and its op as JSON in "Op".

Surfaces: "History" holds one object per step (the template, then the control mesh after each op, as a
compound of its face polygons; all hidden but the last; its op as JSON in "Op"). "LimitSurface" is the
Catmull-Clark limit surface as B-spline patches (the same as gsr_cad's STEP export; DATA["patch_deviation"]
is their largest deviation from the exact limit surface), sewn into a shell and, when closed, a solid;
"LimitMesh" is the limit mesh (Mesh module).

Run: freecadcmd this_file.FCMacro      (GSR_FCSTD=/path/to/file.FCStd, or GSR_ARGS=path, to save the document)
 or: FreeCAD > Macro > Macros... > Execute, or build("/path/to/file.FCStd") from FreeCAD's Python console.
Under freecadcmd an error exits with code 1 (FreeCAD itself would exit 0).
"""
import json
import os
import sys

import FreeCAD as App
import Part

DATA = {}


def _vector(p):
    return App.Vector(p[0], p[1], p[2] if len(p) > 2 else 0.0)


def _pair(v):
    return [v.x, v.y] if DATA["dimension"] == 2 else [v.x, v.y, v.z]


# --- curves: a parametric history ---------------------------------------------------------------------------

def add_point(points, index, position):
    """Insert a control point so that it becomes points[index] (1 <= index <= n - 1)."""
    if not 1 <= index <= len(points) - 1:
        raise ValueError("add_point index %d outside [1, %d]" % (index, len(points) - 1))
    return points[:index] + [list(position)] + points[index:]


def move_point(points, index, delta):
    """Translate the inner control point points[index] by delta (1 <= index <= n - 2)."""
    if not 1 <= index <= len(points) - 2:
        raise ValueError("move_point index %d outside [1, %d]" % (index, len(points) - 2))
    moved = [c + d for c, d in zip(points[index], delta)]
    return points[:index] + [moved] + points[index + 1:]


OPS = {"add_point": (add_point, "Position"), "move_point": (move_point, "Delta")}


def clamped_knots(n, degree):
    """Distinct knots and multiplicities of the clamped uniform knot vector of n poles on [0, 1]."""
    spans = n - degree
    return [i / spans for i in range(spans + 1)], [degree + 1] + [1] * (spans - 1) + [degree + 1]


class Step:
    """One step of the curve history: the template (no Base) or an op applied to its Base's points."""

    def __init__(self, obj, op=None, points=None):
        obj.addProperty("App::PropertyVectorList", "Points", "gsr_cad", "the control polygon after this step")
        obj.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        if op is not None:
            obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the step this op applies to")
            obj.addProperty("App::PropertyString", "Kind", "gsr_cad", "add_point or move_point")
            obj.addProperty("App::PropertyInteger", "Index", "gsr_cad", "the control point the op adds or moves")
            obj.addProperty("App::PropertyVector", OPS[op["op"]][1], "gsr_cad", "where to add, or how far to move")
            obj.Kind = op["op"]
            obj.Index = op["index"]
            setattr(obj, OPS[op["op"]][1], _vector(op["position"] if op["op"] == "add_point" else op["delta"]))
        else:
            obj.Points = [_vector(p) for p in points]
        obj.Proxy = self

    def execute(self, obj):
        if hasattr(obj, "Base"):
            fn, field = OPS[obj.Kind]
            value = _pair(getattr(obj, field))
            points = fn([_pair(v) for v in obj.Base.Points], obj.Index, value)
            obj.Op = json.dumps({"op": obj.Kind, "index": obj.Index, field.lower(): value})
            obj.Points = [_vector(p) for p in points]
        obj.Shape = Part.makePolygon(list(obj.Points))


class Curve:
    """The clamped uniform B-spline on the points of its Base step."""

    def __init__(self, obj, base):
        obj.addProperty("App::PropertyLink", "Base", "gsr_cad", "the last step of the history")
        obj.addProperty("App::PropertyInteger", "Degree", "gsr_cad", "the B-spline degree (3 bspline, 2 chaikin)")
        obj.Base = base
        obj.Degree = DATA["degree"]
        obj.Proxy = self

    def execute(self, obj):
        poles = list(obj.Base.Points)
        knots, mults = clamped_knots(len(poles), obj.Degree)
        spline = Part.BSplineCurve()
        spline.buildFromPolesMultsKnots(poles, mults, knots, False, obj.Degree)
        obj.Shape = spline.toShape()


def build_curve(doc):
    history = doc.addObject("App::DocumentObjectGroup", "History")
    steps = []
    for number, step in enumerate(DATA["steps"]):
        obj = doc.addObject("Part::FeaturePython", "Step%03d" % number)
        obj.Label = step["label"]
        Step(obj, step["op"], step["points"])
        if steps:
            obj.Base = steps[-1]
        history.addObject(obj)
        steps.append(obj)
    curve = doc.addObject("Part::FeaturePython", "Curve")
    curve.Label = "curve (%s, degree %d)" % (DATA["scheme"], DATA["degree"])
    Curve(curve, steps[-1])
    return steps


# --- surfaces ---------------------------------------------------------------------------------------------

def cage_shape(vertices, faces):
    """The control mesh as a compound of closed face polygons."""
    pts = [App.Vector(*p) for p in vertices]
    return Part.Compound([Part.makePolygon([pts[i] for i in face] + [pts[face[0]]]) for face in faces])


def limit_surface():
    """The B-spline patches sewn into a shell (a solid when the shell is closed)."""
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
    import Mesh

    history = doc.addObject("App::DocumentObjectGroup", "History")
    steps = []
    for number, step in enumerate(DATA["steps"]):
        obj = doc.addObject("Part::Feature", "Step%03d" % number)
        obj.Label = step["label"]
        obj.addProperty("App::PropertyString", "Op", "gsr_cad", "the modelling op of this step (JSON)")
        obj.Op = "" if step["op"] is None else json.dumps(step["op"])
        obj.Shape = cage_shape(step["vertices"], step["faces"])
        history.addObject(obj)
        steps.append(obj)
    surface = doc.addObject("Part::Feature", "LimitSurface")
    surface.Label = "limit surface (%d B-spline patches)" % len(DATA["patches"])
    surface.Shape = limit_surface()
    mesh = doc.addObject("Mesh::Feature", "LimitMesh")
    mesh.Label = "limit mesh (%d triangles)" % len(DATA["limit_triangles"])
    points = [App.Vector(*p) for p in DATA["limit_points"]]
    mesh.Mesh = Mesh.Mesh((points, [tuple(t) for t in DATA["limit_triangles"]]))
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
    out = {"document": doc.Name, "file": doc.FileName or None, "kind": DATA["kind"], "steps": len(DATA["steps"]),
           "labels": [step["label"] for step in DATA["steps"]]}
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
