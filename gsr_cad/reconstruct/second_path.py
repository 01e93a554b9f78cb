"""The refinement's second path: the placed template grown in a process of its own while this one grows the
search's winner, so that the closer of the two stands at no cost in time where a second CPU is free.

Refined alone for 220 s (the refinement's share of a 300 s run), the placed cube was as close as the searched
winner's path or closer on five of six real targets (LetterBlock 386 control vertices at 5.0e-3 of the diagonal
where the winner's path reached 356 at 9.0e-3; bone 114 at 5.0e-4 where it had 7.5e-4), and behind it on airplane
(284 at 2.7e-3 against 194 at 1.7e-3): which path wins is not known before both have grown.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import signal
import time
from collections.abc import Callable
from typing import Any

from ..errors import GsrError
from .refine import Level, refine

_POLL = 0.25  # seconds between the parent's looks at its stop flag while it waits for the worker
_STOP: Any = None  # the worker's copy of the parent's stop event (set by :func:`_install`)
_PARENT = -1  # the worker's parent process id


MIN_SECONDS = 60.0
"""The shortest refinement that ``refine_workers`` 0 grows on two processes: a worker takes about two seconds to
start (a fresh interpreter importing numpy, scipy and this package) and a copy of the problem."""


def cpus() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        return os.cpu_count() or 1


ENV = "GSR_REFINE_WORKERS"
"""Environment variable that sets what ``refine_workers`` 0 means (1 or 2), for every run started with it (a
shared machine, or a test suite whose workers already fill the CPUs)."""


def refine_workers(setting: int, seconds: float | None = None) -> int:
    """The processes the refinement grows on for the config's ``refine_workers``: 0 (auto) is :data:`ENV` when
    set to 1 or 2, else 2 where this process may use two or more CPUs and start children, and the refinement may
    take at least :data:`MIN_SECONDS` (``seconds``; None: no limit), else 1."""
    if setting:
        return int(setting)
    if os.environ.get(ENV, "").strip() in ("1", "2"):
        return int(os.environ[ENV])
    long = seconds is None or seconds >= MIN_SECONDS
    return 2 if long and cpus() >= 2 and not multiprocessing.current_process().daemon else 1


def _install(stop: Any) -> None:
    """Worker start: Ctrl-C is the parent's to handle (it sets ``stop``, which ends this path's growth)."""
    global _STOP, _PARENT
    _STOP, _PARENT = stop, os.getppid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stopped() -> bool:
    """The worker's stop: asked by the parent, or the parent gone (killed: no one would take the result)."""
    return bool(_STOP.is_set()) or os.getppid() != _PARENT


def _grow(problem: Any, goal: float, wall_deadline: float | None, max_faces: int,
          tail: Callable[[int], float] | None, free_corners: bool = False, genome: tuple = ()
          ) -> tuple[tuple, list[Level], list[tuple[int, float, tuple]]]:
    """In the worker: the refinement of ``genome`` (default the template) until the deadline (``time.time()``
    seconds), with the front's points it recorded as ``(control vertices, distance, genome)``."""
    deadline = None if wall_deadline is None else time.perf_counter() + (wall_deadline - time.time())
    found: list[tuple[int, float, tuple]] = []

    def record(mesh: Any, cost: float, genome: tuple) -> None:
        found.append((mesh.n_vertices, cost, genome))

    final, levels = refine(problem, genome, goal, deadline, max_faces, record, _stopped, tail,
                           free_corners=free_corners)
    return final, levels, found


class TemplatePath:
    """The template's refinement on ``problem`` (a :class:`~gsr_cad.reconstruct.surface.SurfaceProblem`, which
    must pickle) started in a worker process; :meth:`result` waits for it. ``deadline``: a ``perf_counter``
    value or None; ``free_corners``: every fit of the path lets corners turn concave (``refine``'s strategy);
    ``genome``: where the path starts instead of the bare template (a leaded part's body and legs)."""

    def __init__(self, problem: Any, goal: float, deadline: float | None, max_faces: int,
                 tail: Callable[[int], float] | None, free_corners: bool = False, genome: tuple = ()) -> None:
        context = multiprocessing.get_context("spawn")  # no fork of a process that may hold threads
        self._stop = context.Event()
        self._pool = concurrent.futures.ProcessPoolExecutor(1, mp_context=context, initializer=_install,
                                                            initargs=(self._stop,))
        self._goal = goal
        wall = None if deadline is None else time.time() + (deadline - time.perf_counter())
        self._future = self._pool.submit(_grow, problem, goal, wall, max_faces, tail, free_corners, genome)

    def met(self) -> bool:
        """Whether the worker is done and its last cage is within the goal (the winner's growth then ends: within
        the goal, the template's cage is the one the pick prefers unless the winner's is simpler, and a winner
        not there yet only grows)."""
        if not self._future.done() or self._future.exception() is not None:
            return False
        levels = self._future.result()[1]
        return bool(levels) and levels[-1].cost <= self._goal

    def stop(self) -> None:
        """Ask the worker to end its growth now (it returns what it has)."""
        self._stop.set()

    def result(self, should_stop: Callable[[], bool] | None = None
               ) -> tuple[tuple, list[Level], list[tuple[int, float, tuple]]] | None:
        """The worker's ``(genome, levels, front points)``, waited for (``should_stop()`` turning true while
        waiting, e.g. on Ctrl-C, stops the worker); None when its growth failed on the input (a
        :class:`~gsr_cad.errors.GsrError`) or the worker died."""
        try:
            while True:
                try:
                    return self._future.result(timeout=_POLL)
                except concurrent.futures.TimeoutError:
                    if should_stop is not None and should_stop():
                        self.stop()
        except (GsrError, concurrent.futures.process.BrokenProcessPool):
            return None
        finally:
            self.close()

    def close(self) -> None:
        """Stop the worker and release the pool (waiting for the worker to exit)."""
        self._stop.set()
        self._pool.shutdown(wait=True, cancel_futures=True)
