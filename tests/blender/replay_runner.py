"""Run many generated Blender replay scripts in ONE Blender process (startup costs seconds).

Usage: blender -b --factory-startup --python replay_runner.py -- MANIFEST.json RESULTS.json
MANIFEST is a list of {"script": path, "args": [script arguments]}; each script runs as __main__ on an
emptied scene with those arguments after "--". RESULTS gets one {"script", "error", "objects"} per job:
error is None or the exception's message; objects describes what the script left in the scene
(name, control vertex and face counts, and its modifiers' settings).
"""

import json
import runpy
import sys
import traceback

import bpy


def empty_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)
    for collection in list(bpy.data.collections):
        bpy.data.collections.remove(collection)


def describe_objects():
    out = []
    for obj in bpy.data.objects:
        mods = [{"type": m.type, "levels": m.levels, "render_levels": m.render_levels,
                 "use_limit_surface": m.use_limit_surface, "boundary_smooth": m.boundary_smooth}
                for m in obj.modifiers if m.type == "SUBSURF"]
        out.append({"name": obj.name, "vertices": len(obj.data.vertices), "faces": len(obj.data.polygons),
                    "in_scene": obj.name in bpy.context.scene.objects, "modifiers": mods,
                    "hidden": bool(obj.hide_get()), "collections": [c.name for c in obj.users_collection]})
    return out


def main(argv):
    manifest, results = argv[argv.index("--") + 1:][:2]
    with open(manifest, encoding="utf-8") as fh:
        jobs = json.load(fh)
    out = []
    saved = list(sys.argv)
    for job in jobs:
        empty_scene()
        sys.argv = ["blender", "--", *job["args"]]
        try:
            runpy.run_path(job["script"], run_name="__main__")
            error = None
        except Exception as exc:  # one failing script must not hide the others
            error = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        out.append({"script": job["script"], "error": error, "objects": describe_objects()})
    sys.argv = saved
    with open(results, "w", encoding="utf-8") as fh:
        json.dump(out, fh)


main(sys.argv)
