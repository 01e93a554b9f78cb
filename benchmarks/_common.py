"""What the benchmark scripts share: the environment line and the result table (markdown and terminal)."""

from __future__ import annotations

import os
import platform
from collections.abc import Collection, Hashable, Sequence

import numpy as np
import scipy


def load_average() -> float:
    """The one-minute load average (NaN where the platform has none)."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def environment(load: float | None = None) -> str:
    """Python, NumPy and SciPy versions and the CPUs; with ``load``, the load average at the start."""
    text = (f"Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
            f"{os.cpu_count()} CPUs ({platform.machine()})")
    return text if load is None else f"{text}, load average {load:.1f} at the start"


def command(script: str, argv: Sequence[str]) -> str:
    """The command line that made a table, in backticks."""
    return "`" + " ".join(["python", f"benchmarks/{script}", *argv]) + "`"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]], right: Collection[str]) -> list[str]:
    """A markdown table; the columns named in ``right`` are right-aligned."""
    return ["| " + " | ".join(header) + " |",
            "|" + "|".join("---:" if h in right else "---" for h in header) + "|",
            *("| " + " | ".join(r) + " |" for r in rows)]


def print_table(title: str, header: Sequence[str], rows: Sequence[Sequence[str]], right: Collection[str],
                groups: Sequence[Hashable], width: int) -> None:
    """The table on the terminal (rich), a section break wherever ``groups`` changes, at least ``width`` wide
    even when piped."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    for h in header:
        table.add_column(h, justify="right" if h in right else "left")
    for i, row in enumerate(rows):
        if i and groups[i] != groups[i - 1]:
            table.add_section()
        table.add_row(*row)
    Console(width=max(Console().width, width)).print(table)
