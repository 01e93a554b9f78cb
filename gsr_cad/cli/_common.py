"""Helpers shared by the subcommands: config flags, output directory, control-point CSV, report plots, exports."""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import types
import typing
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..atomic import write_text
from ..errors import ExportError, InputError


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


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
        kwargs.update(type=inner, metavar="LETTERS" if meta.get("letters") else _METAVARS.get(inner, "X"))
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


def write_control_points(path: Path, points: np.ndarray) -> Path:
    """``x,y`` CSV of the control points at full double precision, atomically."""
    rows = "".join(f"{x:.17g},{y:.17g}\n" for x, y in np.asarray(points, dtype=float))
    return write_text(path, "x,y\n" + rows)


def prepare_out_dir(path: str) -> Path:
    """Create the output directory (before the long run) and prove it is writable."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".gsr-write-test"):
            pass
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    if not os.access(out, os.W_OK):
        raise ExportError(f"cannot write to {out}: permission denied")
    return out


def plots_module() -> types.ModuleType:
    """:mod:`gsr_cad.plots` (imported on demand: it loads matplotlib), or ExportError if that is broken."""
    try:
        from .. import plots
    except ImportError as exc:  # matplotlib is a core dependency; say so if it is broken
        raise ExportError(f"cannot draw report.png: {exc}") from None
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
    """Export ``result`` into ``out`` in the given formats (None = all available)."""
    if formats == []:
        return []
    return _formats_module().export_all(result, out, formats)
