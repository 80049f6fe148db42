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
import os
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, suppress
from multiprocessing.context import BaseContext
from typing import Any

from fetch_env.clipping import rewarn
from fetch_env.errors import require, require_int

__all__ = ["Task", "WorkerLostError", "end_workers", "outcome", "pool_context",
           "raise_interrupt", "run_ahead", "stop_exit_code", "stop_on_signals", "stopping",
           "worker_signals"]

# One simulation: a module-level function (picklable) and its arguments.
Task = tuple[Callable[..., Any], tuple[Any, ...]]


class WorkerLostError(RuntimeError):
    """A worker process of :func:`run_ahead` died (killed, out of memory) mid-run."""


def run_ahead(tasks: Sequence[Task], workers: int) -> list[Any]:
    """Each task's result, or the exception it raised, in the tasks' order.

    ``workers`` processes (at most one per task) run them; 1 runs them here, one after the
    other, and so does a daemonic process (a pool's worker may not start processes of its
    own).  The workers start as :func:`pool_context` says.  An exception from a worker
    carries the worker's traceback as a note.

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
    context = pool_context()
    pool = ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=context,
                               initializer=worker_signals)
    try:
        with stopping(pool):
            futures = [pool.submit(_capture_remote, fn, *args) for fn, args in tasks]
            done = [f.result() for f in futures]
    except BrokenProcessPool as exc:
        hint = "if it ran out of memory, run with fewer workers"
        if context.get_start_method() != "fork":  # its workers run the main script again
            hint += ("; in a script, start the work under if __name__ == \"__main__\": "
                     "(workers here run the main script again)")
        raise WorkerLostError(f"a probe worker process died mid-run ({exc}); {hint}") from None
    seen: set[tuple[type[Warning], str]] = set()
    for _, caught in done:
        for key in caught:
            if key not in seen:
                seen.add(key)
                rewarn(*key)
    return [result for result, _ in done]


def pool_context() -> BaseContext:
    """How a pool's workers start.

    On Linux they are forked where this process runs no other Python thread (the command
    line, a script): they start at once, everything imported.  Where other threads run (a
    notebook's kernel, an application) a fork copies any lock one of them holds, and a worker
    could hang on it (Python 3.12 warns of it): there they come from multiprocessing's fork
    server, and import the tasks' modules themselves (about a second a worker).  Elsewhere
    they are spawned.  A fork server or spawned worker runs the main script again, so a
    script with threads of its own starts its pools under ``if __name__ == "__main__":``.
    """
    if sys.platform != "linux":
        return multiprocessing.get_context("spawn")
    return multiprocessing.get_context("fork" if threading.active_count() == 1
                                       else "forkserver")


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


def worker_signals() -> None:
    """A pool worker's signal handlers (its ``initializer``): it stops quietly on SIGTERM and
    SIGHUP, unless the main process ignored them when it started the worker (``nohup``), and
    leaves Ctrl-C to the main process."""
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def raise_interrupt(signum: int, _frame: Any) -> None:
    """A signal handler that stops the main process as Ctrl-C does, naming the signal."""
    raise KeyboardInterrupt(signal.Signals(signum).name)


def stop_on_signals() -> None:
    """Make SIGTERM and SIGHUP stop this process as Ctrl-C does (:func:`raise_interrupt`;
    call it from the main thread), except one ignored now (``nohup`` ignores SIGHUP), which
    stays ignored."""
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, raise_interrupt)


def stop_exit_code(interrupt: BaseException | str | None) -> int:
    """The exit code of a command that a stop ended: 128 + the number of the signal that
    ``interrupt`` names (a ``KeyboardInterrupt`` from :func:`raise_interrupt`, or its name:
    "SIGTERM" gives 143), as a shell reports a process that signal killed; 130 (Ctrl-C's)
    where it names none."""
    if isinstance(interrupt, BaseException):
        interrupt = interrupt.args[0] if interrupt.args else None
    known = isinstance(interrupt, str) and interrupt in signal.Signals.__members__
    return 128 + (signal.Signals[interrupt] if known else signal.SIGINT).value


@contextmanager
def stopping(pool: ProcessPoolExecutor) -> Iterator[None]:
    """Run ``pool``'s work within the block and stop the pool on leaving it, however.

    On entering, the pool's workers are started with the stop signals held back (one
    arriving while a worker is being forked would leave that worker running, unrecorded by
    the pool) and delivered once all are recorded.  Within the block SIGTERM and SIGHUP
    raise ``KeyboardInterrupt`` (:func:`raise_interrupt`), but for one ignored on entering
    (``nohup`` ignores SIGHUP), which stays ignored here and in the workers.  On leaving,
    Ctrl-C, SIGTERM and SIGHUP are ignored while what has not started is cancelled and
    every worker is terminated (killed if it has not ended within ``STOP_GRACE`` s) and
    joined, and the pool's manager thread, which reaps workers too, is given as long to
    end (a worker mid-task would otherwise run on after a stop; ``timeout`` and a
    process-group kill send a stop more than once, and a second one raising here would
    print a traceback); then the handlers found are put back.  Signal handlers can be set
    only in the main thread: elsewhere the pool is stopped the same way with the handlers
    left alone.
    """
    main = threading.current_thread() is threading.main_thread()
    stops = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    before = {sig: signal.getsignal(sig) for sig in stops} if main else {}
    # (a stop ignored on entering, as ``nohup`` ignores SIGHUP, stays ignored)
    during = {sig: handler if sig == signal.SIGINT or handler is signal.SIG_IGN
              else raise_interrupt for sig, handler in before.items()}
    try:
        for sig in _start_workers(pool, during):
            signal.raise_signal(sig)
        yield
    finally:
        for sig in before:
            signal.signal(sig, signal.SIG_IGN)
        end_workers(pool)
        _set_handlers(before)


STOP_GRACE = 5.0  # [s] a terminated worker's time to end before it is killed


def end_workers(pool: ProcessPoolExecutor) -> None:
    """Shut ``pool`` down after a stop or a lost worker: cancel what has not started,
    terminate every worker (a worker mid-task would otherwise run on), kill one that has not
    ended within ``STOP_GRACE`` s (one still starting may ignore SIGTERM), join them, and
    give the pool's manager thread, which reaps workers too, as long to end."""
    alive = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in alive:
        with suppress(Exception):  # a worker already gone, or its handle closed
            proc.terminate()
    for proc in alive:
        with suppress(Exception):
            proc.join(STOP_GRACE)
            if proc.exitcode is None:
                proc.kill()
                proc.join(STOP_GRACE)
    if manager is not None:
        manager.join(timeout=STOP_GRACE)


def _start_workers(pool: ProcessPoolExecutor, after: dict[int, Any]) -> list[int]:
    """Start every worker of ``pool`` (one no-op task each: the pool forks, or asks the fork
    server for, each worker within ``submit``) with the signals in ``after`` held back
    (those not ignored), then set ``after``'s handlers and return the signals held.

    A worker forked from this process meanwhile inherits the holding handler until its
    initializer runs: there a held signal does what it does by default (a ``terminate``
    kills it).
    """
    home, held = os.getpid(), []

    def hold(signum: int, _frame: Any) -> None:
        if os.getpid() != home:
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        if signum not in held:
            held.append(signum)

    for sig, handler in after.items():
        if handler is not signal.SIG_IGN:
            signal.signal(sig, hold)
    try:
        for _ in range(getattr(pool, "_max_workers", 1)):
            pool.submit(int)
    except BaseException:
        _set_handlers(after)
        for sig in held:  # a stop that came meanwhile is what the caller is told
            signal.raise_signal(sig)
        raise
    _set_handlers(after)
    return held


def _set_handlers(handlers: dict[int, Any]) -> None:
    for sig, handler in handlers.items():
        signal.signal(sig, handler)
