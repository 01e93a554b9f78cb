"""A gsr_cad curve for Blender 3.4: the modelling history replayed, then the NURBS curve.

Written by gsr_cad's "blender" exporter; everything specific to this curve is in DATA below. The history
is replayed op by op on the template polygon: after every step a hidden poly-curve object named after it
(in the collection "<name> history"; the last step stays visible as the control polygon) shows the
control polygon at that point. The result is a NURBS curve with endpoint knots: exactly the clamped
uniform B-spline of DATA["degree"]. Edit an op in DATA["steps"] and run the script again.

Run it in Blender's Text Editor, or headless:
    blender -b --factory-startup --python this_file.py -- [--json built.json] [--blend out.blend]
"""

import argparse
import json
import sys

import bpy

DATA = {}


def add_point(points, index, position):
    """Insert a control point so that it becomes points[index]."""
    points.insert(index, tuple(position))


def move_point(points, index, delta):
    """Translate points[index] by delta."""
    points[index] = tuple(c + d for c, d in zip(points[index], delta))


OPS = {"add_point": add_point, "move_point": move_point}


def _xyz(p):
    return (float(p[0]), float(p[1]), float(p[2]) if len(p) > 2 else 0.0)


def curve_object(name, points, kind, collection):
    """A curve object through `points`: kind "POLY" (control polygon) or "NURBS"."""
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    spline = data.splines.new(kind)
    spline.points.add(len(points) - 1)
    for p, q in zip(spline.points, points):
        p.co = (*_xyz(q), 1.0)
    if kind == "NURBS":
        spline.order_u = DATA["degree"] + 1
        spline.use_endpoint_u = True
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
    points = [tuple(p) for p in DATA["template"]]
    steps = []
    for step in DATA["steps"]:
        op = step["op"]
        if op is not None:
            OPS[op["op"]](points, **{k: v for k, v in op.items() if k != "op"})
        steps.append(curve_object(step["label"], points, "POLY", history))
    for obj in steps[:-1]:
        obj.hide_set(True)
        obj.hide_render = True
    curve = curve_object(name, points, "NURBS", scene.collection)
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
    return {"name": curve.name, "type": spline.type, "order": spline.order_u,
            "endpoint": bool(spline.use_endpoint_u), "cyclic": bool(spline.use_cyclic_u),
            "resolution": spline.resolution_u, "poles": [list(p.co) for p in spline.points],
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
