"""Export and validation in the core API: :func:`export` and :func:`validate` (re-exported by :mod:`gsr_cad`).

Exporters are found through the ``gsr_cad.exporters`` entry-point group (``pyproject.toml``, or any other
installed distribution) and loaded on first use; nothing here imports them, so the layering holds.

:func:`export` writes every requested format or none: files are produced in a staging directory inside
the output directory and moved into place only after every exporter has succeeded. It records what it
wrote in a manifest (:data:`MANIFEST`, one entry per file: format, stem, SHA-256) and first removes the
files the previous run's manifest lists, and only those that still hold what gsr wrote, so stale exports
never linger and nothing else is touched.

:func:`validate` checks only what gsr wrote: a file an exporter claims is refused (a failed check, never
run) when it is a symlink, when the manifest does not list it ("not written by gsr"), or, for a script
format, when it differs from the script regenerated from ``result.json`` ("modified"); data files
(STEP, DXF, SVG) are read, never run, and also get a check of their SHA-256 against the manifest. Files no
exporter claims are ignored.

:func:`save_document` saves a host's own document (``.FCStd``, ``.blend``) by running the exported script
in the installed host.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterable, Sequence
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from ..atomic import commit_files, write_text
from ..errors import ExportError, GsrError, GsrWarning, InputError
from .result import Result

GROUP = "gsr_cad.exporters"
MANIFEST = "exports.json"
_PROTOCOL = ("name", "kinds", "suffixes", "host", "available", "claims", "render", "export", "validate", "failure")


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


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def read_manifest(out_dir: str | os.PathLike[str]) -> dict[str, dict[str, str]]:
    """The files the last :func:`export` into ``out_dir`` wrote (``{name: {format, stem, sha256}}``); empty
    when there is no manifest or it is unreadable. Only plain file names are kept."""
    path = Path(out_dir) / MANIFEST
    if path.is_symlink() or not path.is_file():
        return {}
    try:
        files = json.loads(path.read_text(encoding="utf-8")).get("files", {})
    except (OSError, ValueError, AttributeError):
        return {}
    if not isinstance(files, dict):
        return {}
    return {name: entry for name, entry in files.items()
            if isinstance(name, str) and name == Path(name).name and name not in ("", ".", "..")
            and isinstance(entry, dict) and all(isinstance(entry.get(k), str) for k in ("format", "stem", "sha256"))}


def export(result: Any, out_dir: str | os.PathLike[str], formats: Sequence[str] | None = None,
           stem: str | None = None) -> list[Path]:
    """Export ``result`` into ``out_dir`` in ``formats`` (None: every available format for its kind).

    All or nothing: the exporters write into a staging directory inside ``out_dir``; only when every
    one has succeeded are the new files and their manifest moved into place as one transaction
    (:func:`gsr_cad.atomic.commit_files`: all renames or none, signals held), and then the previous run's
    exports that were not replaced removed. Returns their paths.
    """
    names = default_formats(result.kind) if formats is None else check_formats(formats, result.kind)
    refused = {n: why for n in names if (why := _refuses(registry()[n].exporter, result))}
    if refused and formats is not None:
        name, why = next(iter(refused.items()))
        raise ExportError(f"format {name!r} cannot carry this result: {why}")
    for name, why in refused.items():
        warnings.warn(f"format {name} skipped: {why}", GsrWarning, stacklevel=2)
    names = [n for n in names if n not in refused]
    stem = stem or result.kind
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".gsr-export-", dir=out))
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    try:
        produced: list[tuple[str, Path]] = []
        for name in names:
            produced += [(name, p) for p in registry()[name].exporter.export(result, staging, stem)]
        previous = read_manifest(out)
        entries = {p.name: {"format": name, "stem": stem, "sha256": _sha256(p)} for name, p in produced}
        files = [p for _, p in produced]
        if entries:
            files.append(write_text(staging / MANIFEST, json.dumps({"version": 1, "files": entries}, indent=1) + "\n"))
        elif previous:
            (out / MANIFEST).unlink(missing_ok=True)
        final = commit_files(staging, out, files)
        for name, entry in previous.items():  # the previous run's exports this run did not replace
            path = out / name
            if name not in entries and not path.is_symlink() and path.is_file() and _sha256(path) == entry["sha256"]:
                path.unlink()
        return [p for p in final if p.name != MANIFEST]
    except OSError as exc:
        raise ExportError(f"cannot write to {out}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _refuses(exporter: Any, result: Any) -> str | None:
    """Why ``exporter`` cannot carry ``result`` exactly (None: it can; exporters without ``refuses`` can)."""
    refuses = getattr(exporter, "refuses", None)
    return refuses(result) if callable(refuses) else None


def save_document(result: Any, path: str | os.PathLike[str]) -> Path:
    """Save ``result`` as a host document (``.FCStd`` through FreeCAD, ``.blend`` through Blender, chosen by
    the suffix): the exporter that declares that ``document_suffix`` runs its script in the host. InputError
    for a suffix no exporter saves; ExportError when the host is missing or fails."""
    target = Path(path)
    for fmt in registry().values():
        exporter = fmt.exporter
        suffix = getattr(exporter, "document_suffix", None)
        if exporter is not None and suffix and target.suffix.lower() == suffix.lower() and fmt.supports(result.kind):
            return exporter.save_document(result, target)
    known = sorted(getattr(f.exporter, "document_suffix", "") for f in registry().values() if f.exporter)
    raise InputError(f"{target.name}: no exporter saves {target.suffix or 'suffix-less'} documents "
                     f"(known: {', '.join(s for s in known if s)})")


def _refusal(path: Path, result: Any, fmt: Format, entry: dict[str, str] | None) -> tuple[str | None, bool]:
    """Why ``path`` must not be checked (None: go ahead), and whether it is a script format."""
    if path.is_symlink():
        return "a symlink: refused (validate never follows links)", False
    if entry is None:
        return "not written by gsr (not in the manifest): not run", False
    texts = fmt.exporter.render(result, entry["stem"])
    if texts is None:
        return None, False
    want = texts.get(path.name)
    if want is None or path.read_bytes() != want.encode("utf-8"):
        return "modified: differs from the script gsr writes for result.json; not run", True
    return None, True


def validate(out_dir: str | os.PathLike[str]) -> list[Any]:
    """Round-trip every file gsr exported into ``out_dir`` through its host; returns the checks in file order.

    ``out_dir`` must hold the ``result.json`` the files were exported from (InputError otherwise). A
    file whose validation crashes (a damaged file can make a host library throw) gives a failed check.
    """
    out = Path(out_dir)
    if not out.is_dir():
        raise InputError(f"{out}: not a directory")
    if (out / "result.json").is_symlink():
        raise InputError(f"{out / 'result.json'}: a symlink; validate reads only files in the folder")
    result = Result.load(out)
    manifest = read_manifest(out)
    known = registry()
    checks: list[Any] = []
    for path in sorted(p for p in out.iterdir() if not p.name.startswith(".")):
        claimed = [f for f in known.values() if f.supports(result.kind) and f.exporter.claims(path)]
        if not claimed or not (path.is_symlink() or path.is_file()):
            continue
        entry = manifest.get(path.name)
        fmt = known.get(entry["format"], claimed[0]) if entry else claimed[0]
        if fmt.exporter is None:
            continue
        try:
            refusal, script = _refusal(path, result, fmt, entry)
            if refusal:
                checks.append(fmt.exporter.failure(path, "written by gsr", refusal))
                continue
            if not script:
                same = _sha256(path) == entry["sha256"]
                checks.append(dataclasses.replace(
                    fmt.exporter.failure(path, "as exported", "as written" if same else "modified since export"),
                    passed=same))
            checks += fmt.exporter.validate(path, result)
        except Exception as exc:  # report, do not crash: the file under test may be anything
            msg = str(exc).splitlines()[0] if str(exc) else ""
            detail = msg if isinstance(exc, GsrError) else f"{type(exc).__name__}: {msg}"
            checks.append(fmt.exporter.failure(path, "validate", detail))
    return checks
