"""``gsr resume OUT``: continue a ``gsr curve`` or ``gsr surface`` run started with ``--checkpoint``.

The command is repeated with the arguments saved in ``OUT/run.json``; the search continues from the
checkpoint where it stopped, and gives the same result as an uninterrupted run with the same seed.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from ..errors import InputError
from ..reconstruct.inputs import read_json
from ._common import RUN_FILE

RESUMABLE = ("curve", "surface")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("resume", help="continue a curve or surface run started with --checkpoint",
                       description=__doc__.splitlines()[0])
    p.add_argument("out", metavar="OUT", help="the output directory of the interrupted run")
    p.add_argument("--quiet", action="store_true", default=None, help="no progress bar")
    p.set_defaults(run=run)


def saved_args(out: str) -> argparse.Namespace:
    """The arguments of the run saved in ``OUT/run.json`` (InputError if there is none or it is damaged)."""
    path = Path(out) / RUN_FILE
    if not os.path.lexists(path):
        raise InputError(f"{out}: no {RUN_FILE} here (only runs started with --checkpoint FILE can be resumed)")
    values = read_json(path, RUN_FILE)
    if not isinstance(values, dict) or values.get("command") not in RESUMABLE:
        raise InputError(f"{path}: not a resumable run ({' or '.join(RESUMABLE)} expected)")
    if not isinstance(values.get("checkpoint"), str):
        raise InputError(f"{path}: the run has no checkpoint to resume from")
    module = importlib.import_module(f".{values['command']}", __package__)
    parser = argparse.ArgumentParser(add_help=False)
    module.add_parser(parser.add_subparsers(dest="command"))
    defaults = vars(parser.parse_args([values["command"], "_", "-o", "_"]))
    unknown = sorted(set(values) - set(defaults))
    if unknown:
        raise InputError(f"{path}: unknown settings {', '.join(unknown)} (saved by another gsr_cad version?)")
    return argparse.Namespace(**{**defaults, **values})


def run(args: argparse.Namespace) -> int:
    saved = saved_args(args.out)
    if args.quiet is not None:
        saved.quiet = args.quiet
    if not os.path.exists(saved.checkpoint):
        print(f"note: checkpoint {saved.checkpoint} is gone; starting the run again", file=sys.stderr)
    return int(saved.run(saved) or 0)
