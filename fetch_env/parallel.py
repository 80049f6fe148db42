"""Independent simulations run ahead on a pool of processes, each kept with its error.

The probes' clamps and slides are independent simulations of one piece: on a machine with
cores to spare they can run at once and be read afterwards in their serial order, so that
the estimates are the serial ones (each run is deterministic, and everything random, the
sensor noise, is drawn afterwards in the caller's process).  A run's error is kept in its
place and raised where the serial code would have met it; the warnings the workers raise
are raised again here, once each.
"""

from __future__ import annotations

import multiprocessing
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any

from fetch_env.clipping import rewarn
from fetch_env.errors import require, require_int

__all__ = ["Task", "WorkerLostError", "outcome", "run_ahead"]

# One simulation: a module-level function (picklable) and its arguments.
Task = tuple[Callable[..., Any], tuple[Any, ...]]


class WorkerLostError(RuntimeError):
    """A worker process of :func:`run_ahead` died (killed, out of memory) mid-run."""


def run_ahead(tasks: Sequence[Task], workers: int) -> list[Any]:
    """Each task's result, or the exception it raised, in the tasks' order.

    ``workers`` processes (at most one per task) run them; 1 runs them here, one after the
    other, and so does a daemonic process (a pool's worker may not start processes of its
    own).  Linux forks the workers (they inherit the imported modules); elsewhere they are
    spawned.  An exception from a worker carries the worker's traceback as a note.

    Stopping: Ctrl-C is left to this process (the workers ignore it), SIGTERM and SIGHUP
    are raised here as ``KeyboardInterrupt`` (where this runs in the main thread), and on
    any stop the workers are terminated and joined, so none is left behind.

    Raises:
        InvalidParameterError: ``workers`` not an integer >= 1.
        WorkerLostError: a worker process died before its task finished.
    """
    require_int("workers", workers)
    require(workers >= 1, "workers", workers, ">= 1")
    if workers == 1 or len(tasks) <= 1 or multiprocessing.current_process().daemon:
        return [_capture(fn, *args) for fn, args in tasks]
    context = multiprocessing.get_context("fork" if sys.platform == "linux" else "spawn")
    pool = ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=context,
                               initializer=_worker_signals)
    try:
        with _stop_signals_interrupt():
            futures = [pool.submit(_capture_remote, fn, *args) for fn, args in tasks]
            done = [f.result() for f in futures]
    except BrokenProcessPool as exc:
        raise WorkerLostError(f"a probe worker process died mid-run ({exc}); if it ran "
                              "out of memory, run with fewer workers") from None
    finally:
        _stop(pool)
    seen: set[tuple[type[Warning], str]] = set()
    for _, caught in done:
        for key in caught:
            if key not in seen:
                seen.add(key)
                rewarn(*key)
    return [result for result, _ in done]


def _capture(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)``, or the exception it raised (kept for the caller to raise in order)."""
    try:
        return fn(*args)
    except Exception as exc:  # every error goes back, to be raised in order
        return exc


def _capture_remote(fn: Callable[..., Any], *args: Any
                    ) -> tuple[Any, list[tuple[type[Warning], str]]]:
    """In a worker: :func:`_capture`'s result (an exception with its traceback as a note)
    and the warnings raised meanwhile, as (category, text)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = _capture(fn, *args)
    if isinstance(result, Exception):
        result.add_note("in a probe worker process:\n"
                        + "".join(traceback.format_exception(result)).rstrip())
    return result, [(w.category, str(w.message)) for w in caught]


def outcome(result: Any) -> Any:
    """A :func:`run_ahead` result: raise it where it is an exception, else return it."""
    if isinstance(result, BaseException):
        raise result
    return result


def _worker_signals() -> None:
    """Workers stop quietly on SIGTERM and leave Ctrl-C to the main process."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


@contextmanager
def _stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise ``KeyboardInterrupt`` (main thread only:
    elsewhere signal handlers cannot be set); the handlers found are put back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}
    for sig in before:
        signal.signal(sig, _interrupt)
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started, terminate and join every worker (a worker mid-task
    would otherwise run on after a stop); further stop signals wait until this is done."""
    with _signals_ignored():
        alive = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in alive:
            proc.terminate()
            proc.join()


@contextmanager
def _signals_ignored() -> Iterator[None]:
    """Ctrl-C, SIGTERM and SIGHUP ignored within the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    stops = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    before = {sig: signal.getsignal(sig) for sig in stops}
    for sig in stops:
        signal.signal(sig, signal.SIG_IGN)
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
