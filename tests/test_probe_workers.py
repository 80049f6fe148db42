"""The probes' simulations run at once on several processes (``run_probes(workers=)``,
``food-fetch estimate --workers``): the serial numbers, errors raised in their serial order,
a dead worker said in one line."""

from __future__ import annotations

import json
import math
import multiprocessing
import multiprocessing.forkserver
import multiprocessing.resource_tracker
import os
import pickle
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

import fetch_env.parallel
import fetch_env.probes.run as probe_run
from fetch_env.clipping import reported_elsewhere
from fetch_env.controller import FetchSimulator
from fetch_env.errors import (
    InvalidParameterError,
    ParameterClippedWarning,
    SimulationDivergedError,
)
from fetch_env.layouts import single_block
from fetch_env.materials import Material
from fetch_env.parallel import (
    WorkerLostError,
    outcome,
    pool_context,
    run_ahead,
    stop_exit_code,
    stop_on_signals,
)
from fetch_env.probes import (
    PROBE_CALIBRATIONS,
    PROBE_PRESETS,
    run_probes,
    simulate_probes,
    true_parameters_exact,
)
from tests.cli_helpers import assert_one_line_error, run_cli

# a small stiff ellipsoid: the seven clamps of the repeated probes in ~1 s
PIECES = single_block("ellipsoid", 0.012, Material(young=8e5, g1=0.35, tau1=1.2, mu=0.4))


@pytest.fixture(params=["fork", "forkserver"])
def start_method(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both ways :func:`fetch_env.parallel.pool_context` starts workers on Linux, whatever
    threads the test process runs."""
    context = multiprocessing.get_context(request.param)
    monkeypatch.setattr(fetch_env.parallel, "pool_context", lambda: context)
    return str(request.param)


@pytest.mark.parametrize(("preset", "noise"),
                         [("repeated", 0.0), ("repeated", 0.01), ("precise", 0.01)])
def test_workers_give_the_serial_estimates(preset: str, noise: float) -> None:
    """Two workers: every estimate, interval, diagnostic and warning equal to the serial
    run's, bit for bit (each simulation is deterministic; the noise is drawn afterwards)."""
    config, cal = PROBE_PRESETS[preset], PROBE_CALIBRATIONS[preset]
    serial = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal)
    pooled = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal, workers=2)
    assert pooled.estimates == serial.estimates
    assert pooled.intervals == serial.intervals
    assert pooled.warnings == serial.warnings
    assert pooled.details["diagnostics"] == serial.details["diagnostics"]
    assert pooled.reliable == serial.reliable
    assert pooled.visco_valid and pooled.friction_valid


def test_both_start_methods_give_the_serial_estimates(start_method: str) -> None:
    config, cal = PROBE_PRESETS["repeated"], PROBE_CALIBRATIONS["repeated"]
    serial = run_probes(PIECES, config, noise=0.01, seed=4, calibration=cal)
    pooled = run_probes(PIECES, config, noise=0.01, seed=4, calibration=cal, workers=2)
    assert (pooled.estimates, pooled.intervals) == (serial.estimates, serial.intervals)


@pytest.mark.parametrize(("workers", "noise"), [(1, 0.01), (2, 0.0)])
def test_simulated_runs_fitted_later_give_the_same_outcome(
        workers: int, noise: float, monkeypatch: pytest.MonkeyPatch) -> None:
    """``simulate_probes`` then ``run_probes(runs=)``: the outcome of one call, bit for bit,
    with no simulation run by the fitting call."""
    config, cal = PROBE_PRESETS["repeated"], PROBE_CALIBRATIONS["repeated"]
    whole = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal)
    runs = simulate_probes(PIECES, config, workers=workers)
    assert len(runs.clamps) == config.relaxation_repeats
    assert len(runs.slides) == config.slip_repeats
    def no_simulation(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("run_probes(runs=) ran a simulation")

    monkeypatch.setattr(FetchSimulator, "run", no_simulation)
    fitted = run_probes(PIECES, config, noise=noise, seed=4, calibration=cal, runs=runs)
    assert (fitted.estimates, fitted.intervals) == (whole.estimates, whole.intervals)
    assert fitted.warnings == whole.warnings
    assert fitted.details["diagnostics"] == whole.details["diagnostics"]
    assert fitted.reliable == whole.reliable and fitted.visco_valid


def test_the_elastic_twin_runs_beside_the_probes() -> None:
    """``simulate_probes(truth=True)`` on two workers: the twin's truth that
    ``true_parameters_exact`` gives, bit for bit, and the probes' runs fitted to the outcome
    of one ``run_probes`` call; without ``truth`` no twin runs."""
    config = PROBE_PRESETS["repeated"]
    runs = simulate_probes(PIECES, config, workers=2, truth=True)
    assert runs.truth == true_parameters_exact(PIECES[0], config)
    fitted = run_probes(PIECES, config, seed=4, runs=runs)
    whole = run_probes(PIECES, config, seed=4)
    assert (fitted.estimates, fitted.intervals) == (whole.estimates, whole.intervals)
    assert simulate_probes(PIECES, config).truth is None


def test_a_twin_that_fails_keeps_its_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """The twin's error is the runs' ``truth``, for the caller to report; the probes' runs
    are kept."""
    def diverge(*_args: object) -> None:
        raise SimulationDivergedError("twin diverged", None, {})

    monkeypatch.setattr(probe_run, "true_parameters_exact", diverge)
    runs = simulate_probes(PIECES, PROBE_PRESETS["repeated"], truth=True)
    assert isinstance(runs.truth, SimulationDivergedError)
    assert len(runs.clamps) == PROBE_PRESETS["repeated"].relaxation_repeats


def test_cli_workers_give_the_serial_numbers(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """``food-fetch estimate --workers 2`` (the twin in the pool): every number of the
    JSON but the timings as with one worker."""
    food = ["--probes", "repeated", "--shape", "ellipsoid", "--size", "0.012", "--young",
            "8e5", "--g1", "0.35", "--tau1", "1.2", "--mu", "0.4"]
    out = {}
    for workers in (1, 2):
        path = tmp_path / f"w{workers}.json"
        code, _, err = run_cli(["estimate", *food, "--workers", str(workers), "--json",
                                str(path)], capsys)
        assert code == 0, err
        out[workers] = {k: v for k, v in json.loads(path.read_text()).items()
                        if k != "details"}
    assert out[2] == out[1]
    assert all(math.isfinite(v) and v > 0 for v in out[2]["true"].values())


def test_runs_of_another_piece_or_config_are_refused() -> None:
    config = PROBE_PRESETS["repeated"]
    runs = simulate_probes(PIECES, config)
    other = single_block("cube", 0.012, Material(young=8e5, g1=0.35, tau1=1.2, mu=0.4))
    with pytest.raises(InvalidParameterError, match="another piece"):
        run_probes(other, config, runs=runs)
    with pytest.raises(InvalidParameterError, match="another config"):
        run_probes(PIECES, PROBE_PRESETS["precise"], runs=runs)
    with pytest.raises(InvalidParameterError, match="runs must be a ProbeRuns"):
        run_probes(PIECES, config, runs="runs.pkl")  # type: ignore[arg-type]


def _context_name(queue: multiprocessing.Queue, threads: int) -> None:  # type: ignore[type-arg]
    stop = threading.Event()
    for _ in range(threads):
        threading.Thread(target=stop.wait, daemon=True).start()
    queue.put(pool_context().get_start_method())
    stop.set()


@pytest.mark.parametrize(("threads", "method"), [(0, "fork"), (1, "forkserver")])
def test_workers_fork_only_where_no_other_thread_runs(threads: int, method: str) -> None:
    """A process with no other Python thread forks its workers; one with a thread (that
    could hold a lock the fork copies) takes them from the fork server."""
    ctx = multiprocessing.get_context("spawn")
    queue: multiprocessing.Queue = ctx.Queue()  # type: ignore[type-arg]
    proc = ctx.Process(target=_context_name, args=(queue, threads))
    proc.start()
    assert queue.get(timeout=60) == method
    proc.join(timeout=60)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_workers_refused_before_any_work(bad: object) -> None:
    with pytest.raises(InvalidParameterError, match="workers"):
        run_probes(PIECES, PROBE_PRESETS["repeated"], workers=bad)  # type: ignore[arg-type]


def _square(x: int) -> int:
    return x * x


def _diverge(x: int) -> int:
    raise SimulationDivergedError(f"diverged at {x}", {"scene": x}, {"theta_d": 0.05})


def _die(x: int) -> int:
    os._exit(3)


def _warn_and_square(x: int) -> int:
    warnings.warn("a value was clipped", ParameterClippedWarning, stacklevel=1)
    return x * x


def _fail(x: int) -> int:
    raise ValueError(f"bad value {x}")


def test_worker_warnings_are_raised_here_once(start_method: str) -> None:
    """Warnings raised in the workers come back to this process, once per text; a clipping
    warning stays silent where the caller reports clipping itself."""
    tasks = [(_warn_and_square, (2,)), (_warn_and_square, (3,))]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # Python >= 3.12 on the fork forced on a process with threads (the test runner's)
        warnings.filterwarnings("ignore", "This process .* is multi-threaded", DeprecationWarning)
        assert run_ahead(tasks, 2) == [4, 9]
    assert [str(w.message) for w in caught] == ["a value was clipped"]
    assert caught[0].category is ParameterClippedWarning
    assert caught[0].filename == __file__  # the caller's line, as the package warns
    with warnings.catch_warnings(record=True) as caught, reported_elsewhere():
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", "This process .* is multi-threaded", DeprecationWarning)
        run_ahead(tasks, 2)
    assert caught == []


def test_a_worker_error_carries_its_traceback() -> None:
    (result,) = run_ahead([(_fail, (5,)), (_square, (1,))], 2)[:1]
    assert isinstance(result, ValueError) and str(result) == "bad value 5"
    assert "in a probe worker process" in result.__notes__[0]
    assert "_fail" in result.__notes__[0]


def _in_a_daemon(queue: multiprocessing.Queue) -> None:  # type: ignore[type-arg]
    queue.put(run_ahead([(_square, (2,)), (_square, (3,))], 2))


def test_a_daemonic_process_runs_the_tasks_itself() -> None:
    """A pool's worker (daemonic) may not start processes: there the tasks run serially."""
    queue: multiprocessing.Queue = multiprocessing.get_context("fork").Queue()  # type: ignore[type-arg]
    proc = multiprocessing.get_context("fork").Process(target=_in_a_daemon, args=(queue,),
                                                        daemon=True)
    proc.start()
    assert queue.get(timeout=60) == [4, 9]
    proc.join(timeout=60)
    assert proc.exitcode == 0


def _sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def _child_pids(pid: int | str = "self") -> set[int]:
    """A process's child processes (this one's by default), as the kernel has them (a worker
    forked but never recorded by the pool shows here, not in
    ``multiprocessing.active_children()``)."""
    pids: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            pids.update(int(pid) for pid in (task / "children").read_text().split())
        except FileNotFoundError:  # a thread that ended meanwhile
            continue
    return pids


def _fork_server() -> set[int]:
    """The fork server's process, where one runs (it serves every pool, and stays)."""
    pid = getattr(multiprocessing.forkserver._forkserver, "_forkserver_pid", None)
    return {pid} if pid else set()


def _pool_services() -> set[int]:
    """The processes multiprocessing keeps for every pool, not workers: the fork server and
    the resource tracker it starts with it (both stay until this process ends)."""
    tracker = getattr(multiprocessing.resource_tracker._resource_tracker, "_pid", None)
    return _fork_server() | ({tracker} if tracker else set())


def _fork_server_children() -> set[int]:
    """The fork server's children (its workers), as the kernel has them."""
    pids: set[int] = set()
    for server in _fork_server():
        for task in Path(f"/proc/{server}/task").glob("*"):
            pids.update(int(pid) for pid in (task / "children").read_text().split())
    return pids


# 0 s: the stop lands while the pool is still forking its workers; 0.2 s: while they run
@pytest.mark.parametrize("delay", [0.0, 0.0, 0.0, 0.2])
def test_sigterm_stops_the_pool_and_leaves_no_worker(delay: float, start_method: str) -> None:
    """SIGTERM while the workers start or run: ``KeyboardInterrupt`` here, every worker
    process gone, the handler found put back."""
    before = signal.getsignal(signal.SIGTERM)
    children_before = _child_pids()

    def stop_once_the_workers_run() -> None:
        deadline = time.monotonic() + 20.0
        while not multiprocessing.active_children() and time.monotonic() < deadline:
            time.sleep(0.001)
        time.sleep(delay)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=stop_once_the_workers_run, daemon=True).start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        run_ahead([(_sleep, (30.0,)), (_sleep, (30.0,)), (_sleep, (30.0,))], 2)
    assert time.monotonic() - start < 10.0
    assert multiprocessing.active_children() == []
    assert _child_pids() <= children_before | _pool_services()
    assert _fork_server_children() == set()
    assert signal.getsignal(signal.SIGTERM) is before


_GROUP_STOP = """
import multiprocessing, os, signal, sys, threading, time
import fetch_env.parallel as par

def main():
    par.pool_context = lambda: multiprocessing.get_context(sys.argv[1])
    def stop():
        while not multiprocessing.active_children():
            time.sleep(0.0002)
        os.killpg(os.getpgid(0), signal.SIGTERM)
    threading.Thread(target=stop, daemon=True).start()
    try:
        par.run_ahead([(time.sleep, (30,))] * 3, 3)
    except KeyboardInterrupt as exc:
        print("stopped by", exc)

if __name__ == "__main__":
    main()
"""


@pytest.mark.parametrize("method", ["fork", "forkserver"])
def test_a_stop_to_the_process_group_as_workers_start_is_a_stop(method: str,
                                                                 tmp_path: Path) -> None:
    """SIGTERM to the whole process group while the pool starts also ends the workers still
    starting, which breaks the pool: the caller is told of the stop, not of a lost worker."""
    script = tmp_path / "group_stop.py"
    script.write_text(_GROUP_STOP)
    root = str(Path(__file__).resolve().parents[1])
    done = subprocess.run([sys.executable, str(script), method], capture_output=True, text=True,
                          timeout=60, start_new_session=True, cwd=root,
                          env={**os.environ, "PYTHONPATH": root})
    assert done.stdout.strip() == "stopped by SIGTERM", done.stdout + done.stderr


def test_errors_come_back_in_their_place(start_method: str) -> None:
    """A task's error is returned in its place, whole (its scene and action too), and
    :func:`outcome` raises it; the other tasks' results are kept."""
    tasks = [(_square, (2,)), (_diverge, (7,)), (_square, (3,))]
    for workers in (1, 2):
        results = run_ahead(tasks, workers)
        assert results[0] == 4 and results[2] == 9
        with pytest.raises(SimulationDivergedError, match="diverged at 7") as info:
            outcome(results[1])
        assert info.value.scene == {"scene": 7} and info.value.action == {"theta_d": 0.05}


def test_simulation_diverged_error_pickles_whole() -> None:
    exc = SimulationDivergedError("m", {"a": 1}, {"b": 2})
    exc.add_note("where")
    back = pickle.loads(pickle.dumps(exc))
    assert (str(back), back.scene, back.action, back.__notes__) == ("m", {"a": 1}, {"b": 2},
                                                                    ["where"])


def test_a_dead_worker_is_one_clear_error(start_method: str) -> None:
    with pytest.raises(WorkerLostError, match="died mid-run"):
        run_ahead([(_die, (1,)), (_square, (2,))], 2)


def test_cli_workers(capsys: pytest.CaptureFixture[str]) -> None:
    """--workers outside the adaptive probes, or below 1: one line, exit 2."""
    code, _, err = run_cli(["estimate", "--probes", "study", "--workers", "2"], capsys)
    assert_one_line_error(code, err)
    assert "--workers 2 applies to the precise, repeated, measure probes" in err
    code, _, err = run_cli(["estimate", "--workers", "0"], capsys)
    assert_one_line_error(code, err)


@pytest.mark.parametrize(("stop", "code"), [
    (KeyboardInterrupt(), 130), (KeyboardInterrupt("SIGTERM"), 143),
    (KeyboardInterrupt("SIGHUP"), 129), ("SIGTERM", 143), (None, 130),
    (KeyboardInterrupt("not a signal"), 130), (KeyboardInterrupt(15), 130)])
def test_stop_exit_code_is_128_plus_the_signal(stop: object, code: int) -> None:
    assert stop_exit_code(stop) == code  # type: ignore[arg-type]


def _default_stop_signals() -> None:
    """In the child: SIGINT and SIGTERM at their defaults, whatever the test runner's (a
    shell's background job starts with SIGINT ignored, and an ignored signal stays ignored:
    the estimate would then rightly run on)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_DFL)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_estimate_stopped_mid_probes_exits_128_plus_the_signal(sig: signal.Signals) -> None:
    """``food-fetch estimate --workers 2`` stopped while its workers simulate: one line
    naming the stop, exit 128 + the signal's number (as a shell reports a process the
    signal killed), no traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "agents.cli", "estimate", "--workers", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=Path(__file__).resolve().parents[1], preexec_fn=_default_stop_signals)
    deadline = time.monotonic() + 60.0
    while len(_child_pids(proc.pid)) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)  # until both workers simulate the clamps
    assert proc.poll() is None, "the estimate ended before its workers started"
    time.sleep(0.5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert err.strip().splitlines() == [
        "food-fetch: interrupted" + (" (SIGTERM)" if sig == signal.SIGTERM else "")], err


NOHUP_RUN = """
import signal, time
from fetch_env.parallel import run_ahead
signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup starts a command
print(run_ahead([(time.sleep, (2.0,)), (time.sleep, (2.0,))], 2), flush=True)
"""


def test_a_hangup_under_nohup_stops_neither_the_run_nor_its_workers() -> None:
    """SIGHUP ignored when the run starts (``nohup``): a hangup sent to the whole process
    group while the workers run ends nothing, and every task's result comes back."""
    proc = subprocess.Popen([sys.executable, "-c", NOHUP_RUN], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            cwd=Path(__file__).resolve().parents[1])
    deadline = time.monotonic() + 60.0
    while len(_child_pids(proc.pid)) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    os.killpg(proc.pid, signal.SIGHUP)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert out.strip() == "[None, None]", out + err


def test_stop_on_signals_leaves_an_ignored_hangup_ignored() -> None:
    """The benchmarks' stop handlers: SIGTERM raises ``KeyboardInterrupt("SIGTERM")``,
    SIGHUP ignored beforehand (``nohup``) stays ignored."""
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        stop_on_signals()
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is fetch_env.parallel.raise_interrupt
        with pytest.raises(KeyboardInterrupt, match="SIGTERM") as stop:
            signal.raise_signal(signal.SIGTERM)
        assert stop_exit_code(stop.value) == 143
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
