"""Independent simulations run ahead on a pool of processes, each kept with its error.

The probes' clamps and slides are independent simulations of one piece: on a machine with
cores to spare they can run at once and be read afterwards in their serial order, so that
the estimates are the serial ones (each run is deterministic, and everything random, the
sensor noise, is drawn afterwards in the caller's process).  A run's error is kept in its
place and raised where the serial code would have met it.
"""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from fetch_env.errors import require, require_int

__all__ = ["Task", "WorkerLostError", "outcome", "run_ahead"]

# One simulation: a module-level function (picklable) and its arguments.
Task = tuple[Callable[..., Any], tuple[Any, ...]]


class WorkerLostError(RuntimeError):
    """A worker process of :func:`run_ahead` died (killed, out of memory) mid-run."""


def run_ahead(tasks: Sequence[Task], workers: int) -> list[Any]:
    """Each task's result, or the exception it raised, in the tasks' order.

    ``workers`` processes (at most one per task) run them; 1 runs them here, one after the
    other.  Linux forks the workers (they inherit the imported modules); elsewhere they are
    spawned.

    Raises:
        InvalidParameterError: ``workers`` not an integer >= 1.
        WorkerLostError: a worker process died before its task finished.
    """
    require_int("workers", workers)
    require(workers >= 1, "workers", workers, ">= 1")
    if workers == 1 or len(tasks) <= 1:
        return [_capture(fn, *args) for fn, args in tasks]
    context = multiprocessing.get_context("fork" if sys.platform == "linux" else "spawn")
    try:
        with ProcessPoolExecutor(max_workers=min(workers, len(tasks)),
                                 mp_context=context) as pool:
            futures = [pool.submit(_capture, fn, *args) for fn, args in tasks]
            return [f.result() for f in futures]
    except BrokenProcessPool as exc:
        raise WorkerLostError(f"a probe worker process died mid-run ({exc}); run again with "
                              "fewer workers (each holds one simulation)") from None


def _capture(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)``, or the exception it raised (kept for the caller to raise in order)."""
    try:
        return fn(*args)
    except Exception as exc:  # every error goes back, to be raised in order
        return exc


def outcome(result: Any) -> Any:
    """A :func:`run_ahead` result: raise it where it is an exception, else return it."""
    if isinstance(result, BaseException):
        raise result
    return result
