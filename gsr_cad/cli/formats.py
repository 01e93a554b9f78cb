"""The export formats: exporters found through the ``gsr_cad.exporters`` entry-point group.

Nothing in gsr_cad imports an exporter module; each is registered in ``pyproject.toml`` (or by any other
installed distribution) and loaded here on first use. ``export_all`` writes every requested format or
none: files are produced in a staging directory inside the output directory and moved into place only
after every exporter has succeeded. ``validate_all`` hands each exported file to the exporter that wrote
it, which round-trips it through its CAD host.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import shutil
import tempfile
from collections.abc import Iterable, Sequence
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from ..errors import ExportError, GsrError, InputError

GROUP = "gsr_cad.exporters"
_PROTOCOL = ("name", "kinds", "suffixes", "host", "available", "claims", "export", "validate", "failure")


@dataclasses.dataclass(frozen=True)
class Format:
    """One registered format: the loaded exporter, or why it could not be loaded."""

    name: str
    exporter: Any | None
    error: str | None = None

    @property
    def unavailable(self) -> str | None:
        """None when the exporter can write files on this machine, else the reason."""
        return self.error or self.exporter.available()

    def supports(self, kind: str) -> bool:
        return self.exporter is not None and kind in self.exporter.kinds


def _load(ep) -> Format:
    try:
        obj = ep.load()
        exporter = obj() if isinstance(obj, type) else obj
    except Exception as exc:  # a broken third-party plug-in must not take the CLI down
        return Format(ep.name, None, f"cannot load {ep.value}: {type(exc).__name__}: {exc}")
    missing = [a for a in _PROTOCOL if not hasattr(exporter, a)]
    if missing:
        return Format(ep.name, None, f"{ep.value} is not an exporter (lacks {', '.join(missing)})")
    if exporter.name != ep.name:
        return Format(ep.name, None, f"{ep.value} calls itself {exporter.name!r}, registered as {ep.name!r}")
    return Format(ep.name, exporter)


@functools.cache
def registry() -> dict[str, Format]:
    """Every registered format by name (loaded once per process)."""
    return {ep.name: _load(ep) for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name)}


def format_names(kind: str | None = None) -> list[str]:
    """Registered format names, optionally only those that handle ``kind``."""
    return [n for n, f in registry().items() if kind is None or f.supports(kind)]


def check_formats(names: Iterable[str], kind: str) -> list[str]:
    """Validate requested format names for a ``kind`` result before any work is done.

    Raises InputError for an unknown format or one that does not handle ``kind``, and ExportError when
    the format's exporter cannot run here (its library or host is missing).
    """
    out: list[str] = []
    known = registry()
    for name in names:
        fmt = known.get(name)
        if fmt is None:
            raise InputError(f"unknown format {name!r} (known: {', '.join(known) or 'none'})")
        if fmt.exporter is not None and not fmt.supports(kind):
            raise InputError(f"format {name!r} does not export {kind} results "
                             f"(formats for {kind}s: {', '.join(format_names(kind))})")
        reason = fmt.unavailable
        if reason:
            raise ExportError(f"format {name!r} is unavailable: {reason}")
        if name not in out:
            out.append(name)
    return out


def default_formats(kind: str) -> list[str]:
    """Every format that handles ``kind`` and can run here."""
    return [n for n, f in registry().items() if f.supports(kind) and not f.unavailable]


def export_all(result: Any, out_dir: str | os.PathLike[str], formats: Sequence[str] | None = None,
               stem: str | None = None) -> list[Path]:
    """Export ``result`` into ``out_dir`` in ``formats`` (None: every available format for its kind).

    All or nothing: the exporters write into a staging directory inside ``out_dir``; only when every
    one has succeeded are the files moved into place (each by an atomic rename). Returns their paths.
    """
    names = default_formats(result.kind) if formats is None else check_formats(formats, result.kind)
    if not names:
        return []
    stem = stem or result.kind
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".gsr-export-", dir=out))
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    try:
        produced: list[Path] = []
        for name in names:
            produced += registry()[name].exporter.export(result, staging, stem)
        final = []
        for path in produced:
            target = out / path.relative_to(staging)
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(path, target)
            final.append(target)
        return final
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def validate_all(out_dir: str | os.PathLike[str]) -> list[Any]:
    """Round-trip every exported file in ``out_dir`` through its host; returns the checks in file order.

    ``out_dir`` must hold the ``result.json`` the files were exported from (InputError otherwise). A
    file whose validation crashes (a damaged file can make a host library throw) gives a failed check.
    """
    from gsr_cad.reconstruct.result import Result

    out = Path(out_dir)
    if not out.is_dir():
        raise InputError(f"{out}: not a directory")
    result = Result.load(out)
    known = registry()
    checks: list[Any] = []
    for path in sorted(p for p in out.iterdir() if p.is_file() and not p.name.startswith(".")):
        for fmt in known.values():
            if fmt.exporter is None or not fmt.supports(result.kind) or not fmt.exporter.claims(path):
                continue
            try:
                checks += fmt.exporter.validate(path, result)
            except Exception as exc:  # report, do not crash: the file under test may be anything
                msg = str(exc).splitlines()[0] if str(exc) else ""
                detail = msg if isinstance(exc, GsrError) else f"{type(exc).__name__}: {msg}"
                checks.append(fmt.exporter.failure(path, "validate", detail))
    return checks
