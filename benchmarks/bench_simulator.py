"""Simulator speed: real-time factor, physics steps/s, and overhead against bare mj_step.

Two bare loops step the same compiled model for the same number of steps with the same servo
commands (so the blades close and the contacts form), timing mj_step alone: one without the
Prony relaxation (purely elastic food: a different, cheaper trajectory), one with it applied
untimed (the fetch's own states).  The second ratio is the cost of everything this project
adds to MuJoCo: Prony relaxation, sensor readout, strain meter, recording.  The third splits
one fetch itself: its wall time over the time spent inside its own mj_step calls.  It measures
the same overhead as the second without comparing two runs, so the VM's drift between runs
(this shared machine's speed varies by a third from day to day, and within a sitting) does
not enter it.

Run: python benchmarks/bench_simulator.py   (medians of 5 runs; one core)
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import mujoco
import numpy as np

from fetch_env.controller import FetchAction, FetchSimulator, make_profile, servo_commands
from fetch_env.layouts import diced_mix, single_block
from fetch_env.scene import initial_state
from fetch_env.viscoelastic import PronyRelaxation


def bare_loop(sim: FetchSimulator, action: FetchAction, prony: bool = False) -> float:
    """Time spent in mj_step alone over the fetch's steps.

    Without ``prony`` the food is purely elastic: a different trajectory (measured: 4.1
    instead of 6.4 Newton iterations a step, because the relaxing food holds differently), so
    that ratio mixes physics with overhead.  With ``prony`` the Prony rest shape is moved
    (untimed) so mj_step sees exactly the fetch's states: the ratio is pure overhead.
    """
    scene = sim.scene_for("fetch")
    m = scene.model
    profile = make_profile("fetch", action, m.opt.timestep)
    hinge, lift = servo_commands(scene, profile)
    ids = scene.ids
    left, right, up = ids["servo_left"], ids["servo_right"], ids["servo_lift"]
    d = initial_state(scene)
    forces = PronyRelaxation(scene)
    forces.reset(d)  # (the same rest shape as a run starts with)
    robot_nv = scene.robot_nv
    stepping = 0.0
    for i in range(len(hinge)):
        d.ctrl[left] = d.ctrl[right] = hinge[i]
        d.ctrl[up] = lift[i]
        if prony:
            forces.apply(d, d.nv_awake == robot_nv)  # not timed: only mj_step is
        t = time.perf_counter()
        mujoco.mj_step(m, d)
        stepping += time.perf_counter() - t
    forces.restore()
    return stepping


def in_run_ratio(sim: FetchSimulator, action: FetchAction) -> float:
    """One fetch's wall time over the time spent inside its own ``mj_step`` calls.

    ``mujoco.mj_step`` is wrapped with a timer for this one run (the simulator looks it up at
    each call); the wrapper's own ~0.2 us a step (measured) counts as overhead, so the ratio
    errs high, by under 0.1 %.
    """
    inner = mujoco.mj_step
    spent = 0.0

    def timed(m: mujoco.MjModel, d: mujoco.MjData) -> None:
        nonlocal spent
        t = time.perf_counter()
        inner(m, d)
        spent += time.perf_counter() - t

    mujoco.mj_step = timed
    try:
        r = sim.run("fetch", action)
    finally:
        mujoco.mj_step = inner
    return r.wall_time / spent


def bench(name: str, pieces, action: FetchAction, repeats: int = 5,
          timestep: float | None = None, impratio: float | None = None) -> dict[str, float]:
    sim = FetchSimulator(pieces, timestep=timestep, impratio=impratio)
    sim.run("fetch", action)  # compile and warm up
    walls, bares, visco, in_run = [], [], [], []
    for _ in range(repeats):  # interleaved, so load changes hit all alike
        r = sim.run("fetch", action)
        walls.append(r.wall_time)
        bares.append(bare_loop(sim, action))
        visco.append(bare_loop(sim, action, prony=True))
        in_run.append(in_run_ratio(sim, action))
    wall, bare = statistics.median(walls), statistics.median(bares)
    n, dt = r.n_steps, r.timestep
    ratio = statistics.median(w / b for w, b in zip(walls, bares, strict=True))
    ratio_visco = statistics.median(w / b for w, b in zip(walls, visco, strict=True))
    ratio_in_run = statistics.median(in_run)
    print(f"{name:26s} {n * dt / wall:6.1f}x real time  {n / wall:7.0f} steps/s  "
          f"bare mj_step {n / bare:7.0f} steps/s  ratio {ratio:4.2f}  "
          f"ratio to mj_step on the same states {ratio_visco:4.2f}  in-run {ratio_in_run:4.2f}")
    return {"realtime": n * dt / wall, "simulated": n * dt, "wall": wall,
            "steps_per_s": n / wall, "ratio": ratio,
            "ratio_visco": ratio_visco, "ratio_in_run": ratio_in_run}


if __name__ == "__main__":
    print(f"machine: {platform.machine()} {platform.processor()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}, mujoco {mujoco.__version__}")
    bench("single 15 mm soft cube", single_block(), FetchAction())
    # A diced fetch's cost depends on its trajectory (which columns the blades grip, how many
    # pieces wake, how long the solver takes in each contact event), and that trajectory is
    # chaotic: any change to the simulator moves one seed's figure by up to 2x.  So the
    # diced figure is the median over several seeded mixes, one run each.
    # The default (5 ms step, the multi-piece impratio 100), then in the same sitting the
    # impratio 1000 that multi-piece scenes ran at in 0.1.0 (the VM's speed drifts by a third
    # from day to day: compare within one run), then the opt-in 10 ms step
    # (FetchSimulator(timestep=0.01), the env's fetch_timestep), which loses outcome agreement
    # (benchmarks/bench_step_size.py).
    for timestep, impratio, label in ((None, None, ""), (None, 1000.0, " at impratio 1000"),
                                      (0.01, None, " at 10 ms")):
        rows = [bench(f"9-piece diced mix{label}, seed {seed}",
                      diced_mix(np.random.default_rng(seed), n_pieces=9),
                      FetchAction(theta_d=0.085), repeats=1, timestep=timestep,
                      impratio=impratio)
                for seed in range(1, 6)]
        print(f"{'9-piece diced mix' + label + ', median':26s} "
              f"{statistics.median(r['realtime'] for r in rows):6.1f}x real time (in all "
              f"{sum(r['simulated'] for r in rows) / sum(r['wall'] for r in rows):.1f}x)  "
              f"ratio {statistics.median(r['ratio'] for r in rows):4.2f}  ratio to mj_step on "
              f"the same states {statistics.median(r['ratio_visco'] for r in rows):4.2f}  "
              f"in-run {statistics.median(r['ratio_in_run'] for r in rows):4.2f}")
