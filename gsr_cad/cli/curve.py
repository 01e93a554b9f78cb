"""``gsr curve POINTS -o OUT``: reconstruct a control polygon and write result.json, CSV, report and exports."""

from __future__ import annotations

import argparse

from ..reconstruct.config import PRESETS, CurveConfig
from ..reconstruct.curve import reconstruct_curve
from ..reconstruct.inputs import curve_target, load_curve_points
from ..reconstruct.units import resolve_lengths
from ._common import (add_config_flags, add_run_flags, check_run_args, config_overrides, html_module, output_dir,
                      parse_formats, plots_module, save_run_args, searching, settle_stop, write_control_points,
                      write_exports, write_outputs)
from .summary import add_model_units, finish


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("curve", help="reconstruct a B-spline/Chaikin control polygon from ordered 2D points",
                       description=__doc__)
    p.add_argument("points", help="ordered x,y points (CSV, TXT or NPY)")
    p.add_argument("--preset", choices=PRESETS, default="default",
                   help="'paper' reproduces the paper's GA exactly; 'default' adds least-squares placement")
    p.add_argument("--truth", help="ground-truth control points (CSV) to draw in the report")
    add_run_flags(p)
    add_config_flags(p, CurveConfig, skip=())
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    target = curve_target(args.points)
    overrides = resolve_lengths(config_overrides(args, CurveConfig), target.diagonal, CurveConfig)
    config = CurveConfig.preset(args.preset, **overrides)
    check_run_args(args)
    truth = load_curve_points(args.truth) if args.truth else None
    formats = parse_formats(args.formats, "curve")
    reports = html_module()  # a broken plotly install fails here, before the run
    with output_dir(args.out) as out:
        if args.checkpoint:
            save_run_args(out, args)
        with searching(f"curve {target.name}", args.quiet, config.max_seconds) as (progress, should_stop):
            result = reconstruct_curve(target, seed=args.seed, config=config, preset=args.preset,
                                       progress=progress, should_stop=should_stop, checkpoint=args.checkpoint)
    settle_stop(result)
    add_model_units(result)
    written = write_outputs(progress, [
        ("writing result.json", lambda: result.save(out)),
        ("writing control_points.csv",
         lambda: write_control_points(out / "control_points.csv", result.control_points)),
        ("drawing report.png",
         lambda: plots_module().curve_report(result, target.points, out / "report.png", truth=truth)),
        ("drawing report.html",
         lambda: reports.curve_html(result, target.points, out / "report.html", truth=truth)),
        ("writing the exports", lambda: write_exports(result, out, formats)),
    ])
    return finish(result, out, written[2:])
