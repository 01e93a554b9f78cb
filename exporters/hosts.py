"""Finding and running the CAD hosts (Blender, FreeCAD, OpenSCAD) as independent judges.

Runners for Blender, FreeCAD, OpenSCAD and the CadQuery venv. Each raises
:class:`~gsr_cad.errors.ExportError` with one line when the host is missing, times out or reports failure,
so the CLI can print it and tests can tell "host absent" from "check failed".
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Mapping, Sequence
from pathlib import Path

from gsr_cad.errors import ExportError

_EXECUTABLES = {"blender": "blender", "freecad": "freecadcmd", "openscad": "openscad"}
_NAMES = {"blender": "Blender", "freecad": "FreeCAD", "openscad": "OpenSCAD"}


def find_host(name: str) -> str | None:
    """Path of a host's executable (``GSR_<NAME>`` overrides), or None when it is not installed."""
    override = os.environ.get(f"GSR_{name.upper()}")
    if override:
        return override if Path(override).exists() else None
    return shutil.which(_EXECUTABLES[name])


def run(cmd: Sequence[str], host: str, timeout: float,
        env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``cmd`` headless (``env`` added to the environment); ExportError naming ``host`` when it cannot
    start, times out or exits non-zero (with the last line of its output)."""
    full_env = {"QT_QPA_PLATFORM": "offscreen", **os.environ, **(env or {})}
    try:
        proc = subprocess.run(list(map(str, cmd)), capture_output=True, text=True, timeout=timeout, env=full_env,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise ExportError(f"{host} did not finish within {timeout:.0f} s") from None
    except OSError as exc:
        raise ExportError(f"cannot run {host}: {exc.strerror or exc}") from None
    if proc.returncode != 0:
        tail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or ["no output"]
        raise ExportError(f"{host} failed (exit {proc.returncode}): {tail[0]}")
    return proc


def _not_installed(name: str) -> str:
    return f"{_NAMES[name]} is not installed (apt-get install {_EXECUTABLES[name].removesuffix('cmd')})"


def missing(name: str) -> str | None:
    """None when a host is installed, else the reason to report (with the Debian package that brings it)."""
    return None if find_host(name) is not None else _not_installed(name)


def _require(name: str) -> str:
    exe = find_host(name)
    if exe is None:
        raise ExportError(_not_installed(name))
    return exe


def run_blender(script: str | Path, args: Sequence[str] = (), timeout: float = 600) -> subprocess.CompletedProcess:
    """Run a Python script in background Blender; a Python exception in it is a failure (exit 1)."""
    exe = _require("blender")
    cmd = [exe, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script), "--", *map(str, args)]
    return run(cmd, "blender", timeout)


def run_freecad(script: str | Path, args: Sequence[str] = (), timeout: float = 600) -> subprocess.CompletedProcess:
    """Run a macro with ``freecadcmd``; scripts must ``raise SystemExit(1)`` themselves on failure
    (FreeCAD 0.20 exits 0 on an uncaught exception), and arguments reach them through ``GSR_ARGS``."""
    exe = _require("freecad")
    return run([exe, script], "freecad", timeout, env={"GSR_ARGS": os.pathsep.join(map(str, args))})


def run_openscad(scad: str | Path, out: str | Path, timeout: float = 600,
                 defines: Mapping[str, str] | None = None, options: Sequence[str] = ()) -> subprocess.CompletedProcess:
    """Render ``scad`` to ``out`` (format from its suffix, e.g. STL) with OpenSCAD, no display needed;
    ``defines`` override top-level variables (``-D name=value``, value as OpenSCAD source); ``options``
    are further command-line options (e.g. ``("--export-format", "binstl")``)."""
    exe = _require("openscad")
    extra = [arg for name, value in (defines or {}).items() for arg in ("-D", f"{name}={value}")]
    extra += list(options)
    return run([exe, *extra, "-o", out, scad], "openscad", timeout)


NO_CADQUERY = "no CadQuery environment (run scripts/cadquery-venv.sh or set GSR_CADQUERY_PYTHON)"


def cadquery_python() -> Path | None:
    """The interpreter of the CadQuery venv (``GSR_CADQUERY_PYTHON`` or ``.venv-cadquery``), or None.

    CadQuery and build123d ship different OCP builds that must not share a Python environment."""
    override = os.environ.get("GSR_CADQUERY_PYTHON")
    candidates = [Path(override)] if override else [
        Path(__file__).resolve().parents[1] / ".venv-cadquery" / "bin" / "python",
        Path.cwd() / ".venv-cadquery" / "bin" / "python",
    ]
    return next((p for p in candidates if p.is_file() and os.access(p, os.X_OK)), None)


def run_cadquery(script: str | Path, args: Sequence[str] = (), timeout: float = 300) -> subprocess.CompletedProcess:
    """Run a script with the CadQuery interpreter; ExportError when it is missing, fails or times out."""
    python = cadquery_python()
    if python is None:
        raise ExportError(NO_CADQUERY)
    return run([python, script, *args], "cadquery", timeout)
