"""``gsr curve POINTS -o OUT``: reconstruct a control polygon and write result.json, CSV, report and exports.

Exit codes: 0 done, 2 bad input or settings, 3 finished but the requested --max-distance was not met
(data -> curve or curve -> data; the result is still written).
"""

from __future__ import annotations

import argparse
import sys
import warnings

from ..reconstruct.config import PRESETS, CurveConfig
from ..reconstruct.curve import CurveWarning, reconstruct_curve
from ..reconstruct.inputs import curve_target, load_curve_points
from ._common import (add_config_flags, config_overrides, parse_formats, plots_module, prepare_out_dir,
                      write_control_points, write_exports)
from .progress import ga_progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("curve", help="reconstruct a B-spline/Chaikin control polygon from ordered 2D or 3D points",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("points", help="ordered x,y or x,y,z points (CSV, TXT or NPY)")
    closure = p.add_mutually_exclusive_group()
    closure.add_argument("--closed", dest="closure_flag", action="store_const", const="closed",
                         help="fit a closed (periodic) curve (default: detected from the data)")
    closure.add_argument("--open", dest="closure_flag", action="store_const", const="open",
                         help="fit an open curve even when the data close")
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
    overrides = config_overrides(args, CurveConfig)
    if args.closure_flag:
        overrides["closure"] = args.closure_flag
    config = CurveConfig.preset(args.preset, **overrides)
    truth = load_curve_points(args.truth) if args.truth else None
    formats = parse_formats(args.formats, "curve")
    out = prepare_out_dir(args.out)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CurveWarning)
        with ga_progress(f"curve {target.name}", enabled=not args.quiet) as on_generation:
            result = reconstruct_curve(target, seed=args.seed, config=config, preset=args.preset,
                                       progress=on_generation)
    for w in caught:
        if issubclass(w.category, CurveWarning):
            print(f"warning: {w.message}", file=sys.stderr)
    result.save(out)
    write_control_points(out / "control_points.csv", result.control_points)
    if target.points.shape[1] == 2:
        plots_module().curve_report(result, target.points, out / "report.png", truth=truth)
    else:
        print("  no report.png: the report draws planar curves only", file=sys.stderr)
    written = write_exports(result, out, formats)
    m = result.metrics
    missed = m.get("tolerance_met") is False
    status = "interrupted: best so far" if result.interrupted else ("tolerance missed" if missed else "done")
    kind = ("closed" if m.get("closed") else "open") + (f", {m['n_corners']} corners" if m.get("n_corners") else "")
    print(f"{status}: {m['n_control_points']} control points ({kind}), data->curve mean "
          f"{m['data_to_fit_mean']:.3g} max {m['data_to_fit_max']:.3g}, curve->data max {m['fit_to_data_max']:.3g} "
          f"of the diagonal, {m['seconds']:.2f} s -> {out}")
    for path in written:
        print(f"  wrote {path}")
    return 3 if missed and not result.interrupted else 0

