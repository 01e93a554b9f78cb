"""Evaluators: any callable ``(fn, items) -> list`` returning ``[fn(x) for x in items]`` in order.

The engine hands every batch of new genomes to its evaluator, so the same run can use one core, a
process pool or a dask cluster; results never depend on which (the problem's cost must be pure).
"""

from __future__ import annotations

import concurrent.futures
import math
import multiprocessing
import os
import signal
import weakref
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from ..errors import ConfigError

T = TypeVar("T")
R = TypeVar("R")
Evaluator = Callable[[Callable[[Any], Any], Sequence[Any]], list]


def serial_evaluator(fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
    """Evaluate in this process, in order."""
    return [fn(x) for x in items]


_WORKER_FN: Callable[[Any], Any] | None = None


def _install_worker(fn: Callable[[Any], Any]) -> None:
    """Pool initializer: keep ``fn`` in the worker (shipped once, not with every chunk); leave Ctrl-C to the parent."""
    global _WORKER_FN
    _WORKER_FN = fn
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _call_worker_chunk(items: Sequence[Any]) -> list:
    return [_WORKER_FN(x) for x in items]


POLL_SECONDS = 0.1
"""How often an out-of-process evaluator checks whether the run was asked to stop."""


def _stopping(fn: Callable[[Any], Any]) -> bool:
    """Whether ``fn`` (the engine's cost wrapper) says the run was asked to stop."""
    check = getattr(fn, "stopping", None)
    return bool(check()) if callable(check) else False


class ProcessPoolEvaluator:
    """Evaluate on a pool of worker processes (``concurrent.futures``), in chunks.

    The pool starts on first use and is kept across batches; it restarts only when a different ``fn`` comes
    (``fn``, hence the problem, must pickle). Use it as a context manager or call :meth:`close`; an
    interrupted or failing batch cancels the pending chunks and shuts the pool down.
    """

    def __init__(self, max_workers: int | None = None, chunks_per_worker: int = 4,
                 mp_context: str | None = None) -> None:
        if max_workers is not None and (isinstance(max_workers, bool) or not isinstance(max_workers, int)
                                        or max_workers < 1):
            raise ConfigError(f"max_workers must be a positive integer or None, not {max_workers!r}")
        if not isinstance(chunks_per_worker, int) or chunks_per_worker < 1:
            raise ConfigError(f"chunks_per_worker must be a positive integer, not {chunks_per_worker!r}")
        self.max_workers = max_workers or os.cpu_count() or 1
        self.chunks_per_worker = chunks_per_worker
        self._context = multiprocessing.get_context(mp_context) if mp_context else None
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._fn: Callable[[Any], Any] | None = None
        self._finalizer: weakref.finalize | None = None

    def __call__(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        items = list(items)
        if not items:
            return []
        if self._pool is None or fn is not self._fn:
            self.close()
            self._pool = concurrent.futures.ProcessPoolExecutor(
                max_workers=self.max_workers, mp_context=self._context,
                initializer=_install_worker, initargs=(fn,))
            self._fn = fn
            self._finalizer = weakref.finalize(self, self._pool.shutdown, wait=False, cancel_futures=True)
        size = max(1, math.ceil(len(items) / (self.max_workers * self.chunks_per_worker)))
        try:
            futures = [self._pool.submit(_call_worker_chunk, items[i:i + size]) for i in range(0, len(items), size)]
            pending = set(futures)
            while pending:
                if _stopping(fn):
                    raise KeyboardInterrupt
                _, pending = concurrent.futures.wait(pending, timeout=POLL_SECONDS)
            return [r for f in futures for r in f.result()]
        except BaseException:
            self.close(wait=False)
            raise

    def close(self, wait: bool = True) -> None:
        """Shut the pool down (pending chunks are cancelled); the next call starts a new one."""
        if self._finalizer is not None:
            self._finalizer.detach()
            self._finalizer = None
        if self._pool is not None:
            self._pool.shutdown(wait=wait, cancel_futures=True)
            self._pool = None
            self._fn = None

    def __enter__(self) -> ProcessPoolEvaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class DaskEvaluator:
    """Evaluate on a dask.distributed cluster: ``address`` of a scheduler, an existing ``client``, or
    (neither) a local cluster. Needs the ``[dask]`` extra, imported only here."""

    def __init__(self, address: str | None = None, client: Any = None, **client_kwargs: Any) -> None:
        try:
            from dask import distributed
        except ImportError:
            raise ConfigError("DaskEvaluator needs dask.distributed: pip install 'gsr-cad[dask]'") from None
        self._owns_client = client is None
        self.client = client if client is not None else distributed.Client(address, **client_kwargs)

    def __call__(self, fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
        items = list(items)
        if not items:
            return []
        from dask import distributed

        futures = self.client.map(fn, items, pure=False)
        try:
            pending = list(futures)
            while pending:
                if _stopping(fn):
                    raise KeyboardInterrupt
                try:
                    distributed.wait(pending, timeout=POLL_SECONDS)
                except (TimeoutError, distributed.TimeoutError):
                    pass
                pending = [f for f in pending if not f.done()]
            return list(self.client.gather(futures))
        except BaseException:
            self.client.cancel(futures)
            raise

    def close(self) -> None:
        """Close the client if this evaluator created it."""
        if self._owns_client:
            self.client.close()

    def __enter__(self) -> DaskEvaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
