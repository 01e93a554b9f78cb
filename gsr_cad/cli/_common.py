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


def add_config_flags(parser: argparse.ArgumentParser, config_cls: type, skip: tuple[str, ...] = ()) -> None:
    """One flag per config field (``--field-name``), typed from the dataclass annotations."""
    hints = typing.get_type_hints(config_cls)
    group = parser.add_argument_group("settings (defaults from --preset)")
    for field in dataclasses.fields(config_cls):
        if field.name in skip:
            continue
        hint = hints[field.name]
        args = typing.get_args(hint)
        origin = typing.get_origin(hint)
        kwargs: dict[str, Any] = {"dest": f"cfg_{field.name}", "default": None}
        if hint is bool:
            kwargs["action"] = argparse.BooleanOptionalAction
        elif origin is Literal:
            kwargs["choices"] = list(args)
        elif origin in (typing.Union, types.UnionType):
            inner = next(a for a in args if a is not type(None))
            kwargs["type"] = inner
        else:
            kwargs["type"] = hint
        kwargs["help"] = f"default {field.default!r}"
        group.add_argument(_flag(field.name), **kwargs)


def config_overrides(args: argparse.Namespace, config_cls: type) -> dict[str, Any]:
    """The config fields given on the command line."""
    out = {}
    for field in dataclasses.fields(config_cls):
        value = getattr(args, f"cfg_{field.name}", None)
        if value is not None:
            out[field.name] = value
    return out


def write_control_points(path: Path, points: np.ndarray) -> Path:
    """``x,y`` (or ``x,y,z``) CSV of the control points at full double precision, atomically."""
    pts = np.asarray(points, dtype=float)
    rows = "".join(",".join(f"{v:.17g}" for v in row) + "\n" for row in pts)
    return write_text(path, ",".join("xyz"[:pts.shape[1]]) + "\n" + rows)


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
