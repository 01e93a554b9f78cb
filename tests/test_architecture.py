"""Layering contracts (import-linter) and packaging rules."""

import ast
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_import_layers_hold():
    beside = Path(sys.executable).with_name("lint-imports")  # this venv's, before any other on PATH
    exe = str(beside) if beside.exists() else shutil.which("lint-imports")
    if exe is None:
        pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
    proc = subprocess.run([exe, "--config", str(REPO / "pyproject.toml")], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]


def test_no_bare_exporters_package_installed(tmp_path):
    proc = subprocess.run([sys.executable, "-c", "import importlib.util,sys; "
                           "sys.exit(importlib.util.find_spec('exporters') is not None)"],
                          capture_output=True, cwd=tmp_path)
    assert proc.returncode == 0, "a top-level 'exporters' package is importable: it must live as gsr_cad.exporters"
    assert importlib.util.find_spec("gsr_cad.exporters") is not None


def _imports(path: Path, root: Path = REPO) -> set[str]:
    """Every module name ``path`` imports (and ``module.name`` for each ``from module import name``), relative
    imports resolved against the installed layout, where ``exporters/`` is ``gsr_cad.exporters``."""
    parts = path.relative_to(root).with_suffix("").parts
    if parts[0] == "exporters":
        parts = ("gsr_cad", *parts)
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = ".".join([*parts[:-node.level], node.module or ""]).strip(".") if node.level else node.module
            names.add(base)
            names.update(f"{base}.{a.name}" for a in node.names)
    return names


def _reaches_exporters(name: str) -> bool:
    head = name.split(".")
    return head[0] == "exporters" or head[:2] == ["gsr_cad", "exporters"]


def _reaches_cli(name: str) -> bool:
    return name.split(".")[:2] == ["gsr_cad", "cli"]


def test_import_scan_resolves_relative_imports(tmp_path):
    """The scan below sees relative imports of the exporters from gsr_cad and of the CLI from the exporters."""
    (tmp_path / "gsr_cad" / "cli").mkdir(parents=True)
    (tmp_path / "exporters").mkdir()
    cli = tmp_path / "gsr_cad" / "cli" / "run.py"
    cli.write_text("from ..exporters import step\nfrom . import formats\n")
    package = tmp_path / "gsr_cad" / "__init__.py"
    package.write_text("from . import exporters\nimport numpy\n")
    exporter = tmp_path / "exporters" / "step.py"
    exporter.write_text("from ..cli import main\nfrom .base import Exporter\n")
    assert any(map(_reaches_exporters, _imports(cli, tmp_path)))
    assert any(map(_reaches_exporters, _imports(package, tmp_path)))
    assert {"gsr_cad.cli.formats", "numpy"} <= _imports(cli, tmp_path) | _imports(package, tmp_path)
    assert any(map(_reaches_cli, _imports(exporter, tmp_path)))
    assert "gsr_cad.exporters.base.Exporter" in _imports(exporter, tmp_path)


def test_nothing_in_gsr_cad_imports_the_exporters():
    """Exporters sit on top and are found through entry points; import-linter cannot see the package-dir
    mapping, so this rule is checked on the source directly."""
    offenders = [str(p.relative_to(REPO)) for p in (REPO / "gsr_cad").rglob("*.py")
                 if any(map(_reaches_exporters, _imports(p)))]
    assert offenders == []


def test_exporters_import_only_gsr_cad_downward():
    """Not the CLI above them, and never a top-level ``exporters`` (it is not installed)."""
    for path in (REPO / "exporters").rglob("*.py"):
        for name in _imports(path):
            assert not _reaches_cli(name), f"{path.name} imports the CLI ({name})"
            assert name.split(".")[0] != "exporters", f"{path.name} imports a top-level exporters ({name})"


SHARED = {"base", "model", "checks", "hosts", "encode", "hostside"}
"""The floor every exporter stands on; exporters are siblings and never import each other."""


def _exporter_modules() -> set[str]:
    import tomllib

    eps = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["entry-points"]
    return {value.split(":")[0].rsplit(".", 1)[1] for value in eps["gsr_cad.exporters"].values()}


def _exporter_imports(path: Path) -> set[str]:
    """The gsr_cad.exporters modules ``path`` imports (first component after the package)."""
    out = set()
    for name in _imports(path):
        head = name.split(".")
        if head[:2] == ["gsr_cad", "exporters"] and len(head) > 2:
            out.add(head[2])
    return out - {"__init__"}


def test_exporters_are_siblings_over_one_shared_floor():
    exporters = _exporter_modules()
    assert {"step", "dxf", "svg", "freecad", "openscad", "cadquery", "blender"} <= exporters
    assert not exporters & SHARED
    graph = {p.stem: _exporter_imports(p) for p in (REPO / "exporters").glob("*.py") if p.stem != "__init__"}
    assert set(graph) == exporters | (SHARED - {"hostside"}), "every exporter module is an exporter or shared"
    for name in exporters:
        siblings = graph[name] & exporters
        assert not siblings, f"exporter {name} imports exporter(s) {sorted(siblings)}"
        assert graph[name] <= SHARED
    for name in SHARED - {"hostside"}:
        assert not graph[name] & exporters, f"shared module {name} imports an exporter"


def test_hostside_code_imports_nothing_of_gsr_cad():
    """Host scripts run inside Blender, FreeCAD or CadQuery, where gsr_cad is not installed."""
    for path in (REPO / "exporters" / "hostside").glob("*.py"):
        for name in _imports(path):
            assert name.split(".")[0] != "gsr_cad" or path.name == "__init__.py", f"{path.name} imports {name}"


def test_the_architecture_scan_sees_an_exporter_importing_a_sibling(tmp_path):
    (tmp_path / "exporters").mkdir()
    bad = tmp_path / "exporters" / "step.py"
    bad.write_text("from .freecad import freecad_read\nfrom . import model\nimport gsr_cad.exporters.blender\n")
    assert {"freecad", "model", "blender"} <= {n.split(".")[2] for n in _imports(bad, tmp_path)
                                               if n.startswith("gsr_cad.exporters.")}


@pytest.mark.parametrize("command, absent", [("curve", "gsr_cad.reconstruct.surface"),
                                             ("surface", "gsr_cad.reconstruct.curve")])
def test_a_subcommand_imports_only_its_own_problem(tmp_path, command, absent):
    """``gsr curve`` starts without the surface code and ``gsr surface`` without the curve code (each costs a
    few tenths of a second at every start); ``--help`` still lists every subcommand."""
    code = (f"import sys; from gsr_cad.cli import SUBCOMMANDS, build_parser; build_parser([{command!r}]); "
            f"assert {absent!r} not in sys.modules, 'imported'; "
            "text = build_parser().format_help(); assert all(name in text for name in SUBCOMMANDS), text")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_every_public_name_is_the_function_or_class_after_its_modules_are_imported():
    """The lazily loaded API names are never shadowed by a submodule of the same name (``export``)."""
    code = ("import importlib, types, gsr_cad, gsr_cad.reconstruct as r\n"
            "for m in ('config', 'curve', 'surface', 'export', 'inputs', 'meshio', 'result'):\n"
            "    importlib.import_module('gsr_cad.reconstruct.' + m)\n"
            "bad = [n for n in r.__all__ if isinstance(getattr(r, n), types.ModuleType)]\n"
            "bad += [n for n in gsr_cad._API if isinstance(getattr(gsr_cad, n), types.ModuleType)]\n"
            "assert not bad, bad\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
