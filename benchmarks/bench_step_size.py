"""How a diced fetch's outcome depends on the physics step: agreement with a finer step.

A diced fetch is chaotic (which column the blades grip, which piece slips out), so a coarser
step is judged by outcomes, not traces: for each seeded mix, each piece's fetched-or-not is
compared with the run at the finest step, the reference.  Also printed per step: mixes whose
every piece agrees, mixes with a crushed piece (LE > 1: a one-cell flex inverted), runs in
which MuJoCo warned (an under-converged effective-metric solve, say), the mean
fetch rate and the median real-time factor (with ``--workers`` > 1 the runs share the
machine: read the speed from ``bench_simulator.py``).

Run: python benchmarks/bench_step_size.py [--seeds 20] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
from concurrent.futures import ProcessPoolExecutor

import mujoco
import numpy as np

from fetch_env.controller import FetchAction, FetchSimulator
from fetch_env.layouts import diced_mix

CRUSHED_LOG_STRAIN = 1.0  # above it a piece's one-cell flex has inverted (README, "Crushed")


def run_mix(seed: int, steps: tuple[float, ...], theta_d: float) -> list[dict]:
    """One seeded diced mix (6-12 pieces), fetched once at each step."""
    pieces = diced_mix(np.random.default_rng(seed))
    out = []
    for dt in steps:
        r = FetchSimulator(pieces, timestep=dt).run("fetch", FetchAction(theta_d=theta_d))
        out.append({"fetched": [bool(p["fetched"]) for p in r.pieces],
                    "log_strain": max(max(p["max_log_strain_clamp"], p["max_log_strain_lift"])
                                      for p in r.pieces),
                    "fetch_rate": r.fetch_rate,
                    "warned": bool(r.extra["mujoco_warnings"]),
                    "realtime": r.n_steps * r.timestep / r.wall_time})
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=20, help="number of mixes (default 20)")
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--theta-d", type=float, default=0.085, help="clamp angle [rad]")
    p.add_argument("--steps", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=(0.0025, 0.005, 0.01), help="physics steps [s]; the first is the "
                   "reference (default 0.0025,0.005,0.01)")
    p.add_argument("--workers", type=int, default=1)
    args = p.parse_args()
    if args.seeds < 1 or args.workers < 1 or len(args.steps) < 2:
        p.error("--seeds and --workers must be >= 1 and --steps must name at least two steps")
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    print(f"machine: {platform.machine()} {platform.processor()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}, mujoco {mujoco.__version__}; "
          f"{args.seeds} diced mixes (seeds {seeds[0]}-{seeds[-1]}), theta_d {args.theta_d} rad, "
          f"{args.workers} worker(s)")
    with ProcessPoolExecutor(args.workers) as pool:
        runs = list(pool.map(run_mix, seeds, [args.steps] * len(seeds),
                             [args.theta_d] * len(seeds)))
    n_pieces = sum(len(r[0]["fetched"]) for r in runs)
    for k, dt in enumerate(args.steps):
        agree = sum(sum(a == b for a, b in zip(r[0]["fetched"], r[k]["fetched"], strict=True))
                    for r in runs)
        whole = sum(r[0]["fetched"] == r[k]["fetched"] for r in runs)
        crushed = sum(r[k]["log_strain"] > CRUSHED_LOG_STRAIN for r in runs)
        warned = sum(r[k]["warned"] for r in runs)
        label = "reference" if k == 0 else f"agree {agree}/{n_pieces} ({agree / n_pieces:.1%})"
        print(f"step {dt * 1000:5.2f} ms  {label:24s} whole mixes {whole:2d}/{len(runs)}  "
              f"crushed {crushed:2d}  MuJoCo warnings {warned:2d}  mean fetch rate "
              f"{statistics.mean(r[k]['fetch_rate'] for r in runs):.3f}  median "
              f"{statistics.median(r[k]['realtime'] for r in runs):5.2f}x real time")


if __name__ == "__main__":
    main()
