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
from ..reconstruct.inputs import load_template, surface_target
from ..reconstruct.meshio import save_obj
from ..reconstruct.surface import reconstruct_surface
from ._common import (add_config_flags, config_overrides, parse_formats, plots_module, prepare_out_dir,
                      write_exports)
from .progress import ga_progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("surface", help="reconstruct a Catmull-Clark control mesh from a mesh or point cloud",
                       description=__doc__.splitlines()[0])
    p.add_argument("target", help="a mesh (OBJ, PLY, STL, OFF) or point cloud (XYZ, CSV, TXT, PTS, NPY, or "
                                  "an OBJ/PLY without faces)")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--template", default="cube",
                   help="'cube' (a cube whose limit surface fills the target's box) or a quad mesh file")
    p.add_argument("--preset", choices=PRESETS, default="default",
                   help="'paper' reproduces the paper's GA (mixed mean distance, no polish); 'default' adds "
                        "the point-to-surface fitness and the least-squares polish")
    p.add_argument("--seed", type=int, default=None, help="random seed (same seed, same result)")
    p.add_argument("--workers", type=int, default=1, help="evaluate genomes on this many processes (default 1)")
    p.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_config_flags(p, SurfaceConfig)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    target = surface_target(args.target)
    config = SurfaceConfig.preset(args.preset, **config_overrides(args, SurfaceConfig))
    if args.template != "cube":
        load_template(args.template)  # a bad template file fails here, before any output
    if args.workers < 1:
        raise ConfigError(f"workers must be at least 1, not {args.workers}")
    formats = parse_formats(args.formats, "surface")
    out = prepare_out_dir(args.out)
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(ProcessPoolEvaluator(max_workers=args.workers)) if args.workers > 1 else None
        on_generation = stack.enter_context(ga_progress(f"surface {target.name}", enabled=not args.quiet))
        result = reconstruct_surface(target, template=args.template, seed=args.seed, config=config,
                                     preset=args.preset, progress=on_generation, evaluator=pool)
    written = [result.save(out), save_obj(result.control_mesh, out / "control_mesh.obj"),
               save_obj(limit_mesh(result.control_mesh, config.levels, config.boundary), out / "limit_mesh.obj")]
    plots = plots_module()
    written.append(plots.surface_report(result, out / "report.png"))
    written += write_exports(result, out, formats)
    m = result.metrics
    status = "interrupted: best so far" if result.interrupted else "done"
    print(f"{status}: {m['n_control_faces']} control faces, {m['n_control_vertices']} vertices, "
          f"ops {plots.run_length(m['ops']) or '-'}; "
          f"data->fit mean {m['data_to_fit_mean']:.3g} (max {m['data_to_fit_max']:.3g}), fit->data mean "
          f"{m['fit_to_data_mean']:.3g} (max {m['fit_to_data_max']:.3g}) of the diagonal "
          f"(mixed mean {m['mixed_mean_distance']:.3g}), {m['seconds']:.1f} s -> {out}")
    for path in written:
        print(f"  wrote {path}")
    if m.get("tolerance_met") is False:
        print(f"error: no cage on the front met --max-distance {config.max_distance:g} (best: "
              f"{m['fitness']:.3g})")
        return 3
    return 0
