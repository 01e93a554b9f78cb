"""A rich progress bar for GA runs: generation, best fitness, elapsed time and ETA."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


@contextlib.contextmanager
def ga_progress(label: str, enabled: bool = True) -> Iterator[Callable[[Any], None]]:
    """Yield an ``on_generation`` callback that drives a progress bar on stderr (no-op when disabled)."""
    if not enabled:
        yield lambda report: None
        return
    console = Console(file=sys.stderr)
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("gen {task.fields[generation]:>4}"),
        TextColumn("best {task.fields[best]}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console, transient=False) as bar:
        task = bar.add_task(label, total=1.0, generation=0, best="-")

        def update(report: Any) -> None:
            bar.update(task, completed=min(1.0, max(0.0, float(report.progress))),
                       generation=report.generation, best=f"{report.best_cost:.4g}")

        yield update
        bar.update(task, completed=1.0)
