"""Evaluate agents on the same seeded scenes: per-episode records, summaries with 95 %
intervals, regret against ``search``, CSV/JSON output and plots.

Episode ``i`` of every agent uses the scene of ``env.reset(seed=seed + i)`` and the agent is
seeded with ``seed + i`` too, so each (agent, episode) is an independent, reproducible work
item: ``workers > 1`` runs them in a process pool and gives the same numbers as one worker,
a stopped run can be resumed from the records that finished (:mod:`agents.episode_log`),
and a worker that dies costs only its tasks, rerun once on a fresh pool.  Ctrl-C, SIGTERM
and SIGHUP (under :class:`StopSignals`) stop a run with every finished record kept.  The
intervals stay inside what each quantity can be (:data:`INTERVALS`).
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.base import Agent

AGENT_NAMES: tuple[str, ...] = ("random", "study", "size-only", "model-based", "search")
REFERENCE = "search"


class AgentSpecError(Exception):
    """An unknown agent name or an unusable model path (one line)."""


def make_agent(spec: str, env_id: str | None = None) -> Agent:
    """An agent from a name in ``AGENT_NAMES``, the path of a saved SB3 model (.zip) or of
    a policy exported by ``train --backend rllib`` (``policy.npz``, or its folder)."""
    if spec == "random":
        from agents.baselines import RandomAgent

        return RandomAgent()
    if spec == "study":
        from agents.baselines import StudyAgent

        diced = None if env_id is None else env_id.startswith("FoodFetch-Diced")
        return StudyAgent(diced=diced)
    if spec == "size-only":
        from agents.baselines import SizeOnlyAgent

        return SizeOnlyAgent()
    if spec == "model-based":
        from agents.model_based import ModelBasedAgent

        return ModelBasedAgent()
    if spec == "search":
        from agents.search import SearchAgent

        return SearchAgent()
    looks_like_path = spec.endswith((".zip", ".npz")) or "/" in spec or Path(spec).exists()
    if not looks_like_path:
        raise AgentSpecError(f"unknown agent {spec!r}; choose from {', '.join(AGENT_NAMES)} "
                             "or give the path of a saved model (.zip, or an RLlib "
                             "policy.npz)")
    if spec.endswith(".npz") or (Path(spec) / "policy.npz").is_file():
        from agents.rllib_policy import PolicyFileError, RLlibPolicyAgent

        try:
            return RLlibPolicyAgent(spec)
        except PolicyFileError as exc:
            raise AgentSpecError(str(exc)) from None
    from agents.sb3_agent import ModelLoadError, SB3Agent

    try:
        return SB3Agent(spec)
    except ModelLoadError as exc:
        raise AgentSpecError(str(exc)) from None


# ------------------------------------------------------------------------------ episodes
@dataclass
class Task:
    agent: str
    env_id: str
    episode: int
    seed: int
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    record: bool = False  # also return the episode's transition (``--dataset``)


_ENVS: dict[tuple[str, str], Any] = {}
_AGENTS: dict[tuple[str, str], Agent] = {}
_WARM: list[bool] = []


def warm_up() -> None:
    """Compile one scene of every piece shape, once per process, before any episode.

    MuJoCo's compiler leaves last-bit differences in a flex's mass and stiffness that depend
    on which scene of that shape was compiled first in the process (found while checking
    ``--workers``); the contacts amplify them to ~1e-4 in LE.  Compiling a fixed scene of
    each shape first makes every later episode independent of the process's history, so
    any number of workers gives the same numbers.
    """
    if _WARM:
        return
    from fetch_env.layouts import SHAPES, Piece
    from fetch_env.scene import build_scene

    for shape in SHAPES:
        build_scene((Piece(shape, 0.015),))  # type: ignore[arg-type]
    _WARM.append(True)


def _env(env_id: str, env_kwargs: dict[str, Any]) -> Any:
    import gymnasium as gym

    import fetch_env  # noqa: F401  (registers the ids)

    key = (env_id, repr(sorted(env_kwargs.items())))
    if key not in _ENVS:
        _ENVS[key] = gym.make(env_id, **env_kwargs)
    return _ENVS[key]


def run_episode(task: Task) -> dict[str, Any]:
    """One fetch of one agent on the scene of ``seed``; a flat record."""
    warm_up()
    env = _env(task.env_id, task.env_kwargs)
    key = (task.agent, task.env_id)
    if key not in _AGENTS:
        _AGENTS[key] = make_agent(task.agent, task.env_id)
    agent = _AGENTS[key]
    wall = time.perf_counter()
    obs, reset_info = env.reset(seed=task.seed)
    agent.seed(task.seed)
    agent.begin_episode(env)
    action = np.asarray(agent.act(obs), np.float32)
    next_obs, reward, terminated, truncated, info = env.step(action)
    wall = time.perf_counter() - wall
    applied = info.get("action_applied", {})
    k = int(reset_info.get("probe_piece", 0))
    pieces = reset_info.get("pieces", [])
    material = pieces[k]["material"] if pieces else {}
    le = info.get("max_log_strain")
    record = {
        "agent": task.agent, "episode": task.episode, "seed": task.seed,
        "reward": float(reward), "fetch_rate": float(info.get("fetch_rate", 0.0)),
        "is_success": bool(info.get("is_success", False)),
        "max_log_strain": float(le) if le is not None else math.nan,
        "time_per_fetch": float(info.get("episode_time", math.nan)),
        "reward_fetch": float(info.get("reward_fetch", 0.0)),
        "reward_deformation": float(info.get("reward_deformation", 0.0)),
        "theta_d": float(applied.get("theta_d", math.nan)),
        "omega": float(applied.get("omega", math.nan)),
        "lift_speed": float(applied.get("lift_speed", math.nan)),
        "n_pieces": len(pieces),
        "young": float(material.get("young", math.nan)),
        "true_K1": float(reset_info.get("true_params", {}).get("K1") or math.nan),
        "diverged": "error" in info, "wall_s": wall,
    }
    if task.record:  # the data of a Minari episode, written by the parent in seed order
        from agents.datasets import transition

        record["transition"] = transition(obs, reset_info, action, next_obs, float(reward),
                                          bool(terminated), bool(truncated), info)
    return record


def _init_worker() -> None:
    """A worker leaves Ctrl-C to the parent (the terminal sends it to the whole group) and
    dies at once on SIGTERM or SIGHUP (the parent stops the run and reruns nothing)."""
    from fetch_env.parallel import worker_signals

    worker_signals()  # (a signal ignored under nohup stays ignored)
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


# ------------------------------------------------------------------------------ stopping
class StopRequested(KeyboardInterrupt):
    """Ctrl-C, SIGTERM or SIGHUP while :class:`StopSignals` is armed (a KeyboardInterrupt,
    so code that handles Ctrl-C handles the others alike)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class StopSignals:
    """Ctrl-C, SIGTERM and SIGHUP as one request to stop, in the main thread.

    While armed, the first of them raises :class:`StopRequested`; later ones, and any that
    comes once disarmed (while the results are written), are only remembered in ``signum``,
    so the writing finishes and a second signal cannot cut it short.  A signal that was
    ignored when the block started (``nohup``, a background job's SIGINT) stays ignored.
    The previous handlers come back when the block ends.
    """

    SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self) -> None:
        self.signum: int | None = None
        self.armed = True
        self._old: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                old = signal.getsignal(sig)
                if old is not signal.SIG_IGN:
                    self._old[sig] = old
                    signal.signal(sig, self._handle)
        return self

    def __exit__(self, *_exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)

    def _handle(self, signum: int, _frame: Any) -> None:
        first = self.signum is None
        if first:
            self.signum = signum
        if first and self.armed:
            raise StopRequested(signum)


class EvaluationInterrupted(Exception):
    """The run stopped before every task finished.

    ``results``: the finished records in task order; ``reason``: why, as a phrase
    ("stopped by SIGTERM"); ``code``: the exit code a command should end with (128 + the
    signal's number, 1 for a lost worker or a failed episode).
    """

    def __init__(self, results: list[dict[str, Any]], reason: str = "stopped by SIGINT",
                 code: int = 128 + signal.SIGINT) -> None:
        super().__init__(reason)
        self.results = results
        self.reason = reason
        self.code = code


class _WorkersLost(Exception):
    pass


class _EpisodeFailed(Exception):
    def __init__(self, task: Task, exc: BaseException | str) -> None:
        """``exc``: the exception, or its ``"TypeName: message"`` (raised on another machine)."""
        if isinstance(exc, BaseException):
            line = str(exc).splitlines()[0] if str(exc) else ""
            exc = f"{type(exc).__name__}{': ' + line if line else ''}"
        super().__init__(f"{task.agent!r} episode {task.episode} (seed {task.seed}) failed: "
                         f"{exc}")


# ------------------------------------------------------------------------------ running
def run_tasks(tasks: Sequence[Task], workers: int = 1,
              on_result: Callable[[dict[str, Any]], None] | None = None,
              stop: StopSignals | None = None,
              notify: Callable[[str], None] | None = None, ray_address: str | None = None,
              ray_batch: int | None = None) -> list[dict[str, Any]]:
    """Run the tasks (in a process pool when ``workers > 1``, as Ray tasks when
    ``ray_address`` is given: see :mod:`agents.ray_runner`); results in task order.

    ``on_result`` sees each record as it finishes.  A stop (Ctrl-C, or SIGTERM/SIGHUP under
    ``stop``), a worker process lost twice (the first loss reruns the unfinished tasks on a
    fresh pool, saying so through ``notify``) or an episode that raises ends the run with
    :class:`EvaluationInterrupted`, which holds every finished record.
    """
    done: dict[int, dict[str, Any]] = {}

    def collect(i: int, rec: dict[str, Any]) -> None:
        done[i] = rec
        if on_result is not None:
            on_result(rec)

    workers = min(workers, len(tasks))  # an idle worker would only cost its start-up
    try:
        if ray_address is not None:
            from agents.ray_runner import ClusterLost, TaskFailed, run_on_ray

            try:
                run_on_ray(tasks, collect, ray_address, max(workers, 1), ray_batch)
            except ClusterLost as exc:
                raise _WorkersLost(str(exc)) from None
            except TaskFailed as exc:
                raise _EpisodeFailed(exc.task, exc.error) from None
        elif workers <= 1:
            for i, task in enumerate(tasks):
                try:
                    rec = run_episode(task)
                except Exception as exc:
                    raise _EpisodeFailed(task, exc) from exc
                collect(i, rec)
        else:
            _run_in_pools(tasks, workers, collect, notify)
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        raise EvaluationInterrupted(_in_order(done), f"stopped by {signal.Signals(signum).name}",
                                    128 + signum) from None
    except (_WorkersLost, _EpisodeFailed) as exc:
        raise EvaluationInterrupted(_in_order(done), str(exc), 1) from exc
    return _in_order(done)


def _in_order(done: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    return [done[i] for i in sorted(done)]


def _run_in_pools(tasks: Sequence[Task], workers: int,
                  collect: Callable[[int, dict[str, Any]], None],
                  notify: Callable[[str], None] | None) -> None:
    """The tasks on a pool of ``workers`` processes; when a worker dies (killed, out of
    memory) the pool breaks visibly, and the unfinished tasks run once more on a fresh
    pool.  A second loss raises :class:`_WorkersLost`."""
    from concurrent.futures.process import BrokenProcessPool

    pending = dict(enumerate(tasks))
    try:
        _run_pool(pending, workers, collect)
        return
    except BrokenProcessPool:
        # A stop sent to every process of the job (scancel) kills the workers too: give the
        # parent's own signal a moment to arrive, so that is a stop and not a lost worker.
        time.sleep(0.2)
    if notify is not None:
        notify(f"a worker process died (killed, or out of memory?); its {len(pending)} "
               "unfinished task(s) run again on a fresh pool")
    try:
        _run_pool(pending, workers, collect)
    except BrokenProcessPool:
        time.sleep(0.2)
        raise _WorkersLost(f"a worker process died again on the fresh pool; {len(pending)} "
                           f"of {len(tasks)} task(s) unfinished") from None


def _forget_a_dead_tracker() -> None:
    """If multiprocessing's resource tracker was killed during the run, stop telling it
    about semaphores: its relaunch at exit would print a KeyError traceback for every
    semaphore the dead one knew.  Called as a pool closes, when no worker is started any
    more: this process unlinks its semaphores itself as they are freed or it exits
    (``SemLock._cleanup``), so nothing leaks."""
    from multiprocessing import resource_tracker

    tracker = getattr(resource_tracker, "_resource_tracker", None)
    alive = getattr(tracker, "_check_alive", None)
    if alive is None or getattr(tracker, "_fd", None) is None or alive():
        return

    def ignore(_name: str, _rtype: str) -> None:
        return None

    resource_tracker.register = resource_tracker.unregister = ignore


def _run_pool(pending: dict[int, Task], workers: int,
              collect: Callable[[int, dict[str, Any]], None]) -> None:
    """Run ``pending`` (index -> task) on one fresh pool, removing each as it finishes."""
    import concurrent.futures as cf
    import multiprocessing as mp
    from concurrent.futures.process import BrokenProcessPool

    pool = cf.ProcessPoolExecutor(min(workers, len(pending)),
                                  mp_context=mp.get_context("spawn"),  # clean MuJoCo/torch
                                  initializer=_init_worker)
    clean = False
    try:
        futures = {pool.submit(run_episode, task): i for i, task in pending.items()}
        for fut in cf.as_completed(futures):
            i = futures[fut]
            try:
                rec = fut.result()
            except BrokenProcessPool:
                _harvest(futures, pending, collect)
                raise
            except Exception as exc:
                raise _EpisodeFailed(pending[i], exc) from exc
            del pending[i]
            collect(i, rec)
        clean = True
    finally:
        _forget_a_dead_tracker()  # before the pool's queues are freed and unregistered
        _close_pool(pool, clean)


def _harvest(futures: dict[Any, int], pending: dict[int, Task],
             collect: Callable[[int, dict[str, Any]], None]) -> None:
    """Collect the tasks that finished on a pool before it broke (not yet seen)."""
    for fut, i in futures.items():
        if i in pending and fut.done() and not fut.cancelled() and fut.exception() is None:
            del pending[i]
            collect(i, fut.result())


def _close_pool(pool: Any, clean: bool) -> None:
    """Shut ``pool`` down; after a stop or a lost worker, its workers are ended too (one
    mid-episode would otherwise run on after the stop), so nothing hangs or leaks."""
    if clean:
        pool.shutdown(wait=True)
        return
    from fetch_env.parallel import end_workers

    end_workers(pool)


# ------------------------------------------------------------------------------ statistics
def mean_ci(x: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t interval (NaNs dropped); one value gives a zero-width interval."""
    a = np.asarray([v for v in x if math.isfinite(v)], dtype=float)
    if a.size == 0:
        return math.nan, math.nan, math.nan
    m = float(a.mean())
    if a.size == 1:
        return m, m, m
    from scipy import stats

    h = float(stats.t.ppf(0.5 + level / 2, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return m, m - h, m + h


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a proportion k / n."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


MIN_EPISODES = 5  # fewer values than this: the values themselves, "n too small", no interval
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0  # a fixed seed: the same records give the same interval, run or resumed
# The per-episode means of the summary and how each 95 % interval is made: a reward (and a
# regret) can be negative, so Student t fits; a fetch rate lies in [0, 1] and LE and time
# cannot be negative, so a percentile bootstrap, whose interval never leaves the range of
# the values (a t interval does at small n: "time/fetch 1.69 ± 5.77" at 2 episodes).
MEANS: tuple[tuple[str, str], ...] = (
    ("reward", "t"), ("fetch_rate", "bootstrap"), ("max_log_strain", "bootstrap"),
    ("time_per_fetch", "bootstrap"))
INTERVALS: dict[str, Any] = {
    "level": 0.95, "min_episodes": MIN_EPISODES,
    "reward": "Student t (a reward can be negative)",
    "regret": "Student t of the paired differences (a regret can be negative)",
    "fetch_rate": f"percentile bootstrap of the mean ({BOOTSTRAP_RESAMPLES} resamples, seed "
                  f"{BOOTSTRAP_SEED}): inside [0, 1]",
    "max_log_strain": "percentile bootstrap of the mean: never below 0",
    "time_per_fetch": "percentile bootstrap of the mean: never below 0",
    "success_rate": "Wilson score: inside [0, 1]",
}


def bootstrap_ci(x: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Mean and percentile-bootstrap interval (NaNs dropped; seeded, so repeatable).

    The interval lies within [min(x), max(x)]: a mean of non-negative values never gets a
    negative bound, a mean of rates never leaves [0, 1]."""
    a = np.asarray([v for v in x if math.isfinite(v)], dtype=float)
    if a.size == 0:
        return math.nan, math.nan, math.nan
    m = float(a.mean())
    if a.size == 1 or float(np.ptp(a)) == 0.0:
        return m, m, m
    import inspect

    from scipy import stats

    seed = np.random.default_rng(BOOTSTRAP_SEED)  # scipy >= 1.15 names it rng
    rng = {"rng" if "rng" in inspect.signature(stats.bootstrap).parameters
           else "random_state": seed}
    res = stats.bootstrap((a,), np.mean, n_resamples=BOOTSTRAP_RESAMPLES,
                          batch=max(1, min(BOOTSTRAP_RESAMPLES, 2**22 // a.size)),
                          confidence_level=level, method="percentile", **rng)
    lo, hi = (float(v) for v in res.confidence_interval)
    return m, max(lo, float(a.min())), min(hi, float(a.max()))


def _mean_entries(key: str, values: Sequence[float], method: str) -> dict[str, Any]:
    """``KEY_mean`` and ``KEY_ci95``; below :data:`MIN_EPISODES` finite values the interval
    is [NaN, NaN] and ``KEY_values`` holds every value, in episode order."""
    finite = [v for v in values if math.isfinite(v)]
    if len(finite) < MIN_EPISODES:
        m = float(np.mean(finite)) if finite else math.nan
        return {f"{key}_mean": m, f"{key}_ci95": [math.nan, math.nan],
                f"{key}_values": [float(v) for v in values]}
    m, lo, hi = (mean_ci if method == "t" else bootstrap_ci)(finite)
    return {f"{key}_mean": m, f"{key}_ci95": [lo, hi]}


def _agent_summary(recs: list[dict[str, Any]], ref: dict[int, float]) -> dict[str, Any]:
    """One agent's summary (its records in episode order)."""
    n = len(recs)
    s: dict[str, Any] = {"episodes": n, "n_too_small": n < MIN_EPISODES}
    for key, method in MEANS:
        s.update(_mean_entries(key, [r[key] for r in recs], method))
    les = [r["max_log_strain"] for r in recs if math.isfinite(r["max_log_strain"])]
    s["max_log_strain_max"] = max(les) if les else math.nan
    k = sum(bool(r["is_success"]) for r in recs)
    s["success_rate"] = k / n
    if n < MIN_EPISODES:
        s["success_rate_ci95"] = [math.nan, math.nan]
        s["success_rate_values"] = [int(bool(r["is_success"])) for r in recs]
    else:
        s["success_rate_ci95"] = list(wilson(k, n))
    s["diverged"] = sum(bool(r["diverged"]) for r in recs)
    s["theta_d_mean"] = float(np.mean([r["theta_d"] for r in recs]))
    s["wall_s_mean"] = float(np.mean([r["wall_s"] for r in recs]))
    paired = [ref[r["seed"]] - r["reward"] for r in recs if r["seed"] in ref]
    if paired:
        s.update(_mean_entries("regret", paired, "t"))
        s["regret_episodes"] = len(paired)
    return s


def summarize(records: Sequence[dict[str, Any]], agents: Sequence[str]) -> dict[str, Any]:
    """Per-agent summary with 95 % intervals (:data:`INTERVALS` says how each is made;
    below :data:`MIN_EPISODES` the values instead); regret paired on the seeds ``search``
    ran."""
    by_agent: dict[str, list[dict[str, Any]]] = {a: [] for a in agents}
    for r in records:
        by_agent.setdefault(r["agent"], []).append(r)
    ref = {r["seed"]: r["reward"] for r in by_agent.get(REFERENCE, [])}
    out: dict[str, Any] = {}
    for name in agents:
        recs = sorted(by_agent[name], key=lambda r: r["episode"])
        out[name] = _agent_summary(recs, ref) if recs else {"episodes": 0}
    return out


# ------------------------------------------------------------------------------ output
def _fmt(m: float, ci: Sequence[float], digits: int = 3) -> str:
    """``mean ± half-width``: for a symmetric (Student t) interval."""
    if not math.isfinite(m):
        return "-"
    half = (ci[1] - ci[0]) / 2 if all(math.isfinite(c) for c in ci) else math.nan
    return f"{m:.{digits}f} ± {half:.{digits}f}" if math.isfinite(half) else f"{m:.{digits}f}"


def _fmt_bounds(m: float, ci: Sequence[float], digits: int = 3) -> str:
    """``mean [low, high]``: for an interval that need not be symmetric."""
    if not math.isfinite(m):
        return "-"
    if not all(math.isfinite(c) for c in ci):
        return f"{m:.{digits}f}"
    return f"{m:.{digits}f} [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"


def _fmt_values(values: Sequence[float], digits: int) -> str:
    return ", ".join(f"{v:.{digits}f}" if math.isfinite(v) else "-" for v in values) or "-"


TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("reward", "reward"), ("fetch rate", "fetch_rate"), ("success", "success_rate"),
    ("mean LE", "max_log_strain"), ("max LE", "max_log_strain_max"),
    ("time/fetch [s]", "time_per_fetch"), ("regret", "regret"))
TABLE_LEGEND = (
    "95 % intervals. reward, regret: mean ± half-width, Student t (they can be negative);\n"
    "fetch rate, mean LE, time/fetch: mean [bootstrap], success: rate [Wilson], never "
    "outside what each can be;\nregret = search reward - agent reward on the same scenes")
N_TOO_SMALL = (f"n too small (< {MIN_EPISODES} episodes) for an interval: each episode's "
               "value is shown, in episode order")


def _cell(s: dict[str, Any], key: str) -> str:
    """One agent's table cell for the column ``key``."""
    digits = 2 if key == "time_per_fetch" else 3
    if key == "success_rate":
        if "success_rate_values" in s:
            return ", ".join(str(v) for v in s["success_rate_values"])
        lo, hi = s["success_rate_ci95"]  # Wilson: asymmetric, so the interval itself
        return f"{s['success_rate']:.2f} [{lo:.2f}, {hi:.2f}]"
    if key == "max_log_strain_max":
        return f"{s[key]:.3f}" if math.isfinite(s[key]) else "-"
    if key == "regret" and "regret_mean" not in s:
        return "-"
    if f"{key}_values" in s:
        text = _fmt_values(s[f"{key}_values"], digits)
    elif dict(MEANS).get(key) == "bootstrap":
        text = _fmt_bounds(s[f"{key}_mean"], s[f"{key}_ci95"], digits)
    else:
        text = _fmt(s[f"{key}_mean"], s[f"{key}_ci95"], digits)
    if key == "regret" and s["regret_episodes"] != s["episodes"]:
        text += f" (n={s['regret_episodes']})"
    return text


def format_table(summary: dict[str, Any], markdown: bool = False) -> str:
    """One row per agent: each mean with its 95 % interval (``mean ± half-width`` where the
    interval is symmetric, ``mean [low, high]`` where not); below :data:`MIN_EPISODES`
    episodes the values and a closing "n too small" line."""
    rows = [["agent", "n", *[c for c, _ in TABLE_COLUMNS]]]
    for name, s in summary.items():
        if not s.get("episodes"):
            rows.append([name, "0", *["-"] * len(TABLE_COLUMNS)])
            continue
        rows.append([name, str(s["episodes"]), *[_cell(s, key) for _, key in TABLE_COLUMNS]])
    small = any(k.endswith("_values") for s in summary.values() for k in s)
    if markdown:
        lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
        lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
        return "\n".join(lines + (["", N_TOO_SMALL] if small else []))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
             for r in rows]
    return "\n".join(lines + ([N_TOO_SMALL] if small else []))


CSV_FIELDS: tuple[str, ...] = (
    "agent", "episode", "seed", "reward", "fetch_rate", "is_success", "max_log_strain",
    "time_per_fetch", "reward_fetch", "reward_deformation", "theta_d", "omega", "lift_speed",
    "n_pieces", "young", "true_K1", "diverged", "wall_s")


def write_csv(path: Path, records: Sequence[dict[str, Any]]) -> None:
    """One row per (agent, episode), written atomically (:mod:`agents.atomic`)."""
    import csv

    from agents.atomic import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(CSV_FIELDS), extrasaction="ignore")
        w.writeheader()
        for r in sorted(records, key=lambda r: (r["agent"], r["episode"])):
            w.writerow(r)


def _save_figure(fig: Any, path: Path) -> Path:
    """``fig`` as PNG at ``path``, written atomically, and closed."""
    import matplotlib.pyplot as plt

    from agents.atomic import atomic_path

    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
    return path


def write_plots(directory: Path, summary: dict[str, Any],
                records: Sequence[dict[str, Any]], env_id: str) -> list[Path]:
    """reward.png and fetch_rate.png (mean and 95 % interval per agent; no bar where n is
    too small for an interval) and theta_vs_stiffness.png (the chosen theta_d against the
    probed piece's Young's modulus), each written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    names = [n for n, s in summary.items() if s.get("episodes")]
    out: list[Path] = []
    for key, label in (("reward", "mean reward"), ("fetch_rate", "mean fetch rate")):
        fig, ax = plt.subplots(figsize=(1.4 * len(names) + 2, 3.2))
        means = [summary[n][f"{key}_mean"] for n in names]
        err = np.nan_to_num(np.array([[summary[n][f"{key}_mean"] - summary[n][f"{key}_ci95"][0],
                                       summary[n][f"{key}_ci95"][1] - summary[n][f"{key}_mean"]]
                                      for n in names]).T)
        ax.bar(range(len(names)), means, yerr=err, capsize=4, color="tab:blue", alpha=0.8)
        ax.set_xticks(range(len(names)), [_short(n) for n in names], rotation=15)
        ax.set_ylabel(label)
        ax.set_title(f"{env_id}: {label} (95 % interval)")
        fig.tight_layout()
        out.append(_save_figure(fig, directory / f"{key}.png"))
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for n in names:
        rs = [r for r in records if r["agent"] == n]
        ax.scatter([r["young"] for r in rs], [r["theta_d"] for r in rs], s=12, label=_short(n),
                   alpha=0.7)
    ax.set_xscale("log")
    ax.set_xlabel("probed piece's Young's modulus E_0 [Pa]")
    ax.set_ylabel("theta_d applied [rad]")
    ax.set_title(f"{env_id}: chosen clamp angle against stiffness")
    ax.legend(fontsize=8)
    fig.tight_layout()
    out.append(_save_figure(fig, directory / "theta_vs_stiffness.png"))
    return out


def _short(name: str) -> str:
    return name if len(name) <= 18 else "…" + name[-17:]


def record_videos(directory: Path, agents: Sequence[str], env_id: str, seed: int,
                  env_kwargs: dict[str, Any]) -> list[Path]:
    """One MP4 (GIF without ffmpeg) per agent of the first evaluation scene."""
    import gymnasium as gym

    import fetch_env  # noqa: F401

    directory.mkdir(parents=True, exist_ok=True)
    out = []
    env = gym.make(env_id, render_mode="rgb_array_list", **env_kwargs)
    try:
        for name in agents:
            agent = make_agent(name, env_id)
            obs, _ = env.reset(seed=seed)
            agent.seed(seed)
            agent.begin_episode(env)
            env.step(agent.act(obs))
            frames = env.render()
            stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in _short(name))
            out.append(_save_frames(directory / stem, frames, env.metadata["render_fps"]))
    finally:
        env.close()
    return out


def _save_frames(stem: Path, frames: list[np.ndarray], fps: int) -> Path:
    """The frames as MP4 (GIF without ffmpeg), written atomically."""
    import imageio.v2 as imageio

    from agents.atomic import atomic_path

    try:
        path = stem.with_suffix(".mp4")
        with atomic_path(path) as tmp:
            imageio.mimsave(tmp, frames, fps=fps)
    except OSError:
        raise  # no folder, no space: a GIF would fail alike
    except Exception:  # no ffmpeg backend: a GIF still shows the fetch
        path = stem.with_suffix(".gif")
        with atomic_path(path) as tmp:
            imageio.mimsave(tmp, frames, duration=1000 / fps)
    return path
