"""A rich progress bar for GA runs (generation, best fitness, elapsed time, ETA) and status lines for the
phases after the search (polish, history rewrite, report, exports), all on stderr."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class RunProgress:
    """Callable as ``on_generation``; :meth:`status` prints a phase line; :meth:`finish` completes the bar."""

    def __init__(self, bar: Progress | None, task: Any, console: Console | None) -> None:
        self._bar, self._task, self._console = bar, task, console
        self._finished = False
        self._started = time.monotonic()

    def __call__(self, report: Any) -> None:
        if self._bar is None or self._finished:
            return
        self._bar.update(self._task, completed=min(1.0, max(0.0, float(report.progress))),
                         generation=report.generation, best=f"{report.best_cost:.4g}")
        if float(report.progress) >= 1.0:
            self.finish()
            self.status("search done; polishing the winner and rewriting its history")

    def finish(self, note: str = "done") -> None:
        """Show the bar full (or as far as it got, when ``note`` says why not) and stop redrawing it."""
        if self._bar is None or self._finished:
            return
        self._finished = True
        if note == "done":
            self._bar.update(self._task, completed=1.0)
        self._bar.update(self._task, note=note)
        self._bar.stop()

    def status(self, text: str) -> None:
        """One status line (``[elapsed] text``) on stderr."""
        if self._console is not None:
            self._console.print(f"[{time.monotonic() - self._started:6.1f} s] {text}", highlight=False,
                                markup=False)


@contextlib.contextmanager
def ga_progress(label: str, enabled: bool = True) -> Iterator[RunProgress]:
    """Yield a :class:`RunProgress` driving a progress bar on stderr (no-op when disabled)."""
    if not enabled:
        yield RunProgress(None, None, None)
        return
    console = Console(file=sys.stderr, highlight=False)
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(complete_style="green", finished_style="green"),
        TextColumn("gen {task.fields[generation]:>4}"),
        TextColumn("best {task.fields[best]}"),
        TimeElapsedColumn(),
        TextColumn("{task.fields[note]}"),
        TimeRemainingColumn(),
    )
    bar = Progress(*columns, console=console, transient=False)
    task = bar.add_task(label, total=1.0, generation=0, best="-", note="ETA")
    bar.start()
    progress = RunProgress(bar, task, console)
    try:
        yield progress
    except BaseException:
        progress.finish("stopped")
        raise
    progress.finish("stopped" if not progress._finished else "done")
