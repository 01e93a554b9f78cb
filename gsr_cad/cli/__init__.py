"""The ``gsr`` command line: one module per subcommand, each with ``add_parser`` and ``run``.

Every deliberate error (:class:`~gsr_cad.errors.GsrError`) and every argument error becomes one line
``error: ...`` on stderr and exit code 2; no traceback reaches the user.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import warnings
from collections.abc import Sequence

from ..errors import GsrError, GsrWarning
from . import signals

SUBCOMMANDS = ("curve", "surface", "replay", "validate", "subdivide", "sample", "resume", "batch")


class UsageError(Exception):
    """Raised by the parser instead of printing usage and exiting."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, no usage dump
        raise UsageError(message)


def _version() -> str:
    """The installed package's version (its metadata), or the source tree's when not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("gsr-cad")
    except PackageNotFoundError:
        from .. import __version__

        return __version__


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``gsr`` parser. With ``argv`` naming a subcommand first, only that one is imported and registered (each
    imports its own problem's code, a few tenths of a second at every start); else all of them (``--help``)."""
    parser = _Parser(prog="gsr", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"gsr {_version()}",
                        help="print the installed gsr_cad version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in (argv[0],) if argv and argv[0] in SUBCOMMANDS else SUBCOMMANDS:
        try:
            module = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # subcommand not built yet in this checkout
            raise
        module.add_parser(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """GsrWarnings become one ``warning: ...`` line; every other warning (numpy's among them) is silenced."""
    if issubclass(category, GsrWarning):
        print(f"warning: {str(message).splitlines()[0]}", file=sys.stderr)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _os_error(exc: OSError) -> str:
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{exc.strerror or _one_line(exc)}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 done, 2 bad input or failure, 3 tolerance missed, 130 interrupted).

    No traceback reaches the user: deliberate errors and OS errors (a full disk, a read-only directory)
    are one ``error: ...`` line with exit code 2; anything else is reported as an internal error (exit 1)
    unless ``GSR_DEBUG=1`` asks for the traceback. Run as the program (``argv`` None) after Ctrl-C or
    SIGTERM, the process ends right away once its output is flushed (native threads of half-stopped
    libraries cannot then crash the interpreter's shutdown).
    """
    code = _main(argv)
    if argv is None and signals.interrupted():
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code)
    return code


def _report(exc: Exception) -> int:
    """The one ``error:`` line for ``exc`` and the exit code."""
    if signals.interrupted():  # a library interrupted mid-import or mid-call often turns Ctrl-C into its own error
        message, code = "interrupted", 130
    elif isinstance(exc, UsageError):
        message, code = str(exc), 2
    elif isinstance(exc, GsrError):
        message, code = _one_line(exc), 2
    elif isinstance(exc, MemoryError):
        message, code = "out of memory (try a smaller input or --max-target-points)", 2
    elif isinstance(exc, OSError):
        message, code = _os_error(exc), 2
    elif isinstance(exc, (RecursionError, OverflowError)):
        message, code = f"input too large or too deeply nested ({_one_line(exc)})", 2
    else:
        if os.environ.get("GSR_DEBUG") == "1":
            raise exc
        message, code = (f"internal error: {type(exc).__name__}: {_one_line(exc)} (GSR_DEBUG=1 shows the "
                         "traceback; please report it)"), 1
    print(f"error: {message}", file=sys.stderr)
    return code


def _main(argv: Sequence[str] | None) -> int:
    with warnings.catch_warnings(), signals.handled(final=argv is None), contextlib.ExitStack() as stack:
        warnings.showwarning = _show_warning
        warnings.simplefilter("always", GsrWarning)
        try:
            argv = sys.argv[1:] if argv is None else list(argv)
            parser = build_parser(argv)  # imports the subcommand (numpy, scipy): Ctrl-C is handled from here on
            import numpy as np

            stack.enter_context(np.errstate(all="ignore"))
            args = parser.parse_args(argv)
            if not getattr(args, "command", None):
                parser.print_help()
                return 2
            return int(args.run(args) or 0)
        except KeyboardInterrupt:
            print("error: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:
            return _report(exc)
