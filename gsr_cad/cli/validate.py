"""``gsr validate OUT``: round-trip every file gsr exported into OUT through the CAD hosts installed here.

Only what gsr wrote runs: a script that differs from the one regenerated from OUT/result.json ("modified"),
a file the export manifest (OUT/exports.json) does not list ("not written by gsr") and a symlink are
refused unrun, each as a failed check (:func:`gsr_cad.reconstruct.export.validate`).
Prints one row per check (file, host, check, deviation, result, detail). Exit code 0 when every check
that could run passed, 1 when one failed, 2 when nothing could be checked (no exported files, or none of
their hosts installed) or OUT holds no readable result.json.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from ..reconstruct.export import validate as validate_all

COLUMNS = ("file", "host", "check", "deviation", "result", "detail")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("validate", help="round-trip exported files through the installed CAD hosts",
                       description=__doc__.splitlines()[0])
    p.add_argument("out", help="output directory of gsr curve/surface/replay (holding result.json)")
    p.set_defaults(run=run)


def table(checks: Sequence[Any]) -> str:
    """The checks as an aligned plain-text table (header first)."""
    rows = [COLUMNS] + [(c.file, c.host, c.check, "-" if c.deviation is None else f"{c.deviation:.3g}", c.status,
                         c.detail) for c in checks]
    widths = [max(len(r[i]) for r in rows) for i in range(len(COLUMNS) - 1)]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(r, widths)) + "  " + r[-1] for r in rows)


def run(args: argparse.Namespace) -> int:
    checks = validate_all(args.out)
    if checks:
        print(table(checks))
    n_pass = sum(c.passed is True for c in checks)
    n_fail = sum(c.passed is False for c in checks)
    n_skip = sum(c.passed is None for c in checks)
    print(f"validate: {len(checks)} checks, {n_pass} pass, {n_fail} FAIL, {n_skip} skipped")
    if n_fail:
        return 1
    if n_pass == 0:
        why = "no exported files found" if not checks else "none of their hosts is installed"
        print(f"error: nothing could be checked in {args.out} ({why})", file=sys.stderr)
        return 2
    return 0
