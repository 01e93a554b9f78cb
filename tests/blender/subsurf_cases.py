"""Blender side of tests/test_blender_subsurf.py: evaluate the Subdivision Surface modifier.

Usage: blender -b --factory-startup --python subsurf_cases.py -- CASES.json OUT.npz

CASES.json: {"meshes": {name: {"vertices": [[x, y, z], ...], "faces": [[i, j, k, ...], ...],
"creases": [[a, b, crease], ...] (optional: Blender's edge crease in [0, 1] on edge a-b)}},
"runs": [[name, levels, use_limit_surface, boundary_smooth(, quality)], ...]} (quality 10 unless given). The name "suzanne" means
Blender's own monkey (bpy.ops.mesh.primitive_monkey_add); its control mesh is written too.
OUT.npz holds for every mesh ``NAME/control/vertices|sizes|corners|creases`` (creases: ``(a, b, crease)``
rows as Blender stored them) and for every run ``NAME/LEVELS/LIMIT/BOUNDARY/vertices|sizes|corners`` of the
evaluated mesh (the modifier uses the creases; a run with a quality has ``/QUALITY`` appended to its prefix).
"""

import json
import sys

import bpy
import numpy as np


def mesh_arrays(mesh):
    """Vertices (n, 3), face sizes and the flat corner list of a Blender mesh."""
    verts = np.empty(3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", verts)
    sizes = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_total", sizes)
    starts = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    loops = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loops)
    corners = np.concatenate([loops[s:s + n] for s, n in zip(starts, sizes, strict=True)]) if len(sizes) else loops
    return verts.reshape(-1, 3), sizes, corners


def make_object(name, spec):
    if name == "suzanne":
        bpy.ops.mesh.primitive_monkey_add()
        return bpy.context.active_object
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in spec["vertices"]], [], [tuple(f) for f in spec["faces"]])
    mesh.update()
    index = {tuple(sorted(e.vertices)): e.index for e in mesh.edges}
    for a, b, crease in spec.get("creases", ()):
        mesh.edges[index[tuple(sorted((a, b)))]].crease = crease
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    cases_path, out_path = argv
    with open(cases_path) as fh:
        cases = json.load(fh)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    out = {}
    objects = {}
    for name, spec in cases["meshes"].items():
        obj = make_object(name, spec)
        objects[name] = obj
        for key, arr in zip(("vertices", "sizes", "corners"), mesh_arrays(obj.data), strict=True):
            out[f"{name}/control/{key}"] = arr
        out[f"{name}/control/creases"] = np.array([[*e.vertices, e.crease] for e in obj.data.edges if e.crease > 0],
                                                  dtype=np.float64).reshape(-1, 3)
    for name, levels, limit, boundary, *quality in cases["runs"]:
        obj = objects[name]
        obj.modifiers.clear()
        mod = obj.modifiers.new("subsurf", "SUBSURF")
        mod.subdivision_type = "CATMULL_CLARK"
        mod.levels = levels
        mod.use_limit_surface = limit
        mod.quality = quality[0] if quality else 10
        mod.boundary_smooth = boundary
        mod.use_creases = True
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        for key, arr in zip(("vertices", "sizes", "corners"), mesh_arrays(mesh), strict=True):
            prefix = f"{name}/{levels}/{int(limit)}/{boundary}" + (f"/{quality[0]}" if quality else "")
            out[f"{prefix}/{key}"] = arr
        evaluated.to_mesh_clear()
    np.savez(out_path, **out)


main()
