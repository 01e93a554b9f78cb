"""``gsr curve POINTS -o OUT``: reconstruct a control polygon and write result.json, CSV, report and exports.

Exit codes: 0 done, 2 bad input or settings, 3 finished but the requested --max-distance was not met both ways
(data -> curve or curve -> data, on all points; the result is still written).
"""

from __future__ import annotations

import argparse
import sys
import warnings

from ..reconstruct.config import PRESETS, CurveConfig
from ..reconstruct.curve import CurveWarning, reconstruct_curve
from ..reconstruct.inputs import curve_target, load_curve_points
from ..reconstruct.units import resolve_lengths
from ._common import (add_config_flags, add_run_flags, check_run_args, config_overrides, html_module, output_dir,
                      parse_formats, plots_module, report_points, save_run_args, searching, settle_stop,
                      write_control_points, write_exports, write_outputs)
from .summary import add_model_units, finish


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("curve", help="reconstruct a B-spline/Chaikin control polygon from ordered 2D or 3D points",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("points", help="ordered x,y or x,y,z points (CSV, TXT or NPY)")
    closure = p.add_mutually_exclusive_group()
    closure.add_argument("--closed", dest="closure_flag", action="store_const", const="closed",
                         help="fit a closed (periodic) curve (default: detected from the data)")
    closure.add_argument("--open", dest="closure_flag", action="store_const", const="open",
                         help="fit an open curve even when the data close")
    p.add_argument("--preset", choices=PRESETS, default="default",
                   help="'paper' reproduces the paper's GA exactly; 'default' adds least-squares placement")
    p.add_argument("--truth", help="ground-truth control points (CSV) to draw in the report")
    add_run_flags(p)
    add_config_flags(p, CurveConfig, skip=())
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    target = curve_target(args.points)
    overrides = resolve_lengths(config_overrides(args, CurveConfig), target.diagonal, CurveConfig)
    if args.closure_flag:
        overrides["closure"] = args.closure_flag
    config = CurveConfig.preset(args.preset, **overrides)
    check_run_args(args)
    truth = load_curve_points(args.truth) if args.truth else None
    formats = parse_formats(args.formats, "curve")
    reports = html_module()  # a broken plotly install fails here, before the run
    with output_dir(args.out) as out:
        if args.checkpoint:
            save_run_args(out, args)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", CurveWarning)
            with searching(f"curve {target.name}", args.quiet, config.max_seconds) as (progress, should_stop):
                result = reconstruct_curve(target, seed=args.seed, config=config, preset=args.preset,
                                           progress=progress, should_stop=should_stop, checkpoint=args.checkpoint)
    for w in caught:  # a missed tolerance is reported by finish(); the others (reordered points) here
        if issubclass(w.category, CurveWarning) and "misses the requested" not in str(w.message):
            print(f"warning: {w.message}", file=sys.stderr)
    settle_stop(result)
    add_model_units(result)
    drawn = report_points(target.points)
    written = write_outputs(progress, [
        ("writing result.json", lambda: result.save(out)),
        ("writing control_points.csv",
         lambda: write_control_points(out / "control_points.csv", result.control_points)),
        ("drawing report.png",
         lambda: plots_module().curve_report(result, drawn, out / "report.png", truth=truth)),
        ("drawing report.html",
         lambda: reports.curve_html(result, drawn, out / "report.html", truth=truth)),
        ("writing the exports", lambda: write_exports(result, out, formats)),
    ])
    return finish(result, out, written[2:])
