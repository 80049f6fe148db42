"""Evaluation episodes, and any other independent, seeded work items, as Ray tasks on a
local Ray instance or an existing cluster (``food-fetch evaluate --ray [ADDRESS]``, the
estimator validation harness's ``--ray``; the ``ray`` extra).

Each (agent, episode) task is the same independent work item as on the process pool
(:func:`agents.evaluate.run_episode`: the scene of ``reset(seed)``, the agent seeded alike,
every shape compiled once first), so any cluster gives the numbers of ``--workers 1``, and
the results are put back in task order.  Episodes go to Ray in batches (``batch`` per task),
which keeps Ray's per-task cost a small share of a one-second Block episode.

Why Ray: it schedules tasks over every machine of a cluster, retries a task whose worker
died, and lets a task start more tasks (``search`` spreads its per-scene simulations), with
no code of ours for any of it.  What is ours: the address check before any work starts, the
stop (Ctrl-C, SIGTERM: the unfinished tasks ended, the finished ones kept), and a
cluster that goes away ending the run with one line instead of a hang.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from typing import Any

LOCAL = "local"
# Seconds without an answer from the cluster's head before the run is given up as lost.
HEAD_LOST_AFTER_S = 15.0
# A driver whose head is unreachable would otherwise kill its own process after a minute;
# the watchdog here ends the run with a line first, keeping what finished.
_RAY_ENV = {"RAY_gcs_rpc_server_reconnect_timeout_s": "3600"}
# A local instance's workers run at the command's own priority, as --workers' processes do
# (Ray's default, nice 15, starves them on a machine busy with anything else: measured 20x
# slower Block episodes beside two training runs on 2 cores).
# No usage statistics sent from an instance this command starts (Ray's own opt-out).
_LOCAL_ENV = {"RAY_worker_niceness": "0", "RAY_USAGE_STATS_ENABLED": "0"}


class RaySetupError(Exception):
    """Ray is missing, the address is malformed or nothing answers there (one line)."""


class ClusterLost(Exception):
    """The cluster went away, or a task's worker died twice (one line)."""


class TaskFailed(Exception):
    """A task raised on its worker: the task, and ``error`` ("TypeName: first line")."""

    def __init__(self, task: Any, error: str) -> None:
        super().__init__(error)
        self.task = task
        self.error = error


def check_address(address: str) -> str:
    """``address`` as Ray takes it: ``local`` (start an instance here), ``auto`` (the
    cluster this machine belongs to), ``HOST:PORT`` (a head's GCS port) or
    ``ray://HOST:PORT`` (Ray Client).  Raises :class:`RaySetupError` naming a bad one."""
    if address in (LOCAL, "auto"):
        return address
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise RaySetupError(f"bad Ray address {address!r}: give 'local', 'auto', HOST:PORT "
                            "or ray://HOST:PORT")
    return address


def why_unreachable(address: str, timeout: float = 3.0) -> str | None:
    """Why a HOST:PORT address does not answer (None: it does, or it is local/auto)."""
    if address in (LOCAL, "auto"):
        return None
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            return None
    except OSError as exc:
        return exc.strerror or type(exc).__name__


@contextmanager
def connected(address: str, num_cpus: int) -> Iterator[tuple[Any, bool]]:
    """Ray, initialised for ``address`` (a local instance of ``num_cpus`` CPUs for
    ``local``), and whether this call started it (then it shuts it down again at the end)."""
    try:
        import ray
    except ImportError:
        raise RaySetupError("--ray needs the ray extra: pip install -e '.[ray]'") from None
    why = why_unreachable(address)
    if why is not None:
        raise RaySetupError(f"no Ray cluster answers at {address!r} ({why})")
    for key, value in {**_RAY_ENV, **(_LOCAL_ENV if address == LOCAL else {})}.items():
        os.environ.setdefault(key, value)
    started = not ray.is_initialized()
    if started:
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                  "configure_logging": False}
        kwargs["address"] = address  # "local": always a new instance, whatever RAY_ADDRESS
        if address == LOCAL:
            kwargs["num_cpus"] = num_cpus
        handlers = _stop_handlers()
        try:
            ray.init(**kwargs)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise RaySetupError(f"cannot join the Ray cluster at {address!r}: "
                                f"{_first_line(exc)} (a cluster with token authentication "
                                "needs RAY_AUTH_MODE=token and its token here too)") from None
        finally:
            _restore(handlers)  # Ray's own SIGTERM handler would end the process at once
    try:
        yield ray, started
    finally:
        if started:
            with suppress(Exception):
                ray.shutdown()


def _stop_handlers() -> dict[int, Any]:
    """The Python handlers of the stop signals (main thread only: elsewhere, none)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM,
                                                   signal.SIGHUP)}


def _restore(handlers: dict[int, Any]) -> None:
    for sig, handler in handlers.items():
        if handler is not None:
            signal.signal(sig, handler)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def batches(n_tasks: int, batch: int | None, cpus: int) -> list[range]:
    """Consecutive task indices in groups of ``batch``; by default about four groups per
    CPU, so the load evens out while each group runs several episodes."""
    if batch is None:
        batch = max(1, min(8, n_tasks // max(4 * cpus, 1)))
    return [range(i, min(i + batch, n_tasks)) for i in range(0, n_tasks, batch)]


def _episode(task: Any) -> dict[str, Any]:
    """On a Ray worker: one evaluation episode (:func:`agents.evaluate.run_episode`), the
    worker set up for it first (its shapes compiled, ``search`` spreading over Ray)."""
    from agents import search
    from agents.evaluate import _init_worker, run_episode

    if not search.SPREAD_ON_RAY:  # once per worker process
        _init_worker()
        search.SPREAD_ON_RAY = True
    return run_episode(task)


def _run_batch(tasks: Sequence[Any], run: Callable[[Any], Any]) -> list[tuple[str, Any]]:
    """On a Ray worker: ``run(task)`` for the tasks in order, each ``("ok", record)``; the
    first that raises ends the batch with ``("error", "TypeName: first line")``."""
    out: list[tuple[str, Any]] = []
    for task in tasks:
        try:
            out.append(("ok", run(task)))
        except Exception as exc:  # reported by the driver, one line
            out.append(("error", f"{type(exc).__name__}: {_first_line(exc)}"))
            break
    return out


def run_on_ray(tasks: Sequence[Any], collect: Callable[[int, Any], None],
               address: str, num_cpus: int, batch: int | None = None,
               run: Callable[[Any], Any] = _episode) -> None:
    """Run ``run(task)`` for each of ``tasks`` as Ray tasks (by default an evaluation
    episode), passing each finished record to ``collect(index, rec)``; ``run`` must pickle
    (a module-level function, or one of ``__main__``, which Ray sends by value).

    A task that raises ends the run with :class:`TaskFailed`; a worker that dies is
    replaced by Ray and its batch rerun once; a second death, or a head that stops answering
    for :data:`HEAD_LOST_AFTER_S`, raises :class:`ClusterLost`.  On any exit the unfinished
    tasks end: cancelled on a cluster, shut down with a local instance.
    """
    with connected(address, num_cpus) as (ray, started):
        cpus = max(1, int(ray.cluster_resources().get("CPU", num_cpus)))
        remote = ray.remote(num_cpus=1, max_retries=1)(_run_batch)
        groups = batches(len(tasks), batch, cpus)
        refs = {remote.remote([tasks[i] for i in g], run): g for g in groups}
        try:
            while refs:
                ready = _wait(ray, list(refs), address)
                for ref in ready:
                    group = refs.pop(ref)
                    for i, (status, value) in zip(group, _get(ray, ref, address), strict=False):
                        if status == "error":
                            raise TaskFailed(tasks[i], value)
                        collect(i, value)
        finally:
            # Unfinished tasks: where this run connected (a local instance or a cluster), it
            # disconnects on exit (ray.shutdown), which ends its job's tasks; cancelling them
            # first can race with a task's reply and abort Ray's core worker ("Tried to
            # complete task that was not pending", ray-project/ray#54846).  So only where the
            # caller connected, and the job goes on, are they cancelled.
            for ref in refs if not started else ():
                with suppress(Exception):
                    ray.cancel(ref, force=True)


def _wait(ray: Any, refs: list[Any], address: str) -> list[Any]:
    """The finished refs, waiting in short slices so that a stop signal is seen at once and
    a head that no longer answers is noticed."""
    silent_since: float | None = None
    while True:
        ready, _ = ray.wait(refs, num_returns=1, timeout=0.5)
        if ready:
            return ready
        alive = address == LOCAL or why_unreachable(address, timeout=1.0) is None
        if alive:
            silent_since = None
            continue
        silent_since = silent_since or time.monotonic()
        if time.monotonic() - silent_since > HEAD_LOST_AFTER_S:
            raise ClusterLost(f"the Ray cluster at {address!r} stopped answering")


def _get(ray: Any, ref: Any, address: str) -> list[tuple[str, Any]]:
    """A batch's results; a worker or node that died twice is a lost cluster."""
    from ray import exceptions as rex

    try:
        return ray.get(ref)
    except rex.RayTaskError as exc:  # not raised by _run_batch itself: Ray's own wrapping
        raise ClusterLost(f"a Ray task failed: {_first_line(exc)}") from None
    except rex.RayError as exc:  # WorkerCrashedError, NodeDiedError, ObjectLostError, ...
        raise ClusterLost(f"a Ray worker died again after its retry, on the cluster at "
                          f"{address!r} ({type(exc).__name__})") from None
