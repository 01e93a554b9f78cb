"""Read back what FreeCAD sees in a gsr_cad document or a STEP file (gsr_cad's host checks run this).

Arguments come through GSR_ARGS (source path, output JSON path, separated by os.pathsep); DATA holds the
curve parameters and the patch grid at which FreeCAD evaluates B-splines. An .FCStd gives its "History"
steps and its "Curve", "LimitSurface" and "LimitMesh" objects; any other file is read with Part.read
and gives every edge as a curve. Errors exit with code 1.
"""
import json
import os
import sys

import FreeCAD as App
import Part

DATA = {}


def dump_curve(edge, params):
    c = edge.Curve
    if c.TypeId != "Part::GeomBSplineCurve":
        return {"type": c.TypeId}
    return {"degree": c.Degree, "rational": bool(c.isRational()),
            "poles": [[p.x, p.y, p.z] for p in c.getPoles()], "knots": c.getKnots(),
            "mults": c.getMultiplicities(), "range": list(edge.ParameterRange), "periodic": bool(c.isPeriodic()),
            "closed": bool(c.isClosed()),
            "samples": [[p.x, p.y, p.z] for p in (c.value(u) for u in params)]}


def dump_face(face, grid):
    s = face.Surface
    if s.TypeId != "Part::GeomBSplineSurface":
        return {"type": s.TypeId}
    return {"type": s.TypeId, "degrees": [s.UDegree, s.VDegree],
            "rational": bool(s.isURational() or s.isVRational()),
            "poles": [[[p.x, p.y, p.z] for p in row] for row in s.getPoles()],
            "uknots": s.getUKnots(), "umults": s.getUMultiplicities(),
            "vknots": s.getVKnots(), "vmults": s.getVMultiplicities(),
            "range": list(face.ParameterRange),
            "samples": [[[p.x, p.y, p.z] for p in (s.value(u, v) for v in grid)] for u in grid]}


def dump_document(doc):
    history = doc.getObject("History")
    steps = []
    for o in (history.Group if history else []):
        shape = getattr(o, "Shape", None)
        steps.append({"label": o.Label, "type": o.TypeId, "visible": bool(o.Visibility),
                      "op": getattr(o, "Op", None), "labels": list(getattr(o, "Labels", [])),
                      "corners": list(getattr(o, "Corners", [])),
                      "nodes": [[v.x, v.y, v.z] for v in getattr(o, "Points", getattr(o, "Nodes", []))],
                      "wires": [[[v.X, v.Y, v.Z] for v in w.OrderedVertexes] for w in shape.Wires] if shape else []})
    data = {"steps": steps, "curve": None, "surface": None, "mesh": None}
    feature = doc.getObject("Curve")
    if feature is not None and feature.Shape.Edges:
        data["curve"] = dump_curve(feature.Shape.Edges[0], DATA["params"])
    feature = doc.getObject("LimitSurface")
    if feature is not None:
        shape = feature.Shape
        data["surface"] = {"type": shape.ShapeType, "valid": shape.isValid(), "closed": shape.isClosed(),
                           "shells": len(shape.Shells), "volume": shape.Volume,
                           "faces": [dump_face(f, DATA["grid"]) for f in shape.Faces]}
    mesh = doc.getObject("LimitMesh")
    if mesh is not None:
        points, facets = mesh.Mesh.Topology
        data["mesh"] = {"points": [[p.x, p.y, p.z] for p in points], "facets": [list(f) for f in facets],
                        "visible": bool(mesh.Visibility)}
    return data


try:
    source, out = os.environ["GSR_ARGS"].split(os.pathsep)[:2]
    if source.lower().endswith(".fcstd"):
        result = dump_document(App.openDocument(source))
    else:
        result = {"curves": [dump_curve(e, DATA["params"]) for e in Part.read(source).Edges]}
    with open(out, "w") as fh:
        json.dump(result, fh)
except Exception as exc:
    print("error: %s: %s" % (type(exc).__name__, exc), file=sys.stderr)
    raise SystemExit(1)
