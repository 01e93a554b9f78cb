"""``gsr surface TARGET -o OUT``: reconstruct a control mesh and write result.json, OBJs, report and exports.

Writes ``result.json``, ``control_mesh.obj``, ``limit_mesh.obj``, ``report.png`` (the paper's Figure 5
layout) and the exports (by default every installed format, the Blender replay script among them).
Bad input stops before anything is written; Ctrl-C during the search keeps the best genome so far.
"""

from __future__ import annotations

import argparse
import contextlib

from ..errors import ConfigError
from ..ga import ProcessPoolEvaluator
from ..geometry.subdivision import limit_mesh
from ..reconstruct.config import PRESETS, SurfaceConfig
from ..reconstruct.inputs import surface_target
from ..reconstruct.meshio import save_obj
from ..reconstruct.surface import make_template, reconstruct_surface
from ..reconstruct.units import resolve_lengths
from ._common import (add_config_flags, add_run_flags, check_run_args, config_overrides, html_module, output_dir,
                      parse_formats, plots_module, save_run_args, searching, settle_stop, whole_number,
                      write_exports, write_outputs)
from .summary import add_model_units, finish, template_warning, warn

MAX_WORKERS = 256


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("surface", help="reconstruct a Catmull-Clark control mesh from a mesh or point cloud",
                       description=__doc__.splitlines()[0])
    p.add_argument("target", help="a mesh (OBJ, PLY, STL, OFF) or point cloud (XYZ, CSV, TXT, PTS, NPY, or "
                                  "an OBJ/PLY without faces)")
    p.add_argument("--template", default="cube",
                   help="'cube' (a cube whose limit surface fills the target's box) or a quad mesh file")
    p.add_argument("--preset", choices=PRESETS, default="default",
                   help="'paper' reproduces the paper's GA (mixed mean distance, no polish); 'default' adds "
                        "the point-to-surface fitness and the least-squares polish")
    p.add_argument("--workers", type=whole_number, default=1,
                   help=f"evaluate genomes on this many processes (default 1, at most {MAX_WORKERS})")
    add_run_flags(p)
    add_config_flags(p, SurfaceConfig)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    target = surface_target(args.target)
    overrides = resolve_lengths(config_overrides(args, SurfaceConfig), target.diagonal, SurfaceConfig)
    config = SurfaceConfig.preset(args.preset, **overrides)
    check_run_args(args)
    template = make_template(args.template, target, config)  # a bad template file fails here, before any output
    warn(template_warning(template, target, args.template))
    if not 1 <= args.workers <= MAX_WORKERS:
        raise ConfigError(f"workers must lie in [1, {MAX_WORKERS}], not {args.workers}")
    formats = parse_formats(args.formats, "surface")
    reports = html_module()  # a broken plotly install fails here, before the run
    with output_dir(args.out) as out, contextlib.ExitStack() as stack:
        if args.checkpoint:
            save_run_args(out, args)
        pool = stack.enter_context(ProcessPoolEvaluator(max_workers=args.workers)) if args.workers > 1 else None
        progress, should_stop = stack.enter_context(searching(f"surface {target.name}", args.quiet,
                                                              config.max_seconds))
        result = reconstruct_surface(target, template=args.template, seed=args.seed, config=config,
                                     preset=args.preset, progress=progress, evaluator=pool,
                                     should_stop=should_stop, checkpoint=args.checkpoint)
    settle_stop(result)
    add_model_units(result)
    written = write_outputs(progress, [
        ("writing result.json", lambda: result.save(out)),
        ("writing control_mesh.obj", lambda: save_obj(result.control_mesh, out / "control_mesh.obj")),
        ("writing limit_mesh.obj", lambda: save_obj(limit_mesh(result.control_mesh, config.levels, config.boundary),
                                                    out / "limit_mesh.obj")),
        ("drawing report.png", lambda: plots_module().surface_report(result, out / "report.png")),
        ("drawing report.html", lambda: reports.surface_html(result, out / "report.html")),
        ("writing the exports", lambda: write_exports(result, out, formats)),
    ])
    return finish(result, out, written)
