"""Regenerate the README pictures in docs/ by running the CAD hosts on real gsr_cad results.

    .venv/bin/python docs/make_pictures.py [--work DIR]

1. a curve: ``gsr curve samples/curves/bspline_07.csv`` (seed 1); a surface: ``gsr sample extended`` fitted by
   :func:`gsr_cad.reconstruct.reconstruct_surface` (seed 1, a short run); both exported and validated;
2. Blender (Workbench, headless) renders what the exported ``*_blender.py`` scripts build: the surface with
   its Subdivision Surface modifier and the control cage, the NURBS curve with its control polygon;
3. OpenSCAD renders its own PNG of the exported ``.scad`` (under ``xvfb-run`` when there is no display).
Every picture is what the host itself draws from the exported file; nothing is drawn by gsr_cad.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from gsr_cad.cli import main as gsr
from gsr_cad.cli.formats import export_all, validate_all
from gsr_cad.exporters import hosts
from gsr_cad.reconstruct.surface import reconstruct_surface

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent

_RENDER = r'''
import math
import runpy
import sys

import bpy
from mathutils import Vector

script, png, kind = sys.argv[sys.argv.index("--") + 1:][:3]
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
sys.argv = ["blender"]
runpy.run_path(script, run_name="__main__")
scene = bpy.context.scene
shown = [o for o in scene.objects if not o.hide_render]
main = bpy.context.view_layer.objects.active


def bounds(objs):
    pts = [o.matrix_world @ Vector(c) for o in objs for c in o.bound_box]
    lo = Vector([min(p[i] for p in pts) for i in range(3)])
    hi = Vector([max(p[i] for p in pts) for i in range(3)])
    return lo, hi


lo, hi = bounds(shown)
centre, size = (lo + hi) / 2, (hi - lo).length
if kind == "surface":
    cage = main.copy()
    cage.modifiers.clear()
    scene.collection.objects.link(cage)
    wire = cage.modifiers.new("cage", "WIREFRAME")
    wire.thickness = 0.006 * size
    cage.color = (0.15, 0.15, 0.18, 1.0)
    main.color = (0.95, 0.62, 0.2, 1.0)
    direction = Vector((1.0, -1.3, 0.9)).normalized()
    ortho = False
else:
    main.data.bevel_depth = 0.004 * size
    main.color = (0.85, 0.2, 0.15, 1.0)
    for o in shown:
        if o is not main:
            o.data.bevel_depth = 0.0015 * size
            o.color = (0.3, 0.3, 0.35, 1.0)
    direction = Vector((0.0, 0.0, 1.0))
    ortho = True
cam_data = bpy.data.cameras.new("camera")
camera = bpy.data.objects.new("camera", cam_data)
scene.collection.objects.link(camera)
camera.location = centre + direction * size * 1.6
camera.rotation_euler = (0.0, 0.0, 0.0) if ortho else (-direction).to_track_quat("-Z", "Y").to_euler()
if ortho:
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 1.08 * max(hi.x - lo.x, (hi.y - lo.y) * 4 / 3)
else:
    cam_data.lens = 50
scene.camera = camera
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.light = "STUDIO"
scene.display.shading.color_type = "OBJECT"
scene.display.shading.show_cavity = kind == "surface"
scene.world.color = (1.0, 1.0, 1.0)
scene.render.resolution_x, scene.render.resolution_y = 640, 480
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.compression = 90
scene.render.filepath = png
bpy.ops.render.render(write_still=True)
'''


def _openscad_png(scad: Path, png: Path, top: bool) -> None:
    """OpenSCAD's own preview image of ``scad`` (a virtual display via xvfb-run when there is none)."""
    view = ["--camera", "0,0,0,0,0,0,0", "--projection", "ortho"] if top else ["--camera", "0,0,0,55,0,30,0"]
    cmd = [hosts.find_host("openscad"), "-D", 'part="both"', "-o", str(png), "--imgsize", "640,480", "--viewall",
           "--autocenter", "--colorscheme", "Tomorrow", *view, str(scad)]
    if not os.environ.get("DISPLAY") and shutil.which("xvfb-run"):
        cmd = ["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", *cmd]
    subprocess.run(cmd, check=True, capture_output=True, timeout=300)
    if not png.is_file() or png.stat().st_size == 0:
        raise SystemExit(f"OpenSCAD wrote no image for {scad} (no OpenGL? install xvfb)")


def _validated(out: Path) -> None:
    failing = [c for c in validate_all(out) if c.passed is False]
    if failing:
        raise SystemExit(f"{out}: validation failed: " + "; ".join(f"{c.file} {c.check}" for c in failing))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, help="keep the results here (default: a temporary directory)")
    args = parser.parse_args(argv)
    for host in ("blender", "openscad"):
        if hosts.find_host(host) is None:
            raise SystemExit(f"{host} is not installed")
    work = args.work or Path(tempfile.mkdtemp(prefix="gsr-pictures-"))
    curve, surface = work / "curve", work / "surface"
    if gsr(["curve", str(REPO / "samples/curves/bspline_07.csv"), "-o", str(curve), "--seed", "1",
            "--formats", "blender,scad,fcmacro"]) != 0:
        raise SystemExit("gsr curve failed")
    target = work / "extended.obj"
    if gsr(["sample", "extended", "-o", str(target)]) != 0:
        raise SystemExit("gsr sample failed")
    result = reconstruct_surface(target, seed=1, generations=15, population=30)
    result.save(surface)
    export_all(result, surface, ["blender", "scad", "fcmacro"], stem="surface")
    for out in (curve, surface):
        _validated(out)
    render = work / "render.py"
    render.write_text(_RENDER, encoding="utf-8")
    for kind, out in (("curve", curve), ("surface", surface)):
        hosts.run_blender(render, [out / f"{kind}_blender.py", DOCS / f"{kind}_blender.png", kind], timeout=600)
        _openscad_png(out / f"{kind}.scad", DOCS / f"{kind}_openscad.png", top=kind == "curve")
    for png in sorted(DOCS.glob("*.png")):
        print(f"{png.relative_to(REPO)}: {png.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
