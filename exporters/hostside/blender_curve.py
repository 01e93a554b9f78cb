"""A gsr_cad curve for Blender 3.4: the modelling history replayed, then the exact curve as a Bezier spline.

Written by gsr_cad's "blender" exporter; everything specific to this curve is in DATA below. The history
is replayed op by op (add, move, corner; each only where gsr_cad allows it, else ValueError) on the template
polygon: after every step a hidden poly-curve object named after it (in the collection "<name> history"; the
last step stays visible as the control polygon) shows the control polygon at that point. The curve is the B-spline of DATA["degree"] on the last
polygon, open (clamped) or closed (periodic, DATA["closed"]), every corner a knot of multiplicity degree,
in the plane or in space. Blender's NURBS cannot repeat interior knots, so the script converts the B-spline
into its exact Bezier pieces (knot insertion; quadratic pieces raised to cubic) and builds a Bezier spline
with free handles, cyclic when closed. Edit an op in DATA["steps"] and run the script again.

Run it in Blender's Text Editor, or headless:
    blender -b --factory-startup --python this_file.py -- [--json built.json] [--blend out.blend]
"""

import argparse
import json
import sys

import bpy
from curve_knots import bezier_pieces, check_index, with_corner  # gsr:inline

DATA = {}


def add_point(points, corners, index, position):
    """Insert a control point so that it becomes points[index] (1 <= index <= n - 1, closed: <= n); later
    corners keep their points."""
    check_index("add_point", index, len(points), DATA["closed"])
    points.insert(index, tuple(position))
    corners[:] = [c + (c >= index) for c in corners]


def move_point(points, corners, index, delta):
    """Translate points[index] by delta (an open curve's end points stay: 1 <= index <= n - 2)."""
    check_index("move_point", index, len(points), DATA["closed"])
    points[index] = tuple(c + d for c, d in zip(points[index], delta))


def corner(points, corners, index):
    """Make points[index] a C0 corner (a knot of multiplicity degree): at least degree points from every other
    corner and, on an open curve, from the ends."""
    corners[:] = with_corner(corners, index, len(points), DATA["degree"], DATA["closed"])


OPS = {"add_point": add_point, "move_point": move_point, "corner": corner}


def _xyz(p):
    return (float(p[0]), float(p[1]), float(p[2]) if len(p) > 2 else 0.0)


def cubic(piece):
    """A quadratic Bezier piece raised exactly to a cubic one (cubic pieces are kept)."""
    if len(piece) == 4:
        return piece
    p0, p1, p2 = piece
    return [p0, tuple(a + 2.0 * (b - a) / 3.0 for a, b in zip(p0, p1)),
            tuple(c + 2.0 * (b - c) / 3.0 for b, c in zip(p1, p2)), p2]


def polygon_object(name, points, collection):
    """The control polygon through `points` as a poly curve (cyclic when the curve is closed)."""
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new("POLY")
    spline.points.add(len(points) - 1)
    for p, q in zip(spline.points, points):
        p.co = (*_xyz(q), 1.0)
    spline.use_cyclic_u = DATA["closed"]
    obj = bpy.data.objects.new(name, data)
    collection.objects.link(obj)
    return obj


def curve_object(name, points, corners, collection):
    """The exact curve as a Bezier spline (free handles), one segment per knot span, cyclic when closed."""
    pieces = [cubic(p) for p in bezier_pieces([_xyz(p) for p in points], DATA["degree"], DATA["closed"], corners)]
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new("BEZIER")
    knots = [p[0] for p in pieces] + ([] if DATA["closed"] else [pieces[-1][3]])
    spline.bezier_points.add(len(knots) - 1)
    m = len(pieces)
    for j, (b, co) in enumerate(zip(spline.bezier_points, knots)):
        b.handle_left_type = b.handle_right_type = "FREE"
        b.co = co
        b.handle_right = pieces[j][1] if j < m else co
        b.handle_left = pieces[j - 1][2] if (j > 0 or DATA["closed"]) else co
    spline.use_cyclic_u = DATA["closed"]
    spline.resolution_u = DATA["resolution"]
    obj = bpy.data.objects.new(name, data)
    collection.objects.link(obj)
    return obj


def clear_scene():
    """Remove every object of the current file (the factory scene's cube, camera and light)."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)


def build():
    """The history objects and the curve; returns (curve object, history objects)."""
    name = DATA["name"]
    scene = bpy.context.scene
    history = bpy.data.collections.new(name + " history")
    scene.collection.children.link(history)
    points, corners = [tuple(p) for p in DATA["template"]], []
    steps = []
    for step in DATA["steps"]:
        op = step["op"]
        if op is not None:
            OPS[op["op"]](points, corners, **{k: v for k, v in op.items() if k != "op"})
        steps.append(polygon_object(step["label"], points, history))
    for obj in steps[:-1]:
        obj.hide_set(True)
        obj.hide_render = True
    curve = curve_object(name, points, corners, scene.collection)
    bpy.context.view_layer.objects.active = curve
    curve.select_set(True)
    return curve, steps


def describe(curve, steps):
    """What Blender built, as JSON-ready data (Bezier points and handles, settings, evaluated points, history)."""
    spline = curve.data.splines[0]
    bezier = [[list(b.handle_left), list(b.co), list(b.handle_right)] for b in spline.bezier_points]
    evaluated = curve.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    samples = [list(v.co) for v in mesh.vertices]
    evaluated.to_mesh_clear()
    return {"name": curve.name, "type": spline.type, "cyclic": bool(spline.use_cyclic_u),
            "resolution": spline.resolution_u, "bezier": bezier,
            "handle_types": sorted(set(t for b in spline.bezier_points for t in (b.handle_left_type,
                                                                                 b.handle_right_type))),
            "samples": samples,
            "history": [{"name": o.name, "hidden": bool(o.hide_get()),
                         "points": [list(p.co) for p in o.data.splines[0].points]} for o in steps]}


def main(argv):
    parser = argparse.ArgumentParser(prog="blender -b --python this.py --")
    parser.add_argument("--json", help="write what Blender built to this JSON file")
    parser.add_argument("--blend", help="save the Blender file here")
    args = parser.parse_args(argv[argv.index("--") + 1:] if "--" in argv else [])
    if bpy.app.background:
        clear_scene()
    curve, steps = build()
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(describe(curve, steps), fh)
    if args.blend:
        bpy.ops.wm.save_as_mainfile(filepath=args.blend)
    return curve


if __name__ == "__main__":
    main(sys.argv)
