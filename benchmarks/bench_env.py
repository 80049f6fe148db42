"""Environment speed: episodes per second per id on one core and with 2 workers, and the
share of each episode spent in the reset probes.

Run: MUJOCO_GL=egl python benchmarks/bench_env.py [--episodes N] [--ids ...]
Episodes use random actions from a seeded action space and the default env settings
(estimator="model"), so the numbers are what a training run sees.
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
    errors = 0
    for ep in range(episodes):
        env.reset(seed=1000 + ep)
        probe += env.unwrapped.last_probe_wall_time
        _, _, _, _, info = env.step(env.action_space.sample())
        step += env.unwrapped.last_step_wall_time
        errors += "error" in info
    wall = time.perf_counter() - wall
    env.close()
    return {"eps": episodes / wall, "probe_share": probe / wall, "step_share": step / wall,
            "errors": errors}


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
    args = ap.parse_args()
    print(f"machine: {platform.machine()} {os.cpu_count()} cores, python "
          f"{platform.python_version()}, mujoco {mujoco.__version__}; "
          f"{args.episodes} episodes, estimator={args.estimator}, random actions")
    print(f"{'id':22s} {'ep/s 1 core':>11s} {'probe share':>11s} {'fetch share':>11s} "
          f"{'ep/s 2 workers':>14s} {'scaling':>8s} {'diverged':>8s}")
    for env_id in args.ids:
        r = one_core(env_id, args.episodes, estimator=args.estimator)
        v = two_workers(env_id, args.episodes, estimator=args.estimator)
        print(f"{env_id:22s} {r['eps']:11.2f} {r['probe_share']:11.0%} {r['step_share']:11.0%} "
              f"{v:14.2f} {v / (2 * r['eps']):8.0%} {r['errors']:8d}")


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
