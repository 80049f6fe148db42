"""Simulator speed: real-time factor, steps/s, and overhead against a bare mj_step loop.

Run: python benchmarks/bench_simulator.py   (prints medians of 3 runs; one core)
"""

from __future__ import annotations

import platform
import statistics
import time

import mujoco
import numpy as np

from fetch_env.controller import FetchAction, FetchSimulator
from fetch_env.layouts import diced_mix, single_block
from fetch_env.scene import initial_state


def bench(name: str, pieces, action: FetchAction, repeats: int = 3) -> None:
    sim = FetchSimulator(pieces)
    runs = []
    for _ in range(repeats):
        r = sim.run("fetch", action)
        runs.append((r.wall_time, r.n_steps, r.timestep))
    wall = statistics.median(w for w, _, _ in runs)
    n, dt = runs[0][1], runs[0][2]
    scene = sim.scene_for("fetch")
    bare = []
    for _ in range(repeats):
        d = initial_state(scene)
        t = time.perf_counter()
        for _ in range(n):
            mujoco.mj_step(scene.model, d)
        bare.append(time.perf_counter() - t)
    bare_wall = statistics.median(bare)
    print(f"{name:28s} {n * dt / wall:7.1f}x real time  {n / wall:8.0f} steps/s  "
          f"ratio to bare mj_step {wall / bare_wall:5.2f}")


if __name__ == "__main__":
    print(f"machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"mujoco {mujoco.__version__}")
    bench("single 15 mm soft cube", single_block(), FetchAction())
    bench("9-piece diced mix", diced_mix(np.random.default_rng(0), n_pieces=9),
          FetchAction(theta_d=0.085))
