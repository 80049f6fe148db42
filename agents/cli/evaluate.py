"""``food-fetch evaluate``: agents side by side on the same seeded scenes."""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from typing import Any

from agents.cli.common import (
    UsageError,
    out_dir,
    positive_int,
    require_extra,
    seed,
    writable,
    write_json,
)
from fetch_env.errors import env_error_line

HELP = "evaluate agents side by side on the same seeded scenes"
DESCRIPTION = ("Run each agent on the same seeded scenes (episode i uses "
               "reset(seed=SEED+i)) and print, per agent, the mean reward, fetch rate, success "
               "rate, mean and max logarithmic strain LE, time per fetch and regret against "
               "'search' (the per-scene optimum found with the simulator), each with its 95 % "
               "interval. Agents: random, study, model-based, search, or the path of a model "
               "saved by 'food-fetch train'. Ctrl-C stops and still writes what finished. "
               "--dataset records the episodes as Minari datasets for offline RL.")


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


def _json_safe(x: Any) -> Any:
    """NaN/inf -> None, so the file is strict JSON (a diverged episode has no LE)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


def _payload(args: argparse.Namespace, agents: list[str], records: list[dict[str, Any]],
             summary: dict[str, Any], interrupted: bool, wall: float,
             describe: dict[str, Any], env_kwargs: dict[str, Any]) -> dict[str, Any]:
    return {
        "env": args.env, "env_kwargs": env_kwargs,
        "episodes": args.episodes, "seed": args.seed,
        "workers": args.workers, "search_episodes": args.search_episodes,
        "interrupted": interrupted, "episodes_finished": len(records),
        "wall_time_s": round(wall, 2),
        "agents": summary, "agent_settings": describe,
        "command": ["food-fetch", *sys.argv[1:]] if sys.argv[0].endswith("food-fetch")
        else ["food-fetch", "evaluate", *[a for a in sys.argv[1:]]],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version()},
        "episodes_detail": records if args.json_episodes else None,
    }


def _checked_agents(args: argparse.Namespace) -> tuple[list[str], dict[str, Any]]:
    """The agents to evaluate and their descriptions; a bad name, path or model file is one
    usage line, before any episode runs."""
    from agents.evaluate import AgentSpecError, make_agent

    agents = list(dict.fromkeys(args.agent or DEFAULT_AGENTS))
    describe = {}
    for spec in agents:
        try:
            agent = make_agent(spec, args.env)
            if hasattr(agent, "model"):
                agent.model  # noqa: B018 (load now: a corrupt file is a usage error)
            describe[spec] = agent.describe()
        except AgentSpecError as exc:
            raise UsageError(f"food-fetch evaluate: {exc}") from None
        except Exception as exc:  # e.g. a model file SB3 cannot read
            raise UsageError(f"food-fetch evaluate: cannot use agent {spec!r}: {exc}") from None
    return agents, describe


def _run_with_bar(args: argparse.Namespace, tasks: list[Any], n_agents: int
                  ) -> tuple[list[Any], bool, float]:
    """Run ``tasks`` under a progress bar: the records, whether Ctrl-C stopped it, wall time."""
    from tqdm import tqdm

    from agents.evaluate import EvaluationInterrupted, run_tasks

    bar = tqdm(total=len(tasks), unit="ep", disable=args.quiet or None, file=sys.stderr,
               desc=f"{args.env} x {n_agents} agents")
    wall = time.perf_counter()
    interrupted = False
    try:
        records = run_tasks(tasks, workers=args.workers, on_result=lambda _: bar.update())
    except EvaluationInterrupted as exc:
        records, interrupted = exc.results, True
    finally:
        bar.close()
    return records, interrupted, time.perf_counter() - wall


def _print_summary(args: argparse.Namespace, agents: list[str], summary: Any, n_search: int,
                   wall: float, interrupted: bool) -> None:
    """The run's one-line header and the agents' table."""
    from agents.evaluate import REFERENCE, format_table

    print(f"{args.env}: {args.episodes} episodes from seed {args.seed}"
          + (f" (search on the first {n_search})" if REFERENCE in agents
             and n_search < args.episodes else "")
          + f", {args.workers} worker(s), {wall:.1f} s"
          + ("  [INTERRUPTED: partial results]" if interrupted else ""))
    print("mean ± half-width of the 95 % interval; regret = search reward - agent reward "
          "on the same scenes")
    print(format_table(summary, markdown=args.markdown))


def _write_videos(args: argparse.Namespace, agents: list[str], env_kwargs: dict[str, Any]
                  ) -> None:
    """``--video``: each agent's first episode; no OpenGL is one usage line, no empty folder."""
    from agents.evaluate import record_videos

    existed = args.video.exists()
    try:
        videos = record_videos(args.video, agents, args.env, args.seed, env_kwargs)
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
                                  _json_safe(settings), overwrite=args.dataset_overwrite)
            except DatasetError as exc:
                raise UsageError(f"food-fetch evaluate: --dataset: {exc}") from None
            if n:
                lines.append(f"dataset{' (partial)' if interrupted else ''}".ljust(18)
                             + f"{ds_id} ({n} episodes)")
    finally:
        env.close()
    return lines


def cmd_evaluate(args: argparse.Namespace) -> int:
    require_extra("evaluate", "figures")
    from agents.datasets import pop_transitions  # (minari itself only with --dataset)
    from agents.evaluate import REFERENCE, Task, summarize, write_csv, write_plots
    from fetch_env import ENV_IDS  # (not agents.train.env_ids: that module needs PyYAML)

    ids = sorted(ENV_IDS)
    if args.env not in ids:
        raise UsageError(f"food-fetch evaluate: unknown environment id {args.env!r}; "
                         f"choose from {', '.join(ids)}")
    datasets = _checked_datasets(args)
    env_kwargs = _check_env_kwargs(args.env, args.env_kwargs)
    agents, describe = _checked_agents(args)
    n_search = min(args.search_episodes or args.episodes, args.episodes)
    tasks = [Task(a, args.env, i, args.seed + i, env_kwargs, record=bool(datasets))
             for i in range(args.episodes) for a in agents
             if not (a == REFERENCE and i >= n_search)]
    # A worker beyond one per task only costs a process start (MuJoCo, numpy imports).
    args.workers = min(args.workers, len(tasks))
    records, interrupted, wall = _run_with_bar(args, tasks, len(agents))
    transitions = pop_transitions(records) if datasets else {}
    summary = summarize(records, agents)
    payload = _payload(args, agents, records, summary, interrupted, wall, describe, env_kwargs)
    if args.json is not None:
        write_json(args.json, _json_safe(payload))
    if args.csv is not None:
        write_csv(args.csv, records)
    _print_summary(args, agents, summary, n_search, wall, interrupted)
    written = [path for path in (args.json, args.csv) if path is not None]
    recorded = _write_datasets(args, datasets, records, transitions, env_kwargs, describe,
                               interrupted) if datasets else []
    if interrupted:
        for path in written:
            print(f"wrote (partial)   {path}")
        for line in recorded:
            print(line)
        return 130
    if args.plots is not None:
        for p in write_plots(args.plots, summary, records, args.env):
            print(f"plot              {p}")
    for path in written:
        print(f"wrote             {path}")
    for line in recorded:
        print(line)
    if args.video is not None:
        _write_videos(args, agents, env_kwargs)
    return 0


def add_options(p: argparse.ArgumentParser) -> None:
    """The options of ``food-fetch evaluate``."""
    p.add_argument("--agent", action="append", metavar="NAME|PATH",
                   help="agent to evaluate; repeat for a side-by-side table (default: random, "
                   "study, model-based)")
    p.add_argument("--env", default="FoodFetch-Block-v0", metavar="ID",
                   help="environment id: FoodFetch-Block-v0, -Row-v0, -TwoRows-v0 or "
                   "-Diced-v0 (default: FoodFetch-Block-v0)")
    p.add_argument("--env-kwargs", type=_env_kwarg, nargs="+", default=[], metavar="KEY=VALUE",
                   help="keyword arguments of the environment, values read as JSON where "
                   "they are JSON, else as strings (e.g. fetch_impratio=1000 "
                   "estimator=oracle); checked before any episode runs")
    p.add_argument("--episodes", type=positive_int, default=20, metavar="N",
                   help="episodes (scenes) per agent (default: 20)")
    p.add_argument("--seed", type=seed, default=0, metavar="S",
                   help="seed of the first scene, 0 to 2**32-1 (default: 0)")
    p.add_argument("--workers", type=positive_int, default=1, metavar="K",
                   help="worker processes, at most one per (agent, episode) task (more are "
                   "not started); any K gives the same numbers (default: 1)")
    p.add_argument("--search-episodes", type=positive_int, default=None, metavar="N",
                   help="run 'search' (~20 simulations per scene) on the first N scenes "
                   "only; regret is then paired on those (default: all)")
    p.add_argument("--json", type=writable, default=None, metavar="FILE",
                   help="write the summary (and settings, machine) as JSON")
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
