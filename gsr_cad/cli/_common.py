"""Helpers shared by the subcommands: config flags, output directory, control-point CSV, report plots, exports."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import shutil
import tempfile
import types
import typing
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..atomic import write_text
from ..errors import ExportError, InputError
from ..reconstruct.inputs import open_input
from . import signals
from .progress import ga_progress


OUTPUT_NAMES = ("result.json", "control_points.csv", "control_mesh.obj", "limit_mesh.obj", "report.png", "report.html",
                "exports.json")
"""Files a run writes into OUT (each must be free to be replaced by a file)."""
STAGING_PREFIXES = (".gsr-export-", ".gsr-write-test")


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def whole_number(text: str) -> int:
    """argparse type: an integer, also written as an integral float (``1e8``), so that range checks can
    state the allowed range instead of a bare "invalid int"."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not (math.isfinite(value) and value.is_integer()):
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}")
    return int(value)


_METAVARS = {int: "N", float: "X", str: "TEXT"}


def _shown_default(field: dataclasses.Field, length: bool) -> str:
    """The default of ``field`` as the help text shows it."""
    value = field.default
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "on" if value else "off"
    if length:
        return f"{100 * value:g}% of the diagonal" if value else "0"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _config_flag_kwargs(field: dataclasses.Field, hint: Any) -> dict[str, Any]:
    """argparse keywords of one config field: type, metavar or choices, and a help sentence with its default."""
    from ..reconstruct.units import is_length_field, parse_length

    args, origin = typing.get_args(hint), typing.get_origin(hint)
    meta = field.metadata
    length = is_length_field(field)
    kwargs: dict[str, Any] = {"dest": f"cfg_{field.name}", "default": None}
    text = meta.get("help") or field.name.replace("_", " ").capitalize() + "."
    if length:
        kwargs.update(type=_length_arg(parse_length), metavar="DIST")
        text += " DIST: model units (see --units), or N% of the target's bounding-box diagonal."
    elif hint is bool:
        kwargs["action"] = argparse.BooleanOptionalAction
    elif origin is Literal or meta.get("choices"):
        kwargs["choices"] = list(meta.get("choices") or args)
    else:
        inner = next(a for a in args if a is not type(None)) if origin in (typing.Union, types.UnionType) else hint
        kwargs.update(type=whole_number if inner is int else inner, metavar="LETTERS" if meta.get("letters") else _METAVARS.get(inner, "X"))
    if meta.get("letters"):
        text += " " + ", ".join(f"{k} {v}" for k, v in meta["letters"].items()) + "."
    kwargs["help"] = f"{text} Default: {_shown_default(field, length)}.".replace("%", "%%")
    return kwargs


def _length_arg(parse: Any) -> Any:
    """An argparse type for lengths: a bad value becomes argparse's one-line usage error."""
    from ..errors import ConfigError

    def convert(text: str) -> Any:
        try:
            return parse(text)
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    convert.__name__ = "length"
    return convert


def add_config_flags(parser: argparse.ArgumentParser, config_cls: type, skip: tuple[str, ...] = ()) -> None:
    """One flag per config field (``--field-name``), typed from the dataclass annotations, its help sentence
    from the field's ``metadata["help"]`` (see :func:`gsr_cad.reconstruct.config._field`) plus its default.
    Length fields take model units or ``N%`` of the diagonal (:class:`~gsr_cad.reconstruct.units.Length`,
    resolved by :func:`~gsr_cad.reconstruct.units.resolve_lengths` once the target is loaded)."""
    hints = typing.get_type_hints(config_cls)
    group = parser.add_argument_group("settings (defaults from --preset default; --preset paper changes some)")
    for field in dataclasses.fields(config_cls):
        if field.name not in skip:
            group.add_argument(_flag(field.name), **_config_flag_kwargs(field, hints[field.name]))


def config_overrides(args: argparse.Namespace, config_cls: type) -> dict[str, Any]:
    """The config fields given on the command line."""
    out = {}
    for field in dataclasses.fields(config_cls):
        value = getattr(args, f"cfg_{field.name}", None)
        if value is not None:
            out[field.name] = value
    return out


REPORT_POINTS = 20_000
"""Most target points of a curve the reports draw (the distances they state are the result's, over all points)."""


def report_points(points: np.ndarray, limit: int = REPORT_POINTS) -> np.ndarray:
    """The target points a curve report draws: all of them up to ``limit``, else ``limit`` evenly spaced in
    order (the first and the last kept), so a 10^6-point curve draws in seconds."""
    if len(points) <= limit:
        return points
    return points[np.unique(np.linspace(0, len(points) - 1, limit).round().astype(np.int64))]


def write_control_points(path: Path, points: np.ndarray) -> Path:
    """``x,y`` (or ``x,y,z``) CSV of the control points at full double precision, atomically."""
    pts = np.asarray(points, dtype=float)
    rows = "".join(",".join(f"{v:.17g}" for v in row) + "\n" for row in pts)
    return write_text(path, ",".join("xyz"[:pts.shape[1]]) + "\n" + rows)


def clean_stale(out: Path) -> None:
    """Remove what an earlier run killed mid-way left in ``out``: export staging folders and the temporary
    files of atomic writes (``.NAME.*.tmp``)."""
    with contextlib.suppress(OSError):
        for entry in out.iterdir():
            name = entry.name
            if name.startswith(STAGING_PREFIXES) and entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            elif name.startswith(".") and name.endswith(".tmp") and entry.is_file():
                entry.unlink()


def prepare_out_dir(path: str, names: tuple[str, ...] = OUTPUT_NAMES) -> Path:
    """Create the output directory (before the long run), prove it is writable, check that none of the
    ``names`` to be written is a directory, and clean what a killed earlier run left behind."""
    if path == "":
        raise InputError("empty output directory name (give -o DIR)")
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    for name in names:
        if (out / name).is_dir():
            raise InputError(f"{out / name}: is a directory; it must be free for the output file")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".gsr-write-test"):
            pass
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    if not os.access(out, os.W_OK):
        raise ExportError(f"cannot write to {out}: permission denied")
    clean_stale(out)
    return out


@contextlib.contextmanager
def output_dir(path: str, names: tuple[str, ...] = OUTPUT_NAMES) -> Iterator[Path]:
    """:func:`prepare_out_dir`, and if the block fails before writing anything, remove the directory again
    when this call created it (an interrupted or failed run leaves OUT untouched)."""
    existed = Path(path).exists() if path else True
    try:
        yield prepare_out_dir(path, names)
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError):
                Path(path).rmdir()  # only if still empty
        raise


def plots_module() -> types.ModuleType:
    """:mod:`gsr_cad.plots` (imported on demand: it loads matplotlib), or ExportError if that is broken."""
    try:
        import matplotlib

        from .. import plots
    except ImportError as exc:  # matplotlib is a core dependency; say so if it is broken
        raise ExportError(f"cannot draw report.png: {exc}") from None
    matplotlib.rcParams["text.usetex"] = False  # user text is escaped for mathtext (plots._plain)
    return plots


def html_module() -> types.ModuleType:
    """:mod:`gsr_cad.html_report` (imported on demand: it loads plotly), or ExportError if plotly is broken."""
    try:
        from .. import html_report

        html_report._plotly()
    except ImportError as exc:
        raise ExportError(f"cannot write report.html: {exc}") from None
    return html_report


def _formats_module():
    from . import formats  # the exporter registry (entry points)

    return formats


def parse_formats(spec: str | None, kind: str) -> list[str] | None:
    """Validate ``--formats`` before any work: None = every available exporter for ``kind``."""
    if spec is None:
        return None
    names = [s.strip() for s in spec.split(",") if s.strip()]
    if names in ([], ["none"]):
        return []
    return _formats_module().check_formats(names, kind)


def write_exports(result, out: Path, formats: list[str] | None) -> list[Path]:
    """Export ``result`` into ``out`` in the given formats (None = all available): all of them or none
    (:func:`gsr_cad.reconstruct.export.export` stages them and moves them into place as one transaction)."""
    if formats == []:
        return []
    return _formats_module().export_all(result, out, formats)


MAX_CHECKPOINT_BYTES = 4 << 30
"""Largest checkpoint read back (4 GiB)."""
RUN_FILE = "run.json"
"""The settings of a run started with ``--checkpoint``, saved in OUT for ``gsr resume OUT``."""
_PATH_ARGS = ("points", "target", "template", "truth", "checkpoint", "out")


def add_run_flags(parser: argparse.ArgumentParser) -> None:
    """Flags shared by ``gsr curve`` and ``gsr surface``: output, seed, formats, progress, checkpoint."""
    parser.add_argument("-o", "--out", required=True, help="output directory")
    parser.add_argument("--seed", type=whole_number, default=None, help="random seed (same seed, same result)")
    parser.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--checkpoint", metavar="FILE",
                        help="save the search state to FILE every generation and continue from it if it exists "
                             "(then `gsr resume OUT` repeats the command); same seed, same result")


def check_seed(seed: int | None) -> None:
    if seed is not None and not 0 <= seed < 2**63:
        raise InputError(f"seed must lie in [0, 2^63 - 1], not {seed}")


def check_run_args(args: argparse.Namespace) -> None:
    """The flags shared by curve and surface runs: a seed in range and a usable ``--checkpoint`` file (an
    existing one must be a regular file: it is resumed)."""
    check_seed(args.seed)
    if args.checkpoint is None:
        return
    if args.checkpoint == "":
        raise InputError("--checkpoint: empty file name")
    ck = Path(args.checkpoint)
    if os.path.lexists(ck):
        open_input(ck, "checkpoint", limit=MAX_CHECKPOINT_BYTES)
    elif not ck.parent.is_dir():
        raise InputError(f"--checkpoint {ck}: directory {ck.parent} does not exist")


def save_run_args(out: Path, args: argparse.Namespace) -> None:
    """Write ``OUT/run.json`` (the command and its arguments, paths made absolute) for ``gsr resume``."""
    values = {k: v for k, v in vars(args).items() if k != "run"}
    values["out"] = str(out)
    for key in _PATH_ARGS:
        if isinstance(values.get(key), str) and values[key] not in ("", "cube"):
            values[key] = os.path.abspath(values[key])
    write_text(out / RUN_FILE, json.dumps(values, indent=1) + "\n")


@contextlib.contextmanager
def searching(label: str, quiet: bool, max_seconds: float | None) -> Iterator[tuple[Any, Any]]:
    """The search phase: a progress bar and a cooperative stop (Ctrl-C, SIGTERM, ``max_seconds`` hard cap).

    Yields ``(progress, should_stop)``."""
    with ga_progress(label, enabled=not quiet) as progress, signals.cooperative(max_seconds) as should_stop:
        yield progress, should_stop


SLOW_STEPS = ("drawing", "writing the exports")
"""How the status texts of the slow output steps start (the report, the exports)."""


def write_outputs(progress: Any, steps: list[tuple[str, Any]]) -> list[Path]:
    """Run the output ``steps`` (``(status text, callable returning a path or a list of paths)``) in order,
    with a status line before each.

    The fast steps come first (result.json, then the control geometry) and run shielded from signals, so
    they exist, complete, before the slow ones (texts starting with :data:`SLOW_STEPS`). After Ctrl-C or
    SIGTERM the slow steps are skipped (the run stops within moments); a signal during one stops it at once.
    """
    written: list[Path] = []
    for text, step in steps:
        slow = text.startswith(SLOW_STEPS)
        if slow and signals.interrupted():
            progress.status("stopped early: report.png and the exports are skipped "
                            "(`gsr replay OUT -o OUT` writes the exports)")
            break
        progress.status(text)
        with contextlib.nullcontext() if slow else signals.shielded():
            produced = step()
        written += produced if isinstance(produced, list) else [produced]
    return written


def settle_stop(result: Any) -> None:
    """A search cut by the ``--max-seconds`` hard cap (not by a signal) is a normal stop: say so; a signal
    at any point (the final refinement is then cut short) marks the result interrupted."""
    if signals.interrupted():
        result.interrupted = True
    elif result.interrupted:
        result.interrupted = False
        result.metrics["stop_reason"] = "max_seconds"


def check_output_file(path: str, flag: str) -> Path:
    """An output file name given with ``flag``: not empty, not a directory, in an existing directory."""
    if path == "":
        raise InputError(f"{flag}: empty file name")
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{p}: is a directory; {flag} needs a file name (e.g. {p / 'target.csv'})")
    if p.exists() and not p.is_file():
        raise InputError(f"{p}: exists and is not a regular file")
    if not p.parent.is_dir() and p.parent.exists():
        raise InputError(f"{p.parent}: is not a directory")
    return p
