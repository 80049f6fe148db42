"""``food-fetch evaluate``: agents side by side on the same seeded scenes."""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.cli.common import (
    DEFAULT_ENV,
    EXIT_USAGE,
    UsageError,
    add_ray_options,
    check_ray_options,
    out_dir,
    positive_int,
    require_distinct,
    require_extra,
    seed,
    writable,
)
from fetch_env.errors import env_error_line

HELP = "evaluate agents side by side on the same seeded scenes"
DESCRIPTION = ("Run each agent on the same seeded scenes (episode i uses "
               "reset(seed=SEED+i)) and print, per agent, the mean reward, fetch rate, success "
               "rate, mean and max logarithmic strain LE, time per fetch and regret against "
               "'search' (the per-scene optimum found with the simulator), each with its 95 % "
               "interval (Student t for reward and regret, bootstrap for fetch rate, LE and "
               "time, Wilson for success: never outside what the quantity can be; below 5 "
               "episodes the values, 'n too small'). Agents: random, study, size-only, "
               "model-based, search, or the path of a model saved by 'food-fetch train'. "
               "Each finished episode is appended to an episode log (--episodes-log) that --resume "
               "continues. Ctrl-C, SIGTERM and SIGHUP stop the run and still write what "
               "finished (exit code 128 + the signal's number); a lost worker's tasks run "
               "once more on a fresh pool; every file is written whole or not at all, and a "
               "file that cannot be written at the end leaves the results in a fallback file "
               "named on stderr (exit code 1). --dataset records the episodes as Minari "
               "datasets for offline RL.")


DEFAULT_AGENTS: tuple[str, ...] = ("random", "study", "model-based")


def _env_kwarg(text: str) -> tuple[str, Any]:
    """KEY=VALUE, the value read as JSON where it is JSON (1000, 0.5, true, null, "x"),
    else as the bare string (estimator=oracle).  Never evaluated as code."""
    key, sep, raw = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(raw)
    except json.JSONDecodeError:
        return key, raw


def _existing_file(path: str) -> Path:
    """``--resume``: a file that exists and can be read and appended to."""
    p = Path(path)
    if not p.is_file():
        raise argparse.ArgumentTypeError(f"no such file: {path!r}")
    if not os.access(p, os.R_OK | os.W_OK):
        raise argparse.ArgumentTypeError(f"cannot read and append to {path!r}")
    return p


def _check_env_kwargs(env_id: str, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """The env kwargs as a dict, checked by building the env once (no reset, no physics):
    the env's own validation names a bad value, a TypeError an unknown name."""
    import gymnasium as gym

    keys = [k for k, _ in pairs]
    twice = next((k for i, k in enumerate(keys) if k in keys[:i]), None)
    if twice is not None:
        raise UsageError(f"food-fetch evaluate: --env-kwargs: {twice} given twice")
    kwargs = dict(pairs)
    if "render_mode" in kwargs:
        raise UsageError("food-fetch evaluate: --env-kwargs: render_mode is not an evaluation "
                         "setting (--video records the first episodes)")
    try:
        gym.make(env_id, **kwargs).close()
    except (TypeError, ValueError) as exc:  # InvalidParameterError is a ValueError
        raise UsageError(f"food-fetch evaluate: --env-kwargs: {env_error_line(exc)}") from None
    return kwargs


def _with_quasi_static(args: argparse.Namespace) -> list[tuple[str, Any]]:
    """``--env-kwargs``, after the id's validated quasi-static setting where
    ``--quasi-static`` asks for it (``fetch_env.quasi_static``; a kwarg given overrides it)."""
    if not args.quasi_static:
        return list(args.env_kwargs)
    from fetch_env.quasi_static import quasi_static_kwargs

    given = {k for k, _ in args.env_kwargs}
    return [(k, v) for k, v in quasi_static_kwargs(args.env).items() if k not in given] + list(
        args.env_kwargs)


def _payload(args: argparse.Namespace, run: _Run, summary: dict[str, Any],
             wall: float) -> dict[str, Any]:
    """The JSON summary of the run (every episode's record with ``--json-episodes``)."""
    from agents.evaluate import INTERVALS

    return {
        "env": args.env, "env_kwargs": run.env_kwargs,
        "episodes": args.episodes, "seed": args.seed,
        "workers": args.workers, "ray": args.ray, "ray_batch": args.ray_batch,
        "search_episodes": args.search_episodes,
        "interrupted": run.stopped is not None,
        "stopped": run.stopped.reason if run.stopped is not None else None,
        "episodes_finished": len(run.records), "wall_time_s": round(wall, 2),
        "episodes_log": None if run.log_path is None else str(run.log_path),
        "resumed_from": None if args.resume is None else str(args.resume),
        "episodes_from_log": run.from_log,
        "intervals": INTERVALS,
        "agents": summary, "agent_settings": run.describe,
        "command": ["food-fetch", *sys.argv[1:]] if sys.argv[0].endswith("food-fetch")
        else ["food-fetch", "evaluate", *[a for a in sys.argv[1:]]],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version()},
        "episodes_detail": run.records if args.json_episodes else None,
    }


@dataclass
class _Run:
    """One evaluation as the command runs it: the checked inputs, the planned tasks, the
    episode log and, once run, the records in task order and why it stopped (if it did)."""

    agents: list[str]
    describe: dict[str, Any]
    env_kwargs: dict[str, Any]
    datasets: dict[str, str]
    n_search: int
    plan: list[Any] = field(default_factory=list)
    header: dict[str, Any] = field(default_factory=dict)
    log_path: Path | None = None
    logged: list[dict[str, Any]] = field(default_factory=list)
    records: list[dict[str, Any]] = field(default_factory=list)
    stopped: Any = None  # agents.evaluate.EvaluationInterrupted
    from_log: int = 0


def _checked_agents(args: argparse.Namespace) -> tuple[list[str], dict[str, Any],
                                                       dict[str, str]]:
    """The agents to evaluate, their descriptions and each model file's SHA-256; a bad name,
    path or model file is one usage line, before any episode runs."""
    from agents.episode_log import file_digest
    from agents.evaluate import AgentSpecError, make_agent

    agents = list(dict.fromkeys(args.agent or DEFAULT_AGENTS))
    describe, files = {}, {}
    for spec in agents:
        try:
            agent = make_agent(spec, args.env)
            if hasattr(agent, "model"):
                agent.model  # noqa: B018 (load now: a corrupt file is a usage error)
                files[spec] = file_digest(getattr(agent, "path", spec))
            elif hasattr(agent, "net"):  # an RLlib policy: its weights file
                path = Path(spec)
                files[spec] = file_digest(path / "policy.npz" if path.is_dir() else path)
            describe[spec] = agent.describe()
        except AgentSpecError as exc:
            raise UsageError(f"food-fetch evaluate: {exc}") from None
        except Exception as exc:  # e.g. a model file SB3 cannot read
            raise UsageError(f"food-fetch evaluate: cannot use agent {spec!r}: {exc}") from None
    return agents, describe, files


def _log_path(args: argparse.Namespace) -> Path | None:
    """Where the episode log goes: ``--resume``'s file, ``--episodes-log``, else beside
    ``--json`` (``x.json`` -> ``x.episodes.jsonl``), else beside ``--csv``, else nowhere."""
    if args.resume is not None:
        if args.episodes_log is not None and (os.path.realpath(args.episodes_log)
                                              != os.path.realpath(args.resume)):
            raise UsageError("food-fetch evaluate: --resume continues its own log; leave out "
                             "--episodes-log")
        if args.dataset is not None:
            raise UsageError("food-fetch evaluate: --resume cannot record --dataset (the log "
                             "holds no transitions): record a dataset in a run of its own")
        return args.resume
    if args.episodes_log is not None:
        if args.episodes_log in (args.json, args.csv):
            raise UsageError("food-fetch evaluate: --episodes-log must differ from --json and "
                             "--csv")
        return args.episodes_log
    from agents.atomic import written_as_is

    for out in (args.json, args.csv):
        if out is not None and not written_as_is(out):  # not beside /dev/stdout
            log = out.with_name(out.stem + ".episodes.jsonl")
            require_distinct("food-fetch evaluate", {"--json": args.json, "--csv": args.csv,
                                                     "the episode log beside them": log})
            return log
    return None


def _plan(args: argparse.Namespace, run: _Run, files: dict[str, str]) -> None:
    """The planned tasks, the log's header, and with ``--resume`` the records the log
    already holds (checked against the command first)."""
    from agents.episode_log import LogError, check_matches, food_fetch_version, read_log
    from agents.evaluate import REFERENCE, Task

    run.plan = [Task(a, args.env, i, args.seed + i, run.env_kwargs, record=bool(run.datasets))
                for i in range(args.episodes) for a in run.agents
                if not (a == REFERENCE and i >= run.n_search)]
    run.header = {"env": args.env, "env_kwargs": run.env_kwargs, "seed": args.seed,
                  "agents": run.agents, "agent_settings": run.describe, "agent_files": files,
                  "food_fetch_version": food_fetch_version(), "episodes": args.episodes,
                  "search_episodes": args.search_episodes}
    run.log_path = _log_path(args)
    if args.resume is None:
        return
    try:
        header, records = read_log(args.resume)
        check_matches(args.resume, header, run.header)
    except LogError as exc:
        raise UsageError(f"food-fetch evaluate: --resume: {exc}") from None
    planned = {(t.agent, t.episode) for t in run.plan}
    run.logged = [r for r in records if (r["agent"], r["episode"]) in planned]
    run.from_log = len(run.logged)


def _open_log(args: argparse.Namespace, run: _Run) -> Any:
    """The episode log to append to (None without one): ``--resume``'s file continued, else
    a new one; a log that cannot be started is one usage line, before any episode runs."""
    from agents.episode_log import EpisodeLog

    if run.log_path is None:
        return None
    try:
        if args.resume is not None:
            return EpisodeLog.reopen(run.log_path)
        return EpisodeLog.create(run.log_path, run.header)
    except OSError as exc:
        raise UsageError(f"food-fetch evaluate: cannot write the episode log "
                         f"{str(run.log_path)!r}: {exc.strerror or exc}") from None


def _run_with_bar(args: argparse.Namespace, run: _Run, tasks: list[Any], log: Any,
                  stop: Any) -> float:
    """Run ``tasks`` under a progress bar, appending each record to the log as it finishes;
    the new records and why it stopped go into ``run``.  The wall time."""
    from tqdm import tqdm

    from agents.evaluate import EvaluationInterrupted, run_tasks
    from agents.ray_runner import RaySetupError  # (imports Ray only when it connects)

    bar = tqdm(total=len(tasks), unit="ep", disable=args.quiet or None, file=sys.stderr,
               desc=f"{args.env} x {len(run.agents)} agents")

    def notify(message: str) -> None:
        bar.write(f"food-fetch evaluate: {message}", file=sys.stderr)

    log_ok = [True]

    def on_result(rec: dict[str, Any]) -> None:
        if log is not None:
            log.append(rec)
            problem = log.problem() if log_ok[0] else None
            if problem is not None:  # said at once; the results are written at the end
                log_ok[0] = False
                notify(f"the episode log {str(log.path)!r} stopped taking records "
                       f"({problem}); the run goes on")
        bar.update()

    wall = time.perf_counter()
    try:
        new = run_tasks(tasks, workers=args.workers, on_result=on_result, stop=stop,
                        notify=notify, ray_address=args.ray, ray_batch=args.ray_batch)
    except EvaluationInterrupted as exc:
        new, run.stopped = exc.results, exc
    except RaySetupError as exc:  # Ray could not start or join: before any episode ran
        raise UsageError(f"food-fetch evaluate: {exc}") from None
    finally:
        stop.armed = False  # from here a signal is remembered: the results get written
        bar.close()
    if log is not None:
        for rec in new:  # a record a stop came between its finish and its log line
            log.append(rec)
        log.close()
    order = {(t.agent, t.episode): i for i, t in enumerate(run.plan)}
    run.records = sorted(run.logged + new, key=lambda r: order[(r["agent"], r["episode"])])
    return time.perf_counter() - wall


def _print_summary(args: argparse.Namespace, run: _Run, summary: Any, wall: float) -> None:
    """The run's one-line header, how to read the intervals, and the agents' table."""
    from agents.evaluate import REFERENCE, TABLE_LEGEND, format_table

    print(f"{args.env}: {args.episodes} episodes from seed {args.seed}"
          + (f" (search on the first {run.n_search})" if REFERENCE in run.agents
             and run.n_search < args.episodes else "")
          + (f", Ray at {args.ray}" if args.ray else f", {args.workers} worker(s)")
          + ("".join(f", {k}={v}" for k, v in run.env_kwargs.items()))
          + f", {wall:.1f} s"
          + (f" ({run.from_log} episode(s) from {args.resume})" if args.resume else "")
          + ("  [INTERRUPTED: partial results]" if run.stopped is not None else ""))
    print(TABLE_LEGEND)
    print(format_table(summary, markdown=args.markdown))
    sys.stdout.flush()  # before any file: --json /dev/stdout comes after the table


class _Writes:
    """The files written at the end of a run, and those that could not be (path, why)."""

    def __init__(self) -> None:
        self.failed: list[tuple[str, str]] = []
        self.usage: list[str] = []  # one-line usage errors (no OpenGL for --video, ...)

    def attempt(self, path: Path | str, write: Any) -> tuple[bool, Any]:
        """Whether ``write()`` succeeded, and what it returned; an OSError (folder removed,
        disk full) is remembered, not raised."""
        try:
            return True, write()
        except OSError as exc:
            self.failed.append((str(path), exc.strerror or str(exc)))
            return False, None


def _fallback(payload: dict[str, Any]) -> Path | None:
    """The results (with every episode) in a new file in the current folder, else in the
    system's temporary folder; its path, or None when neither can be written."""
    import tempfile

    from agents.atomic import write_atomic
    from agents.episode_log import json_safe

    name = f"food-fetch-evaluate-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.json"
    text = json.dumps(json_safe(payload))
    for folder in (".", tempfile.gettempdir()):
        path = Path(os.path.abspath(os.path.join(folder, name)))
        try:
            write_atomic(path, text)
            return path
        except OSError:
            continue
    return None


def _write_outputs(args: argparse.Namespace, run: _Run, summary: dict[str, Any],
                   payload: dict[str, Any], stop: Any) -> _Writes:
    """JSON, CSV, and (for a run that was not stopped) plots, datasets and videos; each
    written atomically, each failure kept for one line at the end."""
    from agents.atomic import write_atomic
    from agents.datasets import pop_transitions
    from agents.episode_log import json_safe
    from agents.evaluate import write_csv, write_plots

    writes, partial = _Writes(), " (partial)" if run.stopped is not None else ""
    transitions = pop_transitions(run.records) if run.datasets else {}
    outputs = [(args.json, lambda: write_atomic(args.json,
                                                json.dumps(json_safe(payload)) + "\n")),
               (args.csv, lambda: write_csv(args.csv, run.records))]
    for path, write in outputs:
        if path is not None and writes.attempt(path, write)[0]:
            print(f"wrote{partial}".ljust(18) + str(path))
    stopped = run.stopped is not None or stop.signum is not None
    if args.plots is not None and not stopped:  # figures and videos can wait after a stop
        for p in writes.attempt(args.plots, lambda: write_plots(
                args.plots, summary, run.records, args.env))[1] or []:
            print(f"plot              {p}")
    try:
        if run.datasets:
            for line in writes.attempt(args.dataset, lambda: _write_datasets(
                    args, run.datasets, run.records, transitions, run.env_kwargs,
                    run.describe, run.stopped is not None))[1] or []:
                print(line)
        if args.video is not None and not stopped:
            writes.attempt(args.video, lambda: _write_videos(args, run.agents,
                                                             run.env_kwargs))
    except UsageError as exc:  # said at the end, after the other outputs
        writes.usage.append(str(exc))
    return writes


def _write_videos(args: argparse.Namespace, agents: list[str], env_kwargs: dict[str, Any]
                  ) -> None:
    """``--video``: each agent's first episode; no OpenGL is one usage line, no empty folder."""
    from agents.evaluate import record_videos

    existed = args.video.exists()
    try:
        videos = record_videos(args.video, agents, args.env, args.seed, env_kwargs)
    except OSError:
        raise  # a write failed (reported with the others), not the rendering
    except Exception as exc:  # no OpenGL context (headless without MUJOCO_GL=egl)
        if not existed and args.video.is_dir() and not any(args.video.iterdir()):
            args.video.rmdir()  # leave no empty folder behind a failed call
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UsageError(f"food-fetch evaluate: --video: cannot render ({msg}); on a "
                         "headless machine set MUJOCO_GL=egl (or osmesa)") from None
    for p in videos:
        print(f"video             {p}")


def _checked_datasets(args: argparse.Namespace) -> dict[str, str]:
    """``--dataset``: {agent: Minari id}, each free (or ``--dataset-overwrite``); the extra,
    the name and the ids are checked before any work."""
    if args.dataset is None:
        if args.dataset_overwrite:
            raise UsageError("food-fetch evaluate: --dataset-overwrite needs --dataset NAME")
        return {}
    require_extra("evaluate --dataset", "datasets")
    from agents.datasets import DatasetError, check_free, dataset_ids

    try:
        ids = dataset_ids(args.dataset, list(dict.fromkeys(args.agent or DEFAULT_AGENTS)))
        check_free(ids, args.dataset_overwrite)
    except DatasetError as exc:
        raise UsageError(f"food-fetch evaluate: --dataset: {exc}") from None
    return ids


def _write_datasets(args: argparse.Namespace, ids: dict[str, str], records: list[Any],
                    transitions: dict[Any, Any], env_kwargs: dict[str, Any],
                    describe: dict[str, Any], interrupted: bool) -> list[str]:
    """Each agent's recorded episodes as its Minari dataset; the lines to print."""
    import gymnasium as gym

    from agents.datasets import DatasetError, write_dataset
    from agents.episode_log import json_safe
    from agents.evaluate import REFERENCE

    n_search = min(args.search_episodes or args.episodes, args.episodes)
    lines = []
    env = gym.make(args.env, **env_kwargs)  # its spec (id, kwargs) goes into the dataset
    try:
        for agent, ds_id in ids.items():
            settings = {"env_id": args.env, "env_kwargs": env_kwargs, "agent": agent,
                        "agent_settings": describe.get(agent), "seed": args.seed,
                        "episodes_planned": n_search if agent == REFERENCE else args.episodes,
                        "complete": not interrupted}
            try:
                n = write_dataset(ds_id, agent, env, records, transitions,
                                  json_safe(settings), overwrite=args.dataset_overwrite)
            except DatasetError as exc:
                raise UsageError(f"food-fetch evaluate: --dataset: {exc}") from None
            if n:
                lines.append(f"dataset{' (partial)' if interrupted else ''}".ljust(18)
                             + f"{ds_id} ({n} episodes)")
    finally:
        env.close()
    return lines


def _kept(args: argparse.Namespace, run: _Run, writes: _Writes, log: Any) -> str:
    """Where what finished is, for the line that says the run stopped."""
    failed = {path for path, _ in writes.failed}
    files = [str(p) for p in (args.json, args.csv) if p is not None and str(p) not in failed]
    text = f"what finished is in {', '.join(files)}" if files else ""
    if log is not None and str(log.path) not in failed:
        text += (" and " if text else "what finished is in ") + (
            f"the episode log {str(log.path)!r} (add --resume {log.path} to the command to "
            "run the rest)")
    return text or "the table above holds what finished"


def _finish(args: argparse.Namespace, run: _Run, writes: _Writes, log: Any,
            payload: dict[str, Any], stop: Any) -> int:
    """The closing lines on stderr (each one line) and the exit code: 128 + the signal's
    number after a stop, 1 after a lost worker or a failed write, else 0."""
    import signal

    problem = log.problem() if log is not None else None
    if problem is not None:
        writes.failed.append((str(log.path), problem))
    code = 0
    if writes.failed:
        fallback = _fallback({**payload, "episodes_detail": run.records})
        where = (f"the results with every episode are in {str(fallback)!r}" if fallback
                 else "nor could the results be written to the current or the temporary "
                 "folder: the table above is what is left")
        failed = ", ".join(f"{path!r} ({why})" for path, why in writes.failed)
        print(f"food-fetch evaluate: cannot write {failed}; {where}", file=sys.stderr)
        code = 1
    for line in writes.usage:
        print(line, file=sys.stderr)
    if writes.usage and not code:
        code = EXIT_USAGE
    if run.stopped is not None:
        print(f"food-fetch evaluate: {run.stopped.reason} ({len(run.records)} of "
              f"{len(run.plan)} episodes finished); {_kept(args, run, writes, log)}",
              file=sys.stderr)
        return int(run.stopped.code)
    if stop.signum is not None:
        print(f"food-fetch evaluate: {signal.Signals(stop.signum).name} came while the "
              "results were written: they are, figures and videos left out", file=sys.stderr)
        return 128 + stop.signum
    return code


def _note_caps(args: argparse.Namespace, n_tasks: int) -> None:
    """Say on stderr where a setting is lowered to what the run can use (no number changes)."""
    if args.workers > max(n_tasks, 1):
        print(f"food-fetch evaluate: note: --workers {args.workers} lowered to "
              f"{max(n_tasks, 1)}, one per task to run", file=sys.stderr)
    if args.search_episodes and args.search_episodes > args.episodes:
        print(f"food-fetch evaluate: note: --search-episodes {args.search_episodes} lowered "
              f"to --episodes {args.episodes}", file=sys.stderr)


# The plan of every episode is made before the first runs (about 200 bytes an episode): a
# million per agent is weeks of one core's fetches, and a typo's extra zeros fail here.
MAX_EPISODES = 1_000_000


def _episodes(text: str) -> int:
    value = positive_int(text)
    if value > MAX_EPISODES:
        raise argparse.ArgumentTypeError(f"{value} is more than {MAX_EPISODES:,} episodes an "
                                         "agent")
    return value


def cmd_evaluate(args: argparse.Namespace) -> int:
    require_extra("evaluate", "figures")
    # with --resume, --episodes-log may only name the same log (_log_path refuses another)
    log = args.episodes_log if args.resume is None else None
    require_distinct("food-fetch evaluate", {"--json": args.json, "--csv": args.csv,
                                             "--episodes-log": log, "--resume": args.resume})
    from agents.evaluate import StopSignals, summarize
    from fetch_env import ENV_IDS  # (not agents.train.env_ids: that module needs PyYAML)

    ids = sorted(ENV_IDS)
    if args.env not in ids:
        raise UsageError(f"food-fetch evaluate: unknown environment id {args.env!r}; "
                         f"choose from {', '.join(ids)}")
    check_ray_options("food-fetch evaluate", args)
    datasets = _checked_datasets(args)
    env_kwargs = _check_env_kwargs(args.env, _with_quasi_static(args))
    agents, describe, files = _checked_agents(args)
    run = _Run(agents, describe, env_kwargs, datasets,
               n_search=min(args.search_episodes or args.episodes, args.episodes))
    _plan(args, run, files)
    done = {(r["agent"], r["episode"]) for r in run.logged}
    tasks = [t for t in run.plan if (t.agent, t.episode) not in done]
    # A worker beyond one per task only costs a process start (MuJoCo, numpy imports).
    _note_caps(args, len(tasks))
    args.workers = max(1, min(args.workers, len(tasks)))
    with StopSignals() as stop:
        try:
            log = _open_log(args, run)
        except KeyboardInterrupt as exc:  # StopRequested too: before any episode ran
            signum = getattr(exc, "signum", 2)
            print(f"food-fetch evaluate: {exc.args[0] if exc.args else 'SIGINT'} before any "
                  "episode ran", file=sys.stderr)
            return 128 + signum
        wall = _run_with_bar(args, run, tasks, log, stop)
        summary = summarize(run.records, agents)
        payload = _payload(args, run, summary, wall)
        _print_summary(args, run, summary, wall)  # first: a failed write still shows it
        writes = _write_outputs(args, run, summary, payload, stop)
        return _finish(args, run, writes, log, payload, stop)


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch evaluate``."""
    p.add_argument("--agent", action="append", metavar="NAME|PATH",
                   help="agent to evaluate; repeat for a side-by-side table (default: random, "
                   "study, model-based)")
    p.add_argument("--env", default=DEFAULT_ENV, metavar="ID",
                   help="environment id: FoodFetch-{Block,Row,TwoRows,Diced}-v0 or -v1, "
                   "FoodFetch-{Row,TwoRows}-v2, FoodFetch-TwoRows-v3 "
                   f"(default: {DEFAULT_ENV}, the benchmark id)")
    p.add_argument("--env-kwargs", type=_env_kwarg, nargs="+", default=[], metavar="KEY=VALUE",
                   help="keyword arguments of the environment, values read as JSON where "
                   "they are JSON, else as strings (e.g. fetch_impratio=1000 "
                   "estimator=oracle); checked before any episode runs")
    p.add_argument("--quasi-static", action="store_true",
                   help="the id's quasi-static holds and slow clamps (fetch_env.quasi_static: "
                   "validated on the -v1 ids, Row-v2 and TwoRows-v3; the other ids get the "
                   "-v1 ids' common setting; --env-kwargs override them): 1.4-2x the "
                   "episodes per core, outcomes at the simulator's chaos floor")
    p.add_argument("--episodes", type=_episodes, default=20, metavar="N",
                   help=f"episodes (scenes) per agent, 1 to {MAX_EPISODES:,} (default: 20)")
    p.add_argument("--seed", type=seed, default=0, metavar="S",
                   help="seed of the first scene, 0 to 2**32-1 (default: 0)")
    p.add_argument("--workers", type=positive_int, default=1, metavar="K",
                   help="worker processes, at most one per (agent, episode) task (more are "
                   "not started); any K gives the same numbers (default: 1); a worker that "
                   "dies has its tasks rerun once on a fresh pool")
    add_ray_options(p, "episodes", "; search also spreads each scene's simulations over "
                    "the cluster")
    p.add_argument("--search-episodes", type=positive_int, default=None, metavar="N",
                   help="run 'search' (~25 simulations per scene) on the first N scenes "
                   "only, at most --episodes; regret is then paired on those (default: all)")
    p.add_argument("--json", type=writable, default=None, metavar="FILE",
                   help="write the summary (and settings, machine) as JSON")
    p.add_argument("--episodes-log", type=writable, default=None, metavar="FILE",
                   help="append each finished (agent, episode) record to FILE as JSON Lines, "
                   "flushed as it finishes (default: beside --json, x.json -> "
                   "x.episodes.jsonl, else beside --csv, else none); a new run replaces it")
    p.add_argument("--resume", type=_existing_file, default=None, metavar="LOG",
                   help="continue the episode log LOG of a stopped run: run only the "
                   "(agent, episode) tasks it does not hold and append them to it; the "
                   "command must name the same --env, --env-kwargs, --seed and agents (else "
                   "refused), --episodes may differ; the numbers equal an uninterrupted run's")
    p.add_argument("--json-episodes", action="store_true",
                   help="also put every episode's record in the JSON")
    p.add_argument("--csv", type=writable, default=None, metavar="FILE",
                   help="write one row per (agent, episode)")
    p.add_argument("--plots", type=out_dir, default=None, metavar="DIR",
                   help="write reward.png, fetch_rate.png, theta_vs_stiffness.png")
    p.add_argument("--video", type=out_dir, default=None, metavar="DIR",
                   help="record each agent's first episode (needs an OpenGL backend, e.g. "
                   "MUJOCO_GL=egl)")
    p.add_argument("--dataset", default=None, metavar="NAME",
                   help="record the episodes as Minari datasets NAME/AGENT-v0, one per agent "
                   "(e.g. food-fetch/block gives food-fetch/block/study-v0), under "
                   "MINARI_DATASETS_PATH or ~/.minari/datasets; needs the datasets extra")
    p.add_argument("--dataset-overwrite", action="store_true",
                   help="replace datasets of those ids (default: refuse before any episode)")
    p.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
