"""Environment speed: episodes per second per id on one core and with 2 workers, and the
share of each episode spent in the reset probes.

Run: MUJOCO_GL=egl python benchmarks/bench_env.py [--episodes N] [--ids ...]
Episodes use random actions from a seeded action space and the default env settings
(estimator="model"), so the numbers are what a training run sees.  The one-core figures are
given twice: from wall time and from the process's CPU time (the latter is what the episode
costs a core; on a machine shared with other jobs the wall figure is lower).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import gymnasium as gym
import mujoco
import numpy as np

import fetch_env


def one_core(env_id: str, episodes: int, **kwargs) -> dict[str, float]:
    env = gym.make(env_id, **kwargs)
    env.action_space.seed(0)
    probe = step = 0.0
    wall = time.perf_counter()
    cpu = time.process_time()
    errors = 0
    for ep in range(episodes):
        t = time.process_time()
        env.reset(seed=1000 + ep)
        probe += time.process_time() - t  # the probes are ~all of a model reset
        _, _, _, _, info = env.step(env.action_space.sample())
        errors += "error" in info
    cpu = time.process_time() - cpu
    step = cpu - probe
    wall = time.perf_counter() - wall
    env.close()
    return {"eps": episodes / wall, "eps_cpu": episodes / cpu, "probe_share": probe / cpu,
            "step_share": step / cpu, "errors": errors}


def two_workers(env_id: str, episodes: int, **kwargs) -> float:
    venv = gym.vector.AsyncVectorEnv([lambda: gym.make(env_id, **kwargs)] * 2)
    venv.action_space.seed(0)
    wall = time.perf_counter()
    venv.reset(seed=2000)
    done = 0
    while done < episodes:
        # autoreset (next-step mode): every other step resets; count finished fetches only
        _, _, terminated, _, _ = venv.step(venv.action_space.sample())
        done += int(terminated.sum())
    wall = time.perf_counter() - wall
    venv.close()
    return done / wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=10)
    ap.add_argument("--ids", nargs="*", default=list(fetch_env.ENV_IDS))
    ap.add_argument("--estimator", default="model", choices=("model", "oracle", "none"))
    ap.add_argument("--probe-hold", type=float, default=None,
                    help="relaxation probe hold [s] (default: the env's)")
    ap.add_argument("--probe-time-scale", type=float, default=None,
                    help="relaxation probe hold's quasi-static time scale (default: the env's)")
    ap.add_argument("--fetch-timestep", type=float, default=None,
                    help="the fetch's physics step [s] (default: the env's 5 ms)")
    ap.add_argument("--no-workers", action="store_true", help="skip the 2-worker run")
    args = ap.parse_args()
    kwargs: dict = {"estimator": args.estimator}
    if args.probe_hold is not None:
        kwargs["probe_hold"] = args.probe_hold
    if args.probe_time_scale is not None:
        kwargs["probe_time_scale"] = args.probe_time_scale
    if args.fetch_timestep is not None:
        kwargs["fetch_timestep"] = args.fetch_timestep
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {platform.machine()} {os.cpu_count()} cores (load average {load:.1f} at "
          f"start), python {platform.python_version()}, mujoco {mujoco.__version__}; "
          f"{args.episodes} episodes, {kwargs}, random actions")
    print(f"{'id':22s} {'ep/s wall':>9s} {'ep/s CPU':>8s} {'probe share':>11s} "
          f"{'fetch share':>11s} {'ep/s 2 workers':>14s} {'scaling':>8s} {'diverged':>8s}")
    for env_id in args.ids:
        r = one_core(env_id, args.episodes, **kwargs)
        v = float("nan") if args.no_workers else two_workers(env_id, args.episodes, **kwargs)
        print(f"{env_id:22s} {r['eps']:9.2f} {r['eps_cpu']:8.2f} {r['probe_share']:11.0%} "
              f"{r['step_share']:11.0%} {v:14.2f} {v / (2 * r['eps']):8.0%} "
              f"{r['errors']:8d}", flush=True)


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
