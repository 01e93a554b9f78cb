"""``gsr curve POINTS -o OUT``: reconstruct a control polygon and write result.json, CSV, report and exports."""

from __future__ import annotations

import argparse

from ..reconstruct.config import PRESETS, CurveConfig
from ..reconstruct.curve import reconstruct_curve
from ..reconstruct.inputs import curve_target, load_curve_points
from ..reconstruct.units import resolve_lengths
from ._common import (add_config_flags, config_overrides, html_module, parse_formats, plots_module,
                      prepare_out_dir, write_control_points, write_exports)
from .progress import ga_progress
from .summary import add_model_units, finish


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("curve", help="reconstruct a B-spline/Chaikin control polygon from ordered 2D points",
                       description=__doc__)
    p.add_argument("points", help="ordered x,y points (CSV, TXT or NPY)")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--preset", choices=PRESETS, default="default",
                   help="'paper' reproduces the paper's GA exactly; 'default' adds least-squares placement")
    p.add_argument("--seed", type=int, default=None, help="random seed (same seed, same result)")
    p.add_argument("--truth", help="ground-truth control points (CSV) to draw in the report")
    p.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_config_flags(p, CurveConfig, skip=())
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    target = curve_target(args.points)
    overrides = resolve_lengths(config_overrides(args, CurveConfig), target.diagonal, CurveConfig)
    config = CurveConfig.preset(args.preset, **overrides)
    truth = load_curve_points(args.truth) if args.truth else None
    formats = parse_formats(args.formats, "curve")
    reports = html_module()  # a broken plotly install fails here, before the run
    out = prepare_out_dir(args.out)
    with ga_progress(f"curve {target.name}", enabled=not args.quiet) as on_generation:
        result = reconstruct_curve(target, seed=args.seed, config=config, preset=args.preset,
                                   progress=on_generation)
    add_model_units(result)
    result.save(out)
    write_control_points(out / "control_points.csv", result.control_points)
    plots = plots_module()
    png = plots.curve_report(result, target.points, out / "report.png", truth=truth)
    html = reports.curve_html(result, target.points, out / "report.html", truth=truth)
    written = [png, html, *write_exports(result, out, formats)]
    return finish(result, out, written)

