"""What ``gsr curve`` / ``gsr surface`` print when they finish (the words come from
:mod:`gsr_cad.reconstruct.summary`): the summary on stdout, warnings on stderr, one line each."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..reconstruct.result import Result
from ..reconstruct.summary import (add_model_units, summary_lines, template_warning, tolerance_status,
                                   warning_lines)

__all__ = ["EXIT_TOLERANCE_MISSED", "add_model_units", "finish", "summary_lines", "template_warning", "warn",
           "warning_lines"]

EXIT_TOLERANCE_MISSED = 3
"""Exit code of a run that finished but missed its requested tolerance."""


def warn(line: str | None) -> None:
    """Print a one-line warning on stderr (nothing for None)."""
    if line:
        print(line, file=sys.stderr)


def finish(result: Result, out: Path, written: Sequence[Path]) -> int:
    """Print the summary (stdout) and warnings (stderr); the exit code (3 if the tolerance was missed)."""
    for line in summary_lines(result, out):
        print(line)
    for path in written:
        print(f"  wrote {path}")
    for line in warning_lines(result):
        warn(line)
    status = tolerance_status(result)
    return EXIT_TOLERANCE_MISSED if status is not None and not status[1] else 0
