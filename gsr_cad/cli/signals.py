"""Ctrl-C and SIGTERM for the CLI: stop cleanly, keep the best so far.

Inside :func:`handled`, SIGTERM behaves as Ctrl-C. The first signal prints ``stopping...`` on stderr. While a
reconstruction runs under :func:`cooperative`, signals only set the stop flag that the search, the polish and
the history rewrite poll (through :func:`stop_requested`), so the run ends within moments with its best result;
a third signal there, or any signal elsewhere (loading, report, exports), raises KeyboardInterrupt at once.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator

HARD_STOP_SIGNALS = 3
"""Signals during a cooperative section after which it is abandoned (KeyboardInterrupt)."""


class _State:
    def __init__(self) -> None:
        self.count = 0
        self.cooperative = False
        self.deadline: float | None = None


_state = _State()


def _handler(signum: int, frame) -> None:
    _state.count += 1
    if _state.count == 1:
        print("stopping... (keeping the best result so far; press Ctrl-C again to stop at once)",
              file=sys.stderr, flush=True)
    if not _state.cooperative or _state.count >= HARD_STOP_SIGNALS:
        raise KeyboardInterrupt


def _unraisable_hook(previous: Callable) -> Callable:
    """A hook for ``sys.unraisablehook``: a KeyboardInterrupt that :func:`_handler` raised inside a finalizer
    (a weakref callback or ``__del__``, which Python swallows and prints as a traceback while the command goes
    on) is delivered again, to the code that runs next; anything else goes to ``previous``."""
    def hook(info) -> None:
        if info.exc_type is KeyboardInterrupt:  # a signal now would land in this hook: one in a moment instead
            signal.setitimer(signal.ITIMER_REAL, REDELIVER_SECONDS)
            return
        previous(info)
    return hook


REDELIVER_SECONDS = 0.005


def _redelivered(signum: int, frame) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def handled(final: bool = False) -> Iterator[None]:
    """Install the SIGINT/SIGTERM handlers (main thread only) for the duration of a CLI command.

    ``final`` (the command is the whole process): afterwards the signals are ignored, so one that comes while
    the finished process shuts down cannot kill it by signal instead of its exit code.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    previous_hook, previous_alarm = sys.unraisablehook, signal.getsignal(signal.SIGALRM)
    _state.count, _state.cooperative, _state.deadline = 0, False, None
    for s in previous:
        signal.signal(s, _handler)
    signal.signal(signal.SIGALRM, _redelivered)
    sys.unraisablehook = _unraisable_hook(previous_hook)
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous_alarm)
        for s, h in previous.items():  # once stopping, later signals must not turn the exit into a traceback
            signal.signal(s, signal.SIG_IGN if _state.count or final else h)


def stop_requested() -> bool:
    """True once Ctrl-C or SIGTERM came, or the ``--max-seconds`` deadline has passed."""
    return _state.count > 0 or (_state.deadline is not None and time.monotonic() > _state.deadline)


def interrupted() -> bool:
    """True once Ctrl-C or SIGTERM came (not just the deadline)."""
    return _state.count > 0


@contextlib.contextmanager
def cooperative(max_seconds: float | None = None) -> Iterator[Callable[[], bool]]:
    """A section whose code polls the yielded ``should_stop``; signals set the flag instead of raising.

    ``max_seconds`` (> 0) also makes ``should_stop`` true once that much time has passed: a hard cap on the
    whole section, not only on the search.
    """
    _state.cooperative = True
    _state.deadline = time.monotonic() + max_seconds if max_seconds else None
    try:
        yield stop_requested
    finally:
        _state.cooperative = False
        _state.deadline = None


@contextlib.contextmanager
def shielded() -> Iterator[None]:
    """A short section (writing result.json) that a signal must not cut: it only sets the stop flag."""
    before = _state.cooperative
    _state.cooperative = True
    try:
        yield
    finally:
        _state.cooperative = before
