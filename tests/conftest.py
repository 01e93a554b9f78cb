"""Shared fixtures: run the CLI in-process and capture its output."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gsr_cad.cli import main

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "samples"


@dataclasses.dataclass
class CliRun:
    code: int
    out: str
    err: str


@pytest.fixture
def gsr(capsys):
    """Call ``gsr`` with a list of arguments; returns exit code, stdout and stderr."""

    def run(*args: str) -> CliRun:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliRun(code, captured.out, captured.err)

    return run
