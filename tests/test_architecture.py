"""Layering contracts (import-linter) and packaging rules."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_import_layers_hold():
    exe = shutil.which("lint-imports") or str(Path(sys.executable).with_name("lint-imports"))
    if not Path(exe).exists():
        pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
    proc = subprocess.run([exe, "--config", str(REPO / "pyproject.toml")], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stdout[-3000:]


def test_no_bare_exporters_package_installed(tmp_path):
    proc = subprocess.run([sys.executable, "-c", "import importlib.util,sys; "
                           "sys.exit(importlib.util.find_spec('exporters') is not None)"],
                          capture_output=True, cwd=tmp_path)
    assert proc.returncode == 0, "a top-level 'exporters' package is importable: it must live as gsr_cad.exporters"
    assert importlib.util.find_spec("gsr_cad.exporters") is not None
