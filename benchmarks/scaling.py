"""Scaling: evaluation episodes/s with 1 and 2 workers by the process pool (``--workers``)
and by Ray (``--ray``), Ray's per-task cost, RLlib's sampling rate with 1 and 2 env
runners, and from those a projection for 8, 64 and 512 cores.

Run (on an otherwise idle machine; one sitting, so the ratios compare):

    python benchmarks/scaling.py [--episodes 40] [--out docs/data/scaling.json]

Episodes: the study agent on FoodFetch-Block-v0 scenes from seed 5000 (probes included: what
an evaluation runs).  Each setting's wall time counts from the first task submitted to the
last result, after its pool or Ray instance has started and run one warm-up round (the
start-up is reported apart: it is paid once per run, not per episode).

The projection (on paper): with t the one-core episode time, o Ray's cost per task (the
round trip of an empty task, measured here), b episodes per task and D the tasks per second
one driver can hand out and collect (measured with empty tasks), N cores give
``min(N / (t + o / b), D * b)`` episodes/s.  It assumes episodes as independent as here
(no shared state), a network no slower than this machine's loopback for a task's few kB,
and nodes with this machine's per-core speed; it ignores stragglers (the last tasks of a
run on a big cluster), which batching makes worse and more tasks per core make better.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from readme_meta import meta, write_json  # noqa: E402

ENV_ID = "FoodFetch-Block-v0"
SEED = 5000


def _tasks(n: int, offset: int = 0) -> list[Any]:
    from agents.evaluate import Task

    return [Task("study", ENV_ID, i, SEED + offset + i) for i in range(n)]


def pool_rate(workers: int, episodes: int) -> dict[str, float]:
    """--workers' process pool (spawned, the same initializer): a warm-up round of one
    episode per worker, then ``episodes`` timed."""
    import concurrent.futures as cf
    import multiprocessing as mp

    from agents.evaluate import _init_worker, run_episode

    start = time.perf_counter()
    with cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                                initializer=_init_worker) as pool:
        list(pool.map(run_episode, _tasks(workers, offset=10_000)))
        startup = time.perf_counter() - start
        t0 = time.perf_counter()
        list(pool.map(run_episode, _tasks(episodes)))
        wall = time.perf_counter() - t0
    return {"episodes_per_s": episodes / wall, "wall_s": wall, "startup_s": startup}


def ray_rates(cpus: int, episodes: int, batch_sizes: tuple[int, ...]) -> dict[str, Any]:
    """--ray on a local instance of ``cpus`` CPUs: episodes/s per batch size, the round
    trip of an empty task (o) and the driver's empty-task throughput (D)."""
    import ray

    from agents.ray_runner import _episode, _run_batch, batches, connected

    out: dict[str, Any] = {}
    t0 = time.perf_counter()
    with connected("local", cpus):
        out["startup_s"] = time.perf_counter() - t0
        remote = ray.remote(num_cpus=1, max_retries=1)(_run_batch)
        ray.get([remote.remote(_tasks(1, offset=10_000 + k), _episode)
                 for k in range(cpus)])  # warm
        for b in batch_sizes:
            tasks = _tasks(episodes)
            t = time.perf_counter()
            refs = [remote.remote([tasks[i] for i in g], _episode)
                    for g in batches(len(tasks), b, cpus)]
            results = ray.get(refs)
            wall = time.perf_counter() - t
            assert sum(len(r) for r in results) == episodes
            out[f"batch_{b}"] = {"episodes_per_s": episodes / wall, "wall_s": wall}
        empty = ray.remote(num_cpus=1)(_empty)
        ray.get([empty.remote() for _ in range(cpus)])
        trips = []
        for _ in range(50):
            t = time.perf_counter()
            ray.get(empty.remote())
            trips.append(time.perf_counter() - t)
        out["task_round_trip_s"] = statistics.median(trips)
        n = 2000
        t = time.perf_counter()
        ray.get([empty.remote() for _ in range(n)])
        out["driver_tasks_per_s"] = n / (time.perf_counter() - t)
    return out


def _empty() -> None:
    return None


def rllib_rate(runners: int, iterations: int) -> dict[str, float]:
    """Fetches sampled per second by RLlib PPO with ``runners`` env runners (after one
    warm-up iteration), batches of 64 fetches, the learner's update included."""
    from agents.ray_runner import connected
    from agents.rllib_train import RLlibPlan, build_config

    settings = {"training": {"train_batch_size_per_learner": 64, "minibatch_size": 32,
                             "num_epochs": 2},
                "model": {"fcnet_hiddens": [64, 64]},
                "env_runners": {"rollout_fragment_length": "auto"}}
    plan = RLlibPlan("ppo", ENV_ID, 0, 0, Path("."), runners, "local", 0, settings)
    with connected("local", runners + 1):
        algo = build_config(plan).build_algo()
        try:
            algo.train()
            before = int(algo.train().get("num_env_steps_sampled_lifetime", 0))
            t = time.perf_counter()
            for _ in range(iterations):
                r = algo.train()
            wall = time.perf_counter() - t
            sampled = int(r.get("num_env_steps_sampled_lifetime", 0)) - before
        finally:
            algo.stop()
    return {"fetches_per_s": sampled / wall, "wall_s": wall, "iterations": iterations,
            "fetches": sampled}


def project(t_episode: float, o_task: float, d_tasks: float, batch: int,
            cores: tuple[int, ...] = (8, 64, 512)) -> dict[str, float]:
    """Episodes/s on N cores: min(N / (t + o / b), D * b)."""
    return {str(n): min(n / (t_episode + o_task / batch), d_tasks * batch) for n in cores}


BEGIN, END = "<!-- scaling table: begin -->", "<!-- scaling table: end -->"


def render(data: dict[str, Any]) -> str:
    """The docs' table of ``docs/data/scaling.json`` (docs/scaling.md holds it between
    BEGIN and END; tests/test_ray.py checks the two agree)."""
    w, r, rl, pr = data["workers"], data["ray"], data["rllib"], data["projection"]
    rows = [
        "| how | 1 CPU | 2 CPUs | 2 / 1 |",
        "|---|---|---|---|",
        _row("`--workers K` (process pool)", w["1"]["episodes_per_s"], w["2"]["episodes_per_s"]),
        _row("`--ray`, 1 episode per task", r["1"]["batch_1"]["episodes_per_s"],
             r["2"]["batch_1"]["episodes_per_s"]),
        _row("`--ray`, 4 episodes per task", r["1"]["batch_4"]["episodes_per_s"],
             r["2"]["batch_4"]["episodes_per_s"]),
        _row("RLlib PPO, fetches/s (1 or 2 env runners, learner included)",
             rl["1"]["fetches_per_s"], rl["2"]["fetches_per_s"]),
    ]
    m = data["meta"]
    lines = [
        *rows, "",
        f"Evaluation: episodes/s of the study agent on {data['env_id']} "
        f"({data['episodes']} scenes each, after a warm-up). Ray: a task's round trip "
        f"{1e3 * pr['o_task_s']:.2f} ms, the driver hands out "
        f"{pr['d_tasks_per_s']:.0f} empty tasks/s; a Ray start "
        f"{r['2']['startup_s']:.1f} s. Projected episodes/s (one episode "
        f"{pr['t_episode_s']:.2f} s): "
        + ", ".join(f"{n} cores {v:.0f}" for n, v in pr["batch_1"].items())
        + " at 1 episode per task; "
        + ", ".join(f"{n} cores {v:.0f}" for n, v in pr["batch_8"].items())
        + " at 8.", "",
        f"{m['machine']}, Python {m['python']}, MuJoCo {m['mujoco']}, commit {m['commit']}, "
        f"load {m['load_average_at_start']} at start; `{m['command']}`, {m['wall_s']} s.",
    ]
    return "\n".join(lines)


def _row(name: str, one: float, two: float) -> str:
    return f"| {name} | {one:.2f} | {two:.2f} | {two / one:.2f} |"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=40)
    p.add_argument("--rllib-iterations", type=int, default=4)
    p.add_argument("--out", type=Path, default=ROOT / "docs/data/scaling.json")
    args = p.parse_args()
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    wall = time.perf_counter()
    data: dict[str, Any] = {"env_id": ENV_ID, "episodes": args.episodes, "agent": "study"}
    data["workers"] = {str(w): pool_rate(w, args.episodes) for w in (1, 2)}
    print("workers", {k: round(v["episodes_per_s"], 3) for k, v in data["workers"].items()})
    data["ray"] = {str(c): ray_rates(c, args.episodes, (1, 4)) for c in (1, 2)}
    print("ray", {c: {k: (round(v["episodes_per_s"], 3) if isinstance(v, dict) else round(v, 4))
                      for k, v in r.items()} for c, r in data["ray"].items()})
    data["rllib"] = {str(n): rllib_rate(n, args.rllib_iterations) for n in (1, 2)}
    print("rllib", {k: round(v["fetches_per_s"], 3) for k, v in data["rllib"].items()})
    t_ep = 1.0 / data["workers"]["1"]["episodes_per_s"]
    r2 = data["ray"]["2"]
    data["projection"] = {
        "assumptions": "N / (t + o / b) capped by D * b; t one-core episode time, o Ray task "
                       "round trip, D driver tasks/s, b episodes per task",
        "t_episode_s": t_ep, "o_task_s": r2["task_round_trip_s"],
        "d_tasks_per_s": r2["driver_tasks_per_s"],
        "batch_1": project(t_ep, r2["task_round_trip_s"], r2["driver_tasks_per_s"], 1),
        "batch_8": project(t_ep, r2["task_round_trip_s"], r2["driver_tasks_per_s"], 8),
    }
    data["meta"] = meta(time.perf_counter() - wall)
    write_json(args.out, data)
    print("projection", data["projection"]["batch_1"], data["projection"]["batch_8"])
    print(f"wrote {args.out}")
    print(render(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
